// rig daemon: own the devices and run sessions from a queue, with an HTTP+JSON API and a
// live status page (capture/service/).
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "capture/devices/signals.h"
#include "capture/service/http_server.h"
#include "capture/service/service.h"
#include "capture/service/service_paths.h"
#include "config/log.h"
#include "rig/commands/command.h"
#include "rig/commands/daemon_client.h"

namespace rig {

int RunDaemon(int argc, char** argv) {
  CLI::App app{"The capture service: owns the devices and runs one session at a time from a "
               "queue (capture, resume, process jobs), with an HTTP+JSON API and a live status "
               "page at http://ADDRESS:PORT/. Loopback only unless --allow-remote with a "
               "--token-file. SIGTERM or SIGINT parks the rig as Ctrl-C does and exits 128+signal.",
               "rig daemon"};
  std::string listen = fmt::format("127.0.0.1:{}", kDefaultDaemonPort), config_path, token_file,
              level;
  bool allow_remote = false;
  std::string sessions_root = DefaultSessionsRoot().string();
  std::vector<std::string> allowed_hosts;
  app.add_option("--listen", listen, "ADDRESS:PORT to serve on (port 0: any free port)")
      ->capture_default_str();
  app.add_option("--config", config_path, "configuration of capture jobs that name none");
  app.add_flag("--allow-remote", allow_remote,
               "allow an address other than loopback (needs --token-file)");
  app.add_option("--token-file", token_file,
                 "file whose first line is the token every /api/ request must send as "
                 "'Authorization: Bearer TOKEN'");
  app.add_option("--sessions-root", sessions_root,
                 "folder every job's session lies under (created if missing); a job's \"config\" "
                 "path must be a file there too")
      ->capture_default_str();
  app.add_option("--allowed-host", allowed_hosts,
                 "a name (NAME or NAME:PORT) a reverse proxy forwards with, accepted in Host and "
                 "Origin besides the listening address and the loopback names (repeatable)");
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;

  auto where = ParseListenAddress(listen);
  if (!where.ok()) return ReportError("daemon", where.error());
  HttpOptions http;
  http.host = where->first;
  http.port = where->second;
  http.allow_remote = allow_remote;
  http.allowed_hosts = allowed_hosts;
  if (!token_file.empty()) {
    auto token = ReadTokenFile(token_file);
    if (!token.ok()) return ReportError("daemon", token.error());
    http.token = *token;
  }
  if (Status st = CheckListenOptions(http); !st.ok()) return ReportError("daemon", st.error());

  ServiceOptions options;
  if (sessions_root.empty())
    return ReportError("daemon", MakeError(ErrorCode::kInvalidInput, "--sessions-root",
                                           "neither XDG_DATA_HOME nor HOME is set: name the folder"));
  std::error_code ec;
  fs::create_directories(sessions_root, ec);
  if (ec || !fs::is_directory(sessions_root))
    return ReportError("daemon", MakeError(ErrorCode::kIo, sessions_root, "cannot create the sessions root: {}",
                                           ec ? ec.message() : "not a folder"));
  options.sessions_root = fs::absolute(sessions_root);
  if (!config_path.empty()) {
    ConfigResult cr = LoadConfig(config_path);
    if (!cr.ok()) {
      for (const auto& d : cr.diagnostics) std::fprintf(stderr, "%s\n", d.ToString().c_str());
      return 2;
    }
    options.default_config = fs::absolute(config_path);
  }

  InstallStopHandlers();
  CaptureService service(DaemonHooks(), options);
  HttpServer server(service, http);
  if (Status st = server.Start(); !st.ok()) return ReportError("daemon", st.error());
  service.Start();
  std::printf("rig daemon: sessions under %s\n", options.sessions_root.c_str());
  std::printf("rig daemon: listening on http://%s:%d/ (pid %d)\n",
              http.host.find(':') != std::string::npos ? ("[" + http.host + "]").c_str() : http.host.c_str(),
              server.port(), static_cast<int>(::getpid()));
  std::fflush(stdout);
  // The signal handlers set the stop flag: a capture in hand parks on its own; this thread
  // only waits for it, then closes the service.
  while (CaughtSignal() == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const int sig = CaughtSignal();
  Log("rig")->warn("daemon: signal {}: parking and closing", sig);
  service.Shutdown();
  server.Stop();
  std::printf("rig daemon: stopped by signal %d\n", sig);
  return 128 + sig;
}

}  // namespace rig
