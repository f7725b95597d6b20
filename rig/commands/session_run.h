// Shared by `rig capture` and `rig resume`: devices, truth, the daemon, the model, the summary.
#pragma once

#include "capture/session/session_store.h"

namespace rig {

// Runs (or continues) a session and returns the exit code: 0 done, 1 fault or failed work,
// 128 + signal when stopped by SIGINT/SIGTERM.
int RunSession(Session& session, bool resuming, bool process, bool progress);

// Fits the session's reflectance model from its radiance maps (model/model.exr).
Status FitSessionModel(const Session& session);

}  // namespace rig
