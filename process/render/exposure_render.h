// Exposure control (the paper's Fig. 12): the 8-bit picture the camera would have recorded
// of a radiance map at a chosen exposure time, through the recovered response curve.
#pragma once

#include <array>
#include <chrono>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

// radiance: CV_32FC3 BGR linear, in the units the response curve was recovered in (so that
// ln(radiance · exposure_s) is on the curve's scale). log_exposure[c][z]: the Debevec-Malik
// g(z) = ln exposure at pixel level z, per channel in OpenCV's order (B, G, R), 256 levels,
// increasing.
//
// For each channel, the pixel is the level z whose g(z) interpolates ln(radiance ·
// exposure_s), rounded to the nearest level: equivalently the number of midpoints
// (g(k) + g(k+1)) / 2, k = 0..254, at or below it. Values under the curve's bottom give 0,
// over its top 255 (saturation), radiance ≤ 0 gives 0. A curve that dips (noise at its ends)
// is read through its running maximum, so the rendering stays monotonic in exposure.
// Returns CV_8UC3 BGR. Errors (kInvalidInput): empty or non-CV_32FC3 image, exposure time
// not positive, a curve without 256 finite levels. Uses cv::parallel_for_ over rows.
Result<cv::Mat> RenderExposure(const cv::Mat& radiance, double exposure_s,
                               const std::array<std::vector<double>, 3>& log_exposure);

inline Result<cv::Mat> RenderExposure(const cv::Mat& radiance,
                                      std::chrono::duration<double> exposure,
                                      const std::array<std::vector<double>, 3>& log_exposure) {
  return RenderExposure(radiance, exposure.count(), log_exposure);
}

}  // namespace rig
