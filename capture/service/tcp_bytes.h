// How many bytes a TCP socket has received since it opened (the kernel's count, TCP_INFO),
// apart from cpp-httplib (whose <netinet/tcp.h> clashes with <linux/tcp.h>, which has it).
#pragma once

#include <cstdint>

namespace rig {

// 0 when the kernel does not say.
uint64_t TcpBytesReceived(int fd);

}  // namespace rig
