// Test-only: a raw client on an emulator's pseudo-terminal (no libserialport), for tests of
// what the emulators say byte for byte (capture/grbl_bringup_test.cc, grbl_firmware_test.cc).
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include <gtest/gtest.h>

namespace rig::testing {

class RawPty {
 public:
  explicit RawPty(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (fd_ < 0) return;
    termios t{};
    tcgetattr(fd_, &t);
    cfmakeraw(&t);
    tcsetattr(fd_, TCSANOW, &t);
  }
  ~RawPty() {
    if (fd_ >= 0) ::close(fd_);
  }
  bool ok() const { return fd_ >= 0; }
  void Write(const std::string& s) { ASSERT_EQ(::write(fd_, s.data(), s.size()), (ssize_t)s.size()); }
  // Reads until `needle` appears in what was read since the last call (or timeout).
  std::string ReadUntil(const std::string& needle, double timeout_s = 2.0) {
    auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    std::string got;
    while (std::chrono::steady_clock::now() < deadline && got.find(needle) == std::string::npos) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 10) <= 0) continue;
      char buf[512];
      ssize_t n = ::read(fd_, buf, sizeof buf);
      if (n > 0) got.append(buf, static_cast<size_t>(n));
    }
    return got;
  }
  // Polls '?' until the report starts with `<state`.
  std::string WaitState(const std::string& state, double timeout_s = 3.0) {
    auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    std::string last;
    while (std::chrono::steady_clock::now() < deadline) {
      Write("?");
      last = ReadUntil(">", 0.2);
      if (last.find("<" + state) != std::string::npos) return last;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return last;
  }

 private:
  int fd_ = -1;
};

// Axis `axis` (0 X, 1 Y, 2 Z) of the machine position in a status report; NaN without one.
inline double Mpos(const std::string& report, int axis) {
  size_t p = report.find("MPos:");
  if (p == std::string::npos) return NAN;
  const char* c = report.c_str() + p + 5;
  for (int i = 0; i < axis; ++i) {
    c = std::strchr(c, ',');
    if (c == nullptr) return NAN;
    ++c;
  }
  return std::strtod(c, nullptr);
}
inline double MposX(const std::string& report) { return Mpos(report, 0); }

}  // namespace rig::testing
