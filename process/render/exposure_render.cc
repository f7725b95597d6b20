// Exposure control: radiance × time through the inverse of the recovered response curve.
#include "process/render/exposure_render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace rig {

Result<cv::Mat> RenderExposure(const cv::Mat& radiance, double exposure_s,
                               const std::array<std::vector<double>, 3>& log_exposure) {
  const std::string where = fmt::format("exposure rendering at {} s", exposure_s);
  if (radiance.empty() || radiance.type() != CV_32FC3) {
    return MakeError(ErrorCode::kInvalidInput, where,
                     "the radiance map must be a non-empty CV_32FC3 image");
  }
  if (!(exposure_s > 0 && std::isfinite(exposure_s))) {
    return MakeError(ErrorCode::kInvalidInput, where, "the exposure time must be positive");
  }
  constexpr int kLevels = 256;
  // thresholds[c][k], k = 0..254: the exposure (radiance · time, linear) at which channel c
  // passes from level k to k + 1, i.e. exp of the midpoint of g(k) and g(k + 1). Compared
  // in the linear domain, no logarithm is taken per pixel.
  std::array<std::array<double, kLevels - 1>, 3> thresholds;
  for (int c = 0; c < 3; ++c) {
    const auto& g = log_exposure[c];
    if (static_cast<int>(g.size()) != kLevels) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "response curve of channel {} has {} levels, 256 expected", c, g.size());
    }
    double running = -std::numeric_limits<double>::infinity();
    std::array<double, kLevels> monotone;
    for (int z = 0; z < kLevels; ++z) {
      if (!std::isfinite(g[z])) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "response curve of channel {} is not finite at level {}", c, z);
      }
      running = std::max(running, g[z]);
      monotone[z] = running;
    }
    for (int k = 0; k + 1 < kLevels; ++k) {
      thresholds[c][k] = std::exp(0.5 * (monotone[k] + monotone[k + 1]));
    }
  }
  cv::Mat out(radiance.size(), CV_8UC3);
  cv::parallel_for_(cv::Range(0, radiance.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* in = radiance.ptr<float>(y);
      uint8_t* o = out.ptr<uint8_t>(y);
      for (int x = 0; x < radiance.cols * 3; x += 3) {
        for (int c = 0; c < 3; ++c) {
          const double e = static_cast<double>(in[x + c]) * exposure_s;
          // NaN and non-positive radiance fall under every threshold: level 0.
          const auto& t = thresholds[c];
          o[x + c] = static_cast<uint8_t>(
              e > 0 ? std::upper_bound(t.begin(), t.end(), e) - t.begin() : 0);
        }
      }
    }
  });
  return out;
}

}  // namespace rig
