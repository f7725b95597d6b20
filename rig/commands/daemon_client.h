// The client side of `rig daemon` shared by rig status, rig capture/resume --daemon: where
// the daemon is, its token, submitting a job and following it.
#pragma once

#include <optional>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "capture/service/client.h"
#include "capture/service/service.h"

namespace rig {

// The hooks `rig daemon` runs sessions with: rig/backends.cc's devices, the session's model fit.
ServiceHooks DaemonHooks();

// Reads a token file: its first line, trimmed; empty or unreadable is an error naming it.
Result<std::string> ReadTokenFile(const std::string& path);

struct DaemonTarget {
  std::string url;         // --daemon URL (else $RIG_DAEMON)
  std::string token_file;  // --token-file (else $RIG_DAEMON_TOKEN_FILE)
  bool wait = false;       // --wait: follow the job to its end
};
// Adds --daemon, --token-file and --wait to a command.
void AddDaemonOptions(CLI::App& app, DaemonTarget* target);
// The daemon a command should talk to, when one was named (by option or environment);
// `fallback_default`: else the default port on loopback (rig status).
Result<std::optional<DaemonAddress>> ResolveDaemon(const DaemonTarget& target, bool fallback_default);

// Submits a job to the daemon, prints its id; with `wait`, follows it and returns the exit
// code the job would have had run here; else 0 once queued.
int SubmitToDaemon(const char* command, const DaemonAddress& daemon, const nlohmann::json& job,
                   bool wait);

}  // namespace rig
