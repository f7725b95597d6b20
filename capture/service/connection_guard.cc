// The daemon's connections, bounded (connection_guard.h).
#include "capture/service/connection_guard.h"

#include <arpa/inet.h>
#include <dirent.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdlib>

#include <fmt/format.h>

#include "capture/service/tcp_bytes.h"
#include <nlohmann/json.hpp>

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

// The local port and the peer's address and port of a connected TCP socket.
bool Endpoints(int fd, int* local_port, std::string* peer_addr, int* peer_port) {
  sockaddr_storage local{}, peer{};
  socklen_t ll = sizeof local, pl = sizeof peer;
  if (::getsockname(fd, reinterpret_cast<sockaddr*>(&local), &ll) != 0) return false;
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &pl) != 0) return false;
  char text[INET6_ADDRSTRLEN] = {};
  if (local.ss_family == AF_INET && peer.ss_family == AF_INET) {
    const auto* l = reinterpret_cast<const sockaddr_in*>(&local);
    const auto* p = reinterpret_cast<const sockaddr_in*>(&peer);
    *local_port = ntohs(l->sin_port);
    *peer_port = ntohs(p->sin_port);
    ::inet_ntop(AF_INET, &p->sin_addr, text, sizeof text);
  } else if (local.ss_family == AF_INET6 && peer.ss_family == AF_INET6) {
    const auto* l = reinterpret_cast<const sockaddr_in6*>(&local);
    const auto* p = reinterpret_cast<const sockaddr_in6*>(&peer);
    *local_port = ntohs(l->sin6_port);
    *peer_port = ntohs(p->sin6_port);
    ::inet_ntop(AF_INET6, &p->sin6_addr, text, sizeof text);
  } else {
    return false;
  }
  *peer_addr = text;
  return true;
}

bool SameConnection(int fd, const std::string& addr, int peer_port, int port) {
  int lp = 0, pp = 0;
  std::string pa;
  return Endpoints(fd, &lp, &pa, &pp) && lp == port && pp == peer_port && pa == addr;
}

// A last answer written straight to the socket, then the socket shut down: the thread
// reading it sees the end and closes it.
void AnswerAndShut(int fd, int status, const char* reason, const std::string& error) {
  const std::string body = nlohmann::json{{"error", error}}.dump();
  const std::string msg = fmt::format(
      "HTTP/1.1 {} {}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n"
      "Connection: close\r\n\r\n{}",
      status, reason, body.size(), body);
  (void)!::send(fd, msg.data(), msg.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  ::shutdown(fd, SHUT_RDWR);
}

}  // namespace

ConnectionGuard::ConnectionGuard(int port, ConnectionLimits limits) : port_(port), limits_(limits) {
  // More threads than connections: a connection over the cap still gets a thread at once,
  // which finds its socket answered and closed.
  for (size_t i = 0; i < limits_.max_connections + 8; ++i) workers_.emplace_back([this] { Work(); });
  watchdog_ = std::thread([this] { Watch(); });
}

ConnectionGuard::~ConnectionGuard() { shutdown(); }

void ConnectionGuard::enqueue(std::function<void()> fn) {
  {
    std::lock_guard lock(mu_);
    Scan();
    Evict();
    jobs_.push_back(std::move(fn));
  }
  cv_.notify_all();
}

void ConnectionGuard::shutdown() {
  {
    std::lock_guard lock(mu_);
    if (shutdown_ && workers_.empty()) return;
    shutdown_ = true;
    // Every connection ends now rather than at its read timeout.
    for (Conn& c : conns_)
      if (c.state != State::kClosed && SameConnection(c.fd, c.addr, c.peer_port, port_))
        ::shutdown(c.fd, SHUT_RDWR);
  }
  cv_.notify_all();
  for (auto& t : workers_)
    if (t.joinable()) t.join();
  if (watchdog_.joinable()) watchdog_.join();
  std::lock_guard lock(mu_);
  workers_.clear();
}

void ConnectionGuard::Work() {
  for (;;) {
    std::function<void()> fn;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return shutdown_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // shut down, nothing left
      fn = std::move(jobs_.front());
      jobs_.pop_front();
    }
    fn();
  }
}

void ConnectionGuard::Watch() {
  std::unique_lock lock(mu_);
  for (int tick = 0; !shutdown_; ++tick) {
    cv_.wait_for(lock, std::chrono::milliseconds(20));
    if (shutdown_) break;
    if (tick % 5 == 0) Scan();
    Expire();
  }
}

void ConnectionGuard::Expire() {
  const auto now = Clock::now();
  for (Conn& c : conns_) {
    if (c.state != State::kWaiting && c.state != State::kBody && c.state != State::kRefused) continue;
    if (!SameConnection(c.fd, c.addr, c.peer_port, port_)) {
      c.state = State::kClosed;  // closed already; its number may be another file's now
      continue;
    }
    if (c.state == State::kRefused) {
      // Answered already: what the client sends on (the body nobody reads) is not taken for
      // another request by cpp-httplib.
      if (TcpBytesReceived(c.fd) - c.bytes_at_state > limits_.max_head_bytes ||
          now - c.since > std::chrono::milliseconds(500)) {
        ::shutdown(c.fd, SHUT_RDWR);
        c.state = State::kClosed;
      }
      continue;
    }
    const uint64_t budget = c.state == State::kWaiting ? limits_.max_head_bytes
                                                       : limits_.max_body_bytes + limits_.max_head_bytes;
    const uint64_t received = TcpBytesReceived(c.fd) - c.bytes_at_state;
    if (received > budget) {
      AnswerAndShut(c.fd, c.state == State::kWaiting ? 431 : 413,
                    c.state == State::kWaiting ? "Request Header Fields Too Large" : "Payload Too Large",
                    fmt::format("{} bytes without the request's {} ending (at most {})", received,
                                c.state == State::kWaiting ? "headers" : "body", budget));
      c.state = State::kClosed;
    } else if (now >= c.deadline) {
      AnswerAndShut(c.fd, 408, "Request Timeout",
                    fmt::format("the request did not arrive within {} s", limits_.request_timeout_s));
      c.state = State::kClosed;
    }
  }
}

void ConnectionGuard::Scan() {
  std::vector<bool> seen(conns_.size(), false);
  std::vector<Conn> fresh;
  if (DIR* d = ::opendir("/proc/self/fd")) {
    while (dirent* e = ::readdir(d)) {
      char* end = nullptr;
      const long fd = std::strtol(e->d_name, &end, 10);
      if (end == e->d_name || *end != '\0' || fd == ::dirfd(d)) continue;
      struct stat st {};
      if (::fstat(static_cast<int>(fd), &st) != 0 || !S_ISSOCK(st.st_mode)) continue;
      Conn c;
      int local_port = 0;
      if (!Endpoints(static_cast<int>(fd), &local_port, &c.addr, &c.peer_port) || local_port != port_)
        continue;
      c.fd = static_cast<int>(fd);
      c.bytes_at_state = TcpBytesReceived(c.fd);
      bool known = false;
      for (size_t i = 0; i < conns_.size(); ++i) {
        if (conns_[i].fd == c.fd && conns_[i].addr == c.addr && conns_[i].peer_port == c.peer_port) {
          seen[i] = known = true;
          break;
        }
      }
      if (known) continue;
      c.since = Clock::now();
      c.deadline = c.since + std::chrono::duration_cast<Clock::duration>(
                                 std::chrono::duration<double>(limits_.request_timeout_s));
      fresh.push_back(std::move(c));
    }
    ::closedir(d);
  }
  std::vector<Conn> kept;
  for (size_t i = 0; i < conns_.size(); ++i)
    if (seen[i]) kept.push_back(std::move(conns_[i]));
  for (Conn& c : fresh) kept.push_back(std::move(c));
  conns_ = std::move(kept);
}

void ConnectionGuard::Evict() {
  auto live = [&] {
    return static_cast<size_t>(std::count_if(conns_.begin(), conns_.end(),
                                              [](const Conn& c) { return c.state != State::kClosed; }));
  };
  while (live() > limits_.max_connections) {
    Conn* oldest = nullptr;
    for (Conn& c : conns_)
      if ((c.state == State::kWaiting || c.state == State::kBody) && (!oldest || c.since < oldest->since))
        oldest = &c;
    if (!oldest || oldest == &conns_.back()) {
      // Every other connection is being answered or streams: the newest one is refused.
      Conn& c = conns_.back();
      AnswerAndShut(c.fd, 503, "Service Unavailable",
                    fmt::format("{} connections are open (at most {}); try again",
                                live(), limits_.max_connections));
      c.state = State::kClosed;
      return;
    }
    AnswerAndShut(oldest->fd, 503, "Service Unavailable",
                  fmt::format("closed to make room: {} connections at most, and this one had "
                              "no request in hand", limits_.max_connections));
    oldest->state = State::kClosed;
  }
}

void ConnectionGuard::Mark(const std::string& addr, int port, State state) {
  std::lock_guard lock(mu_);
  for (Conn& c : conns_) {
    if (c.state == State::kClosed || c.addr != addr || c.peer_port != port) continue;
    if (c.state == State::kRefused) return;  // stays so until it is shut
    c.state = state;
    c.bytes_at_state = TcpBytesReceived(c.fd);
    c.since = Clock::now();
    c.deadline = c.since + std::chrono::duration_cast<Clock::duration>(
                               std::chrono::duration<double>(limits_.request_timeout_s));
    return;
  }
}

void ConnectionGuard::Refused(const std::string& addr, int port) {
  Mark(addr, port, State::kRefused);
}

void ConnectionGuard::HeadersRead(const std::string& addr, int port) { Mark(addr, port, State::kBody); }
void ConnectionGuard::Handling(const std::string& addr, int port) { Mark(addr, port, State::kHandling); }
void ConnectionGuard::Answered(const std::string& addr, int port) { Mark(addr, port, State::kWaiting); }

bool ConnectionGuard::BeginStream(const std::string& addr, int port) {
  {
    std::lock_guard lock(mu_);
    if (streams_ >= limits_.max_streams) return false;
    ++streams_;
  }
  Mark(addr, port, State::kStreaming);
  return true;
}

void ConnectionGuard::EndStream(const std::string&, int) {
  std::lock_guard lock(mu_);
  if (streams_ > 0) --streams_;
}

size_t ConnectionGuard::connections() const {
  std::lock_guard lock(mu_);
  return static_cast<size_t>(std::count_if(conns_.begin(), conns_.end(),
                                           [](const Conn& c) { return c.state != State::kClosed; }));
}

}  // namespace rig
