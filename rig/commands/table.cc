// The command table. Add a command here and in command.h; nothing registers itself.
#include "rig/commands/command.h"

namespace rig {

const std::vector<Command>& Commands() {
  static const std::vector<Command> kCommands = {
      {"check-config", "validate a configuration file", RunCheckConfig},
  };
  return kCommands;
}

}  // namespace rig
