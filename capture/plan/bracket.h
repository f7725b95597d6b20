// Bracket planning: exposure times from config, snapped to the shutter speeds a body offers.
#pragma once

#include <vector>

#include "config/config.h"
#include "config/result.h"

namespace rig {

// The exposure times a session asks for (before snapping): the explicit list, or
// `count` times spaced `ev_step` stops apart, centred (geometrically) on `center_s`.
std::vector<Seconds> WantedExposures(const BracketConfig& bracket);

// Snaps each wanted time to the nearest offered speed (in stops). Fails when two wanted
// times snap to the same speed, or a wanted time lies more than a stop outside the range
// offered: the bracket would silently shrink otherwise.
Result<std::vector<Seconds>> SnapToShutterSpeeds(const std::vector<Seconds>& wanted,
                                                 const std::vector<Seconds>& offered);

// Third-stop shutter speeds from `min` to `max`, as bodies label them
// (1/8000, 1/6400, 1/5000, ... 1/60, ... 0.3, 0.4, 0.5, 0.6, 0.8, 1, 1.3 ... 30 s).
std::vector<Seconds> ThirdStopShutterSpeeds(Seconds min, Seconds max);

}  // namespace rig
