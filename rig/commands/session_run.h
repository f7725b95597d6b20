// Shared by `rig capture` and `rig resume`: devices, truth, the daemon, the model, the summary.
#pragma once

#include "capture/session/session_store.h"
#include "process/model/map_store.h"

namespace rig {

// Runs (or continues) a session and returns the exit code: 0 done, 1 fault or failed work,
// 128 + signal when stopped by SIGINT/SIGTERM.
int RunSession(Session& session, bool resuming, bool process, bool progress);

// Fits the session's reflectance model from its radiance maps (model/model.exr): from `maps`
// when it holds every map the session has (the maps kept as they were merged: no map is read
// back), else from the files. Both give the same model.
Status FitSessionModel(const Session& session, const MapStore* maps = nullptr);

}  // namespace rig
