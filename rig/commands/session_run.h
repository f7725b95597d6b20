// Shared by `rig capture` and `rig resume`: devices, truth, the daemon, the model, the summary.
#pragma once

#include "capture/session/session_store.h"
#include "capture/daemon/session_model.h"

namespace rig {

// Runs (or continues) a session and returns the exit code: 0 done, 1 fault or failed work,
// 128 + signal when stopped by SIGINT/SIGTERM.
int RunSession(Session& session, bool resuming, bool process, bool progress);

}  // namespace rig
