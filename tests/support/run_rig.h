// Test support: run the built `rig` binary (path from $RIG_BINARY) and capture its output.
#pragma once

#include <string>

namespace rig::testing {

struct CommandResult {
  int status = -1;     // exit code; 128+N when killed by signal N
  std::string output;  // stdout and stderr together
};

// Runs `$RIG_BINARY args` through the shell; `args` is shell text.
CommandResult RunRig(const std::string& args);

// $RIG_SOURCE_DIR (the repository) and $RIG_SHARED_DIR (../shared).
std::string SourceDir();
std::string SharedDir();

// A fresh empty folder under the temporary directory, unique per process and name.
std::string FreshTempDir(const std::string& name);

}  // namespace rig::testing
