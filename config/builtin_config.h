// The simulated rig's configuration (config/sim.toml) compiled into the binary, so that the
// commands that default to it (`rig evaluate --dry-run`, the bring-up commands with
// --dry-run) work from any folder, installed or not.
#pragma once

#include <string>

#include "config/config.h"

namespace rig {

// config/sim.toml as it was at build time.
const char* BuiltInSimConfigText();
// The name its diagnostics carry.
inline constexpr const char* kBuiltInSimConfigName = "<built-in config/sim.toml>";

// `path` loaded and validated; an empty path: the built-in simulated rig.
ConfigResult LoadConfigOrBuiltIn(const std::string& path);

}  // namespace rig
