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

// The whole content of a file ("" when it cannot be read).
std::string ReadText(const std::string& path);

}  // namespace rig::testing

#include <sys/types.h>

#include <vector>

namespace rig::testing {

// Starts `$RIG_BINARY args...` in the background, its output appended to `log_path`.
pid_t SpawnRig(const std::vector<std::string>& args, const std::string& log_path);
// Waits for it; returns the exit code, or 128+N when killed by signal N.
int WaitRig(pid_t pid);

// A small, fast dry run's [sim] and [bracket]: 160x120, 40 poses x 4 exposures (for
// WriteSimConfig's `extra`).
inline constexpr const char* kSmallDryRun = R"([sim]
width = 160
height = 120
[bracket]
center_s = 0.02
ev_step = 1.5
count = 4
)";

// Writes config/sim.toml with `extra` TOML appended into `dir`/sim.toml, with the tables of
// `extra` merged over the default ones (keys given in `extra` replace the defaults).
std::string WriteSimConfig(const std::string& dir, const std::string& extra);

}  // namespace rig::testing
