// rig capture: run an acquisition session (on the rig, or simulated with --dry-run).
#include <cstdio>

#include "config/log.h"
#include "config/settings.h"
#include "rig/backends.h"
#include "rig/commands/command.h"
#include "rig/commands/daemon_client.h"
#include "rig/commands/session_run.h"
#include "capture/devices/signals.h"

namespace rig {

int RunCapture(int argc, char** argv) {
  CLI::App app{"Acquire a session: home, then at every lamp pose move, settle, lamp on, capture "
               "the exposure bracket, lamp off; every frame stored and journaled at once; "
               "brackets merged into radiance maps while the rig moves on; the reflectance "
               "model fitted at the end.",
               "rig capture"};
  std::string config_path, out;
  bool dry_run = false, no_process = false, no_progress = false;
  std::string level;
  std::vector<std::string> set;
  DaemonTarget daemon_target;
  app.add_option("--config", config_path, "session configuration (TOML)")->required();
  app.add_option("--out", out, "session folder to create (refused if it holds a session)")->required();
  app.add_flag("--dry-run", dry_run, "simulate every device (camera, motor, lamp), whatever the config says");
  app.add_option("--set", set,
                 "override a setting of the configuration for this session (KEY=VALUE, repeatable; "
                 "e.g. camera.iso=200 or camera.port=usb:001,004): validated as the file is, and "
                 "recorded in the session's session.toml");
  app.add_flag("--no-process", no_process, "store frames only; process later with 'rig process'");
  app.add_flag("--no-progress", no_progress, "no progress bar");
  AddDaemonOptions(app, &daemon_target);
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;

  ConfigResult cr = LoadConfig(config_path);
  if (!cr.ok()) {
    for (const auto& d : cr.diagnostics) std::fprintf(stderr, "%s\n", d.ToString().c_str());
    return 2;
  }
  auto overridden = ApplyOverrides(cr.config, set);
  if (!overridden.ok()) return ReportError("capture", overridden.error());
  for (const auto& c : overridden->second)
    std::printf("setting %s: %s -> %s\n", c.key.c_str(), c.old_value.empty() ? "unset" : c.old_value.c_str(),
                c.new_value.c_str());
  auto daemon = ResolveDaemon(daemon_target, /*fallback_default=*/false);
  if (!daemon.ok()) return ReportError("capture", daemon.error());
  if (*daemon) {
    // The daemon owns the devices: hand it the job (the configuration as text, so that it
    // need not see this machine's files), checked here first for file:line errors.
    auto text = ReadFileBytes(config_path);
    if (!text.ok()) return ReportError("capture", text.error());
    // With --set, the configuration the job runs is the overridden one.
    const std::string toml_text = set.empty() ? std::string(text->begin(), text->end())
                                              : ToToml(overridden->first);
    nlohmann::json job = {{"kind", "capture"},
                          {"session", fs::absolute(out).lexically_normal().string()},
                          {"config", fs::absolute(config_path).string()},
                          {"config_toml", toml_text},
                          {"dry_run", dry_run},
                          {"process", !no_process}};
    return SubmitToDaemon("capture", **daemon, job, daemon_target.wait);
  }
  Config config = overridden->first;
  if (dry_run) UseSimulatedBackends(&config);
  auto session = Session::Create(out, config);
  if (!session.ok()) return ReportError("capture", session.error());
  InstallStopHandlers();
  return RunSession(*session, /*resuming=*/false, !no_process, !no_progress);
}

int RunResume(int argc, char** argv) {
  CLI::App app{"Continue an interrupted or faulted session where its journal says: verifies "
               "every stored frame (size and CRC), redoes only what is missing or damaged.",
               "rig resume"};
  std::string dir, level;
  std::vector<std::string> set;
  bool no_process = false, no_progress = false;
  DaemonTarget daemon_target;
  app.add_option("SESSION", dir, "session folder")->required();
  app.add_option("--set", set,
                 "change a device setting first (KEY=VALUE, repeatable; e.g. "
                 "camera.port=usb:001,004 or motor.port=/dev/ttyUSB1): validated, journaled "
                 "with its old and new value, session.toml rewritten atomically. Never the "
                 "grid, bracket or anything else that shapes a frame.");
  app.add_flag("--no-process", no_process, "store frames only");
  app.add_flag("--no-progress", no_progress, "no progress bar");
  AddDaemonOptions(app, &daemon_target);
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;
  auto daemon = ResolveDaemon(daemon_target, /*fallback_default=*/false);
  if (!daemon.ok()) return ReportError("resume", daemon.error());
  if (*daemon) {
    nlohmann::json job = {{"kind", "resume"},
                          {"session", fs::absolute(dir).lexically_normal().string()},
                          {"process", !no_process}};
    return SubmitToDaemon("resume", **daemon, job, daemon_target.wait);
  }
  auto session = Session::OpenExisting(dir);
  if (!session.ok()) return ReportError("resume", session.error());
  for (const auto& w : session->history().warnings) Log("session")->warn("{}", w);
  if (!set.empty()) {
    auto changes = session->ChangeDeviceSettings(set);
    if (!changes.ok()) return ReportError("resume", changes.error());
    for (const auto& c : *changes)
      std::printf("setting %s: %s -> %s (journaled)\n", c.key.c_str(),
                  c.old_value.empty() ? "unset" : c.old_value.c_str(), c.new_value.c_str());
  }
  // The stored configuration must be the one the journal recorded (or changed through --set).
  Status same = session->CheckStoredConfig();
  if (!same.ok()) return ReportError("resume", same.error());
  InstallStopHandlers();
  return RunSession(*session, /*resuming=*/true, !no_process, !no_progress);
}

}  // namespace rig
