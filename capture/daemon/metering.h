// Metering for adaptive brackets: one stored frame of a pose read as relative radiance, and
// the response window that goes with it, for PlanAdaptiveBracket.
//
// The daemon meters each pose with one frame at the fixed bracket's centre exposure (stored
// and merged as a frame of the bracket). The session's response is recovered only once
// several brackets are in, on the processor's thread, so the metering reads levels through a
// nominal curve instead: RAW (16-bit, LibRaw's linear values) and linear 8-bit frames as
// they are, other 8-bit frames through a 2.2 power law. The window is expressed through the
// same curve, so the plan depends on the true response only through how far it departs from
// the nominal one between the window's levels; the plan's overlap absorbs that.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "capture/plan/adaptive_bracket.h"
#include "config/config.h"
#include "config/result.h"

namespace rig {

// The window [x_lo, x_hi] (relative exposure, 1 = clipping) for frames of `depth` (CV_8U or
// CV_16U) and linearity; the other planner options are left at their defaults.
AdaptiveBracketOptions MeteringWindow(int depth, bool linear);

// The frame `image` (CV_8UC3 or CV_16UC3, as DecodeImageBytes returns it) taken at
// `exposure_s`, as radiance per pixel-channel in the window's units per second. Black
// pixel-channels read 0 (ignored by the planner); clipped ones (8-bit level >= 250, 16-bit at
// the top level) are lower bounds, read four times (two stops) brighter.
Result<std::vector<float>> MeterFrame(const cv::Mat& image, double exposure_s, bool linear,
                                      const std::string& name);

}  // namespace rig
