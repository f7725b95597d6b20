// The bring-up commands' shared options and configuration.
#include "rig/commands/bringup.h"

#include <cstdio>
#include <cstdlib>

#include "config/builtin_config.h"
#include "rig/backends.h"
#include "rig/commands/command.h"

namespace rig {

void AddBringUpOptions(CLI::App& app, BringUpOptions* o) {
  app.add_option("--config", o->config_path,
                 "rig configuration (TOML); default: the built-in simulated rig (config/sim.toml)");
  app.add_flag("--dry-run", o->dry_run, "simulate every device, whatever the configuration says");
  AddLogLevelOption(app, &o->level);
}

Result<Config> LoadBringUpConfig(const BringUpOptions& o) {
  ConfigResult cr = LoadConfigOrBuiltIn(o.config_path);
  if (!cr.ok()) return cr.AsError();
  Config config = cr.config;
  if (o.dry_run) UseSimulatedBackends(&config);
  return config;
}

Result<Pose> ParsePoseArgument(const std::string& text, const std::string& option) {
  const size_t comma = text.find(',');
  if (comma == std::string::npos)
    return MakeError(ErrorCode::kInvalidInput, option, "'{}' is not H,V (degrees, e.g. 30,10)", text);
  const std::string h = text.substr(0, comma), v = text.substr(comma + 1);
  char* end_h = nullptr;
  char* end_v = nullptr;
  double hd = std::strtod(h.c_str(), &end_h), vd = std::strtod(v.c_str(), &end_v);
  if (h.empty() || v.empty() || *end_h != '\0' || *end_v != '\0')
    return MakeError(ErrorCode::kInvalidInput, option, "'{}' is not H,V (degrees, e.g. 30,10)", text);
  return Pose{hd, vd};
}

}  // namespace rig
