// One test frame's exposure: its histogram, clipped and dark fractions, and the bracket that
// would cover the scene (for `rig shot`). The rule is in docs/rig-setup.md.
#pragma once

#include <array>
#include <string>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

struct ExposureStats {
  double exposure_s = 0;
  int pixels = 0;
  // Of the per-pixel brightest channel, 8-bit scale (0..255).
  double p01 = 0, p50 = 0, p99 = 0, p999 = 0;  // 1st, 50th, 99th, 99.9th percentiles
  double clipped_fraction = 0;  // pixels with a channel at >= 250
  double dark_fraction = 0;     // pixels whose brightest channel is <= 5
  std::array<double, 8> histogram{};  // fraction of pixels per 32-value bin of the brightest channel
};

struct BracketAdvice {
  double shortest_s = 0, longest_s = 0;  // the exposures the scene needs at each end
  double center_s = 0;                   // geometric middle
  double ev_step = 1.0;
  int count = 1;
  bool highlights_guessed = false;  // clipped at this exposure: the short end is a guess
  bool shadows_guessed = false;     // below the noise floor: the long end is a guess
  std::string note;
};

// The frame (8-bit BGR, or 16-bit scaled down) captured at `exposure_s`.
Result<ExposureStats> AnalyzeExposure(const cv::Mat& image, double exposure_s);

// The bracket from one frame: the brightest 0.1 % should sit at value 200 in the shortest
// exposure, the darkest 1 % at value 128 in the longest, taking values as sRGB-like
// (linear ≈ (v/255)^2.2); clipped highlights or shadows in the noise are guessed 3 stops
// beyond; 1-stop steps between.
BracketAdvice SuggestBracket(const ExposureStats& stats, double ev_step = 1.0);

}  // namespace rig
