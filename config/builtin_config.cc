// Loading a configuration file, or the built-in simulated rig when none is named.
#include "config/builtin_config.h"

namespace rig {

ConfigResult LoadConfigOrBuiltIn(const std::string& path) {
  if (path.empty()) return ParseConfig(BuiltInSimConfigText(), kBuiltInSimConfigName);
  return LoadConfig(path);
}

}  // namespace rig
