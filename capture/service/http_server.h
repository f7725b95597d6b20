// The capture service over HTTP+JSON (cpp-httplib), in the manner of Moonraker for Klipper:
//
//   GET  /                          the status page (self-contained HTML/JS, no network)
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
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "capture/service/service.h"
#include "config/result.h"

namespace httplib {
class Server;
}

namespace rig {

// The port `rig daemon` listens on, and `rig status` looks at, by default.
inline constexpr int kDefaultDaemonPort = 7130;

struct HttpOptions {
  std::string host = "127.0.0.1";
  int port = kDefaultDaemonPort;  // 0: any free port (see HttpServer::port())
  bool allow_remote = false;
  std::string token;  // empty: no token asked (allowed on loopback only)
};

// 127.0.0.0/8, ::1 and "localhost".
bool IsLoopbackHost(const std::string& host);
// The security defaults: an address other than loopback needs allow_remote and a token.
Status CheckListenOptions(const HttpOptions& options);
// Splits "HOST:PORT" (or "[V6]:PORT", or "PORT").
Result<std::pair<std::string, int>> ParseListenAddress(const std::string& text);

// The self-contained status page served at "/".
const char* StatusPageHtml();

class HttpServer {
 public:
  HttpServer(CaptureService& service, HttpOptions options);
  ~HttpServer();  // Stop()
  // Binds (refused per CheckListenOptions, or when the port is taken) and serves on a thread.
  Status Start();
  // The bound port (the chosen one when asked for 0).
  int port() const { return port_; }
  const std::string& host() const { return options_.host; }
  void Stop();

 private:
  void Routes();
  CaptureService& service_;
  HttpOptions options_;
  std::unique_ptr<httplib::Server> server_;
  std::thread thread_;
  std::atomic<bool> stopping_{false};
  int port_ = 0;
};

}  // namespace rig
