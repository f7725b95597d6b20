// Shared by the bring-up commands (devices, jog, home, lamp, shot): the configuration they
// run with — a file, or the built-in simulated rig — and its devices, built as `rig capture`
// builds them (rig/backends.cc).
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "capture/plan/pose.h"
#include "config/config.h"
#include "config/result.h"

namespace rig {

struct BringUpOptions {
  std::string config_path;  // empty: the built-in config/sim.toml
  bool dry_run = false;     // every device simulated, whatever the configuration says
  std::string level;        // --log-level
};

// --config, --dry-run, --log-level.
void AddBringUpOptions(CLI::App& app, BringUpOptions* options);
// The configuration, validated (every problem printed, exit 2 through ReportError).
Result<Config> LoadBringUpConfig(const BringUpOptions& options);
// "H,V" in degrees.
Result<Pose> ParsePoseArgument(const std::string& text, const std::string& option);

}  // namespace rig
