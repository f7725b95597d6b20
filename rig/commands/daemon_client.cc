// Talking to a running `rig daemon` from the other commands.
#include "rig/commands/daemon_client.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <thread>

#include "capture/devices/signals.h"
#include "capture/service/http_server.h"
#include "rig/backends.h"
#include "rig/commands/command.h"
#include "capture/daemon/session_model.h"

namespace rig {

ServiceHooks DaemonHooks() {
  ServiceHooks h;
  h.make_devices = [](const Config& config) -> Result<ServiceDevices> {
    RIG_ASSIGN_OR_RETURN(Devices made, MakeDevices(config));
    auto owned = std::make_shared<Devices>(std::move(made));
    ServiceDevices d;
    d.camera = owned->camera.get();
    d.motor = owned->motor.get();
    d.lamp = owned->lamp.get();
    d.settle_scale = owned->settle_scale;
    if (owned->write_truth) {
      d.write_truth = [owned, poses = PlanGrid(config.grid)](const fs::path& dir) {
        return owned->write_truth(dir, poses);
      };
    }
    d.owner = owned;
    return d;
  };
  h.fit_model = [](const Session& session, const MapStore* maps) {
    return FitSessionModel(session, maps);
  };
  return h;
}

Result<std::string> ReadTokenFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) return MakeError(ErrorCode::kNotFound, path, "cannot read the token file");
  std::string line;
  std::getline(in, line);
  const auto b = line.find_first_not_of(" \t\r\n");
  const auto e = line.find_last_not_of(" \t\r\n");
  if (b == std::string::npos) return MakeError(ErrorCode::kInvalidInput, path, "the token file is empty");
  return line.substr(b, e - b + 1);
}

void AddDaemonOptions(CLI::App& app, DaemonTarget* t) {
  app.add_option("--daemon", t->url,
                 "hand the job to a running 'rig daemon' at this URL (e.g. http://127.0.0.1:7130) "
                 "instead of opening the devices here (default: $RIG_DAEMON)");
  app.add_option("--token-file", t->token_file,
                 "the daemon's token, for one listening beyond loopback (default: "
                 "$RIG_DAEMON_TOKEN_FILE)");
  app.add_flag("--wait", t->wait, "with --daemon: follow the job to its end and return its exit code");
}

Result<std::optional<DaemonAddress>> ResolveDaemon(const DaemonTarget& t, bool fallback_default) {
  std::string url = t.url;
  if (url.empty()) {
    const char* env = std::getenv("RIG_DAEMON");
    if (env && *env) url = env;
  }
  if (url.empty() && !fallback_default) return std::optional<DaemonAddress>();
  if (url.empty()) url = fmt::format("http://127.0.0.1:{}", kDefaultDaemonPort);
  RIG_ASSIGN_OR_RETURN(DaemonAddress a, ParseDaemonUrl(url));
  std::string token_file = t.token_file;
  if (token_file.empty()) {
    const char* env = std::getenv("RIG_DAEMON_TOKEN_FILE");
    if (env && *env) token_file = env;
  }
  if (!token_file.empty()) {
    RIG_ASSIGN_OR_RETURN(a.token, ReadTokenFile(token_file));
  }
  return std::optional<DaemonAddress>(a);
}

int SubmitToDaemon(const char* command, const DaemonAddress& daemon, const nlohmann::json& job,
                   bool wait) {
  DaemonClient client(daemon);
  auto submitted = client.Post("/api/jobs", job);
  if (!submitted.ok()) return ReportError(command, submitted.error());
  const int id = (*submitted)["id"].get<int>();
  std::printf("job %d (%s %s) queued on %s\n", id, job["kind"].get<std::string>().c_str(),
              job["session"].get<std::string>().c_str(), daemon.Url().c_str());
  std::fflush(stdout);
  if (!wait) return 0;
  // Ctrl-C here stops following, not the rig: the daemon owns it ('rig status', POST /api/stop).
  InstallStopHandlers();
  const std::string path = fmt::format("/api/jobs/{}", id);
  std::string last_state;
  for (;;) {
    if (StopRequested()) {
      std::fprintf(stderr, "rig %s: no longer following job %d; it goes on in the daemon\n", command, id);
      return 128 + StopSignal();
    }
    auto j = client.Get(path);
    if (!j.ok()) return ReportError(command, j.error());
    const std::string state = (*j)["state"].get<std::string>();
    if (state != last_state) {
      std::printf("job %d: %s\n", id, state.c_str());
      std::fflush(stdout);
      last_state = state;
    }
    if (state != "queued" && state != "running") {
      if (j->contains("summary")) std::printf("%s\n", (*j)["summary"].get<std::string>().c_str());
      if (j->contains("error")) std::fprintf(stderr, "rig %s: %s\n", command, (*j)["error"].get<std::string>().c_str());
      return (*j)["exit_code"].is_number() ? (*j)["exit_code"].get<int>() : 1;
    }
    SleepUnlessStopped(Seconds(0.25));
  }
}

}  // namespace rig
