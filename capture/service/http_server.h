// The capture service over HTTP+JSON (cpp-httplib), in the manner of Moonraker for Klipper:
//
//   GET  /, /page.js, /page.css      the status page (capture/service/page/, no network)
//   GET  /api/status                state, job, session, pose, frames, ETA, model, faults
//   GET  /api/jobs, /api/jobs/ID    the queue and every job
//   POST /api/jobs                  {"kind": "capture"|"resume"|"process", "session": ...}
//   POST /api/stop                  park the rig as Ctrl-C does; hold the queue
//   POST /api/resume                resume the stopped session, release the queue
//   GET  /api/journal?since=N       the session's journal records from N on
//   GET  /api/events                the same as Server-Sent Events, with status changes
//   GET  /api/preview/frame.jpg     the last stored frame
//   GET  /api/preview/radiance.jpg  the newest radiance map, tone-mapped
//
// Bound to loopback unless `allow_remote`; a token, when set, is required on every /api/
// request as "Authorization: Bearer TOKEN" (401 otherwise). Any other address needs both.
// Every request passes request_checks.h first (Host, length, token, content type, origin),
// and the connections are bounded by connection_guard.h; docs/daemon.md has the threat model.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "capture/service/service.h"
#include "config/result.h"

namespace httplib {
class Server;
struct Request;
struct Response;
}

namespace rig {

class ConnectionGuard;

// The port `rig daemon` listens on, and `rig status` looks at, by default.
inline constexpr int kDefaultDaemonPort = 7130;

struct HttpOptions {
  std::string host = "127.0.0.1";
  int port = kDefaultDaemonPort;  // 0: any free port (see HttpServer::port())
  bool allow_remote = false;
  std::string token;  // empty: no token asked (allowed on loopback only)
  // --allowed-host: names (NAME, or NAME:PORT) a reverse proxy forwards with, accepted in
  // Host and Origin besides the address listened on and the loopback names.
  std::vector<std::string> allowed_hosts;
  size_t max_connections = 32;
  size_t max_streams = 8;         // /api/events streams open at once
  double request_timeout_s = 5;   // a request's headers and body, from its connection's opening
                                  // or its previous answer
  double heartbeat_s = 2;         // an event stream's comment line when nothing changed
};

// 127.0.0.0/8, ::1 and "localhost".
bool IsLoopbackHost(const std::string& host);
// The security defaults: an address other than loopback needs allow_remote and a token.
Status CheckListenOptions(const HttpOptions& options);
// Splits "HOST:PORT" (or "[V6]:PORT", or "PORT").
Result<std::pair<std::string, int>> ParseListenAddress(const std::string& text);

// The status page's files (capture/service/page/, embedded at build time): name, content.
const std::vector<std::pair<std::string, std::string>>& StatusPageAssets();
// index.html with the page token filled in (given to the page's own script, which sends it
// as X-Rig-Page-Token on its actions).
std::string StatusPageHtml(const std::string& page_token);

class HttpServer {
 public:
  HttpServer(CaptureService& service, HttpOptions options);
  ~HttpServer();  // Stop()
  // Binds (refused per CheckListenOptions, or when the port is taken) and serves on a thread.
  Status Start();
  // The bound port (the chosen one when asked for 0).
  int port() const { return port_; }
  const std::string& host() const { return options_.host; }
  // The token the status page is served with (X-Rig-Page-Token).
  const std::string& page_token() const { return page_token_; }
  // Requests refused by the checks of request_checks.h since Start().
  size_t refused() const { return refused_; }
  void Stop();

 private:
  void WaitUntilListening();
  void Routes();
  void PageRoutes();
  void ApiRoutes();
  void EventRoutes();
  bool PreRouting(const httplib::Request& req, httplib::Response& res);
  CaptureService& service_;
  HttpOptions options_;
  std::string page_token_;  // random per process
  std::atomic<ConnectionGuard*> guard_{nullptr};
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  std::atomic<bool> listen_ended_{false};  // listen_after_bind returned
  std::atomic<bool> stopping_{false};
  std::atomic<size_t> refused_{0};
  int port_ = 0;
};

}  // namespace rig
