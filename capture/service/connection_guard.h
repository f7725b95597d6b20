// The daemon's connections, bounded: the thread pool cpp-httplib runs each accepted
// connection on, which also knows every connection's socket (found in /proc/self/fd by its
// local port when it is accepted) and what it is doing, so that
//  - a connection must deliver each request (headers and body) within `request_timeout_s`
//    of its opening or of its previous answer, else its socket is shut down (a client that
//    dribbles its headers a byte at a time holds a thread for that long at most);
//  - at most `max_connections` are open: one more closes the longest-waiting connection that
//    has no request in hand (slow, idle), or, when every one is answering or streaming, is
//    answered 503 itself;
//  - a connection receives at most `max_head_bytes` before its request's headers are read,
//    and at most the body limit after them (the kernel's count, looked at every 20 ms): a
//    request line or header without an end does not grow cpp-httplib's line buffer for long;
//  - a connection whose request was refused unread is shut half a second after the answer,
//    or as soon as 64 KiB more arrive (the body nobody reads);
//  - at most `max_streams` event streams are open at once.
// The handlers tell it, by the peer's address and port, when a request's headers were read,
// when its handler runs, when its answer was written, and when a stream begins and ends.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

namespace rig {

struct ConnectionLimits {
  size_t max_connections = 32;
  size_t max_streams = 8;
  double request_timeout_s = 5;
  uint64_t max_head_bytes = 64 << 10;  // the request line and headers
  uint64_t max_body_bytes = 1 << 20;
};

class ConnectionGuard : public httplib::TaskQueue {
 public:
  ConnectionGuard(int port, ConnectionLimits limits);
  ~ConnectionGuard() override;
  void enqueue(std::function<void()> fn) override;
  void shutdown() override;

  void HeadersRead(const std::string& addr, int port);  // the body must follow in time
  void Handling(const std::string& addr, int port);     // no deadline while the handler runs
  void Answered(const std::string& addr, int port);     // the next request must follow in time
  // The request was refused before its body was read: no more is read from the connection.
  void Refused(const std::string& addr, int port);
  // False when `max_streams` are open already.
  bool BeginStream(const std::string& addr, int port);
  void EndStream(const std::string& addr, int port);
  size_t connections() const;

 private:
  enum class State { kWaiting, kBody, kHandling, kStreaming, kRefused, kClosed };
  struct Conn {
    int fd = -1;
    std::string addr;
    int peer_port = 0;
    State state = State::kWaiting;
    std::chrono::steady_clock::time_point since, deadline;
    uint64_t bytes_at_state = 0;  // TcpBytesReceived when the state began
  };
  void Expire();  // mu_ held: shuts connections late or over their byte budget
  void Scan();   // mu_ held: registers new sockets, forgets closed ones
  void Evict();  // mu_ held: makes room for the newest connection
  void Mark(const std::string& addr, int port, State state);
  void Watch();
  void Work();

  const int port_;
  const ConnectionLimits limits_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<Conn> conns_;
  size_t streams_ = 0;
  std::deque<std::function<void()>> jobs_;
  bool shutdown_ = false;
  std::vector<std::thread> workers_;
  std::thread watchdog_;
};

}  // namespace rig
