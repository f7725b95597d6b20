// Adaptive brackets: the exposures one pose needs, from a metering of its radiance (the
// previous pose's radiance map, or one metering frame), instead of the same fixed bracket at
// every pose.
//
// A pixel-channel of radiance E is recorded usefully at exposure t when E t falls in the
// window [x_lo, x_hi] of the response (x = exp(g(z)) between a low level z_lo, above which one
// frame's log-radiance error is within the bound asked, and a high level z_hi below clipping).
// Each frame covers radiance [x_lo / t, x_hi / t]; the plan covers the metered range
// [E_min, E_max] from the top down with the fewest offered shutter speeds, consecutive frames
// overlapping by `overlap_stops`. Every metered pixel-channel then has at least one frame in
// its window, so its merged error is no worse than one frame's at z_lo — the bound.
#pragma once

#include <span>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/result.h"

namespace rig {

struct AdaptiveBracketOptions {
  double x_lo = 0, x_hi = 0;        // the window, in the metering's units times seconds
  double overlap_stops = 0.5;       // consecutive frames' windows overlap by this much
  double top_fraction = 1e-4;       // E_max: the value this share of pixel-channels exceeds
  double bottom_fraction = 1e-3;    // E_min: the value this share of them lies below
  double headroom_stops = 0.0;      // E_max raised by this much (a metering of another pose)
  Seconds max_exposure{0};          // the longest exposure allowed (0: the longest offered)
  Seconds min_exposure{0};          // the shortest allowed (0: the shortest offered)
  int min_frames = 2;   // a merge needs two (and a second frame checks the first)
  int max_frames = 16;
};

struct AdaptiveFrame {
  Seconds exposure{0};
  std::string reason;  // why this frame: "radiance 12.3 .. 45.6 (covers the top)" etc.
};

struct AdaptivePlan {
  std::vector<AdaptiveFrame> frames;  // shortest first
  double e_min = 0, e_max = 0;        // the metered range planned for
  double covered_min = 0;             // the lowest radiance the plan records usefully
  // Share of metered pixel-channels below covered_min (too dark even at the longest
  // exposure allowed), and above the top frame's window (brighter than the shortest allows).
  double below_fraction = 0, above_fraction = 0;
};

// Plans one pose's bracket from `metered` values (radiance per pixel-channel; values <= 0 or
// not finite are ignored; values flagged saturated in the metering should be passed raised —
// they are lower bounds). `offered`: the body's shutter speeds, ascending.
Result<AdaptivePlan> PlanAdaptiveBracket(std::span<const float> metered,
                                         const std::vector<Seconds>& offered,
                                         const AdaptiveBracketOptions& options);

}  // namespace rig
