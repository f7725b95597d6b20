// The session's reflectance model after a capture (model/model.exr and model/report.md): from
// the maps kept in memory as they were merged when every one is held, else from the files.
// Used by `rig capture`, `rig resume`, `rig process` and the daemon's process job.
#pragma once

#include <string>

#include "capture/session/session_store.h"
#include "config/result.h"
#include "process/model/session/map_store.h"

namespace rig {

// Fits the session's reflectance model from its radiance maps (model/model.exr): from `maps`
// when it holds every map the session has (no map is read back), else from the files. Both
// give the same model. Writes model/report.md beside it and prints one line.
Status FitSessionModel(const Session& session, const MapStore* maps = nullptr);

// What a leave-one-out RMS error in a fit space ("linear", "srgb", "log") is measured in.
std::string FitSpaceUnit(const std::string& space);

}  // namespace rig
