// Test set-up shared by the daemon's tests: a capture service with its HTTP server on a free
// loopback port, sessions under a root.
#pragma once

#include <string>

#include <gtest/gtest.h>

#include "capture/devices/signals.h"
#include "capture/service/http_server.h"
#include "capture/service/service.h"
#include "rig/commands/daemon_client.h"

namespace rig::testing {

inline ServiceOptions SessionsUnder(const std::string& root) {
  ServiceOptions o;
  o.sessions_root = root;
  return o;
}

// `rig daemon` as it runs, in-process: the service started, its API on 127.0.0.1 at a free port
// (`options` otherwise as given). Stop() (or the destructor) shuts both down and clears the
// stop flag a job may have raised.
struct RunningDaemon {
  CaptureService service;
  HttpServer http;
  explicit RunningDaemon(const std::string& sessions_root, HttpOptions options = {})
      : service(DaemonHooks(), SessionsUnder(sessions_root)), http(service, Loopback(options)) {
    Status st = http.Start();
    EXPECT_TRUE(st.ok()) << (st.ok() ? "" : st.error().ToString());
    service.Start();
  }
  ~RunningDaemon() { Stop(); }
  int port() const { return http.port(); }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(http.port()); }
  void Stop() {
    if (stopped_) return;
    stopped_ = true;
    service.Shutdown();
    http.Stop();
    ClearStopForTesting();
  }

 private:
  static HttpOptions Loopback(HttpOptions o) {
    o.host = "127.0.0.1";
    o.port = 0;
    return o;
  }
  bool stopped_ = false;
};

}  // namespace rig::testing
