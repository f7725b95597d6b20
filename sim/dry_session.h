// A whole dry-run session in this process: every device simulated, latencies zero.
#pragma once

#include <filesystem>

#include "config/config.h"
#include "config/result.h"

namespace rig {

// Creates the session folder `dir` (refused if it holds a session), writes the simulator's
// truth, runs the capture daemon over the grid with simulated camera, motor and lamp (the
// config's backends are ignored; sim.latency_scale and settling are zero) and the processing.
// Errors: the session's or the daemon's; kFault when some pose failed to merge.
Status RunSimulatedSession(const Config& config, const std::filesystem::path& dir);

}  // namespace rig
