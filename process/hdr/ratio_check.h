// The paper's own check (its Fig. 6): two pixels' ratio from plain intensities varies with the
// exposure time, while from radiance it is constant.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/hdr/hdr.h"

namespace rig {

struct RatioCheckOptions {
  // The two pixels; unset: chosen from the data (seeded): flat, recorded well by several
  // frames, with radiances near the 25th and 75th percentiles of the image.
  std::optional<cv::Point> a, b;
  uint64_t seed = 1;
  // Each "pixel" is the mean of a (2r+1)² patch around it (0: the single pixel, as in the
  // paper); a frame's radiance counts only where every level of the patch is well recorded.
  int patch_radius = 2;
};

// One exposure of the bracket. Intensity: the mean of the 8/16-bit levels (three channels,
// the patch). Radiance: the mean of exp(g(z) - ln t) from this one frame alone.
struct RatioRow {
  double exposure_s = 0;
  double intensity_a = 0, intensity_b = 0;
  double intensity_ratio = 0;   // intensity_a / intensity_b (0 when b is black)
  double radiance_ratio = 0;    // radiance_a / radiance_b from this frame
  bool radiance_valid = false;  // both pixels recorded (no channel black or clipped)
};

struct RatioCheckResult {
  cv::Point a, b;
  std::vector<RatioRow> rows;
  double merged_ratio = 0;      // from the merged radiance map of the whole bracket
  // max / min of the ratio over the exposures: intensity over rows where both are non-zero,
  // radiance over valid rows. The paper: intensity 0.5 .. 2 (spread 4), radiance constant.
  double intensity_spread = 0, radiance_spread = 0;

  // The table as CSV: exposure_s,intensity_a,intensity_b,intensity_ratio,radiance_ratio.
  std::string Csv() const;
};

// Runs the check on one bracket through `response`. Errors: an invalid bracket, a pixel
// outside the image, no frame in which both pixels are recorded.
Result<RatioCheckResult> CheckPixelRatios(std::span<const LdrFrame> frames,
                                          const ResponseCurve& response,
                                          const RatioCheckOptions& o = {});

// A plot (CV_8UC3, BGR): both ratios per exposure, each divided by the merged radiance ratio,
// on a log axis from 1/4 to 4: the radiance line stays at 1, the intensity line does not.
cv::Mat PlotPixelRatios(const RatioCheckResult& r);

}  // namespace rig
