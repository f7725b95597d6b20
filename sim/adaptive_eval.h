// Adaptive brackets against the fixed one, on the simulated rig with ground truth: every pose
// of the grid captured both ways through the simulated camera (its noise, response and JPEG),
// merged through the true response, and scored against the scene's exact radiance on the
// pixel-channels the fixed bracket can record (their exact exposure in one of its frames at a
// level in 5-95%), leaving out pixels either merge flags (counted apart). The adaptive bracket meters each pose from
// the previous pose's radiance map (the first pose from one metering frame, counted), plans
// with PlanAdaptiveBracket, and adds a shorter frame when its top frame clipped more than the
// metering predicted (a brighter pose than the one metered).
#pragma once

#include <string>
#include <vector>

#include "capture/plan/adaptive_bracket.h"
#include "config/config.h"
#include "config/result.h"

namespace rig {

struct AdaptiveEvalOptions {
  int z_lo = 24, z_hi = 235;          // the window's levels (8-bit)
  double overlap_stops = 0.5;
  double headroom_stops = 1.0;        // the next pose may be brighter than the one metered
  double reshoot_clipped_fraction = 0;  // top frame clipped beyond this share: one shorter
};

struct AdaptivePoseRow {
  std::string pose;
  int fixed_frames = 0, adaptive_frames = 0;  // adaptive includes metering and re-shots
  double fixed_rms = 0, adaptive_rms = 0;     // log-radiance RMS against the truth
  int fixed_flagged = 0, adaptive_flagged = 0;  // scored pixels each merge flagged (left out)
  std::string plan;                           // the exposures and the reason of each
};

struct AdaptiveComparison {
  std::vector<AdaptivePoseRow> poses;
  int fixed_frames = 0, adaptive_frames = 0;
  double fixed_rms = 0, adaptive_rms = 0;            // over all poses' scored pixel-channels
  int scored = 0;                                    // pixel-channels scored, all poses
  int fixed_flagged = 0, adaptive_flagged = 0;       // pixels flagged by each merge (left out)
  double fixed_capture_s = 0, adaptive_capture_s = 0;  // exposure + download per frame
};

Result<AdaptiveComparison> CompareAdaptiveBracket(const Config& config,
                                                  const AdaptiveEvalOptions& options);

}  // namespace rig
