// Test-only: an SH order-2 model of a 24x16 image with seeded random coefficients around a
// constant term (so renders are bright), sampled on the default grid: h 0-90, v 0-30, 10°
// steps, capture lamp (2, 1.5, 1).
#pragma once

#include <random>

#include <opencv2/core.hpp>

#include "process/model/harmonic/model.h"
#include "process/model/light_direction.h"

namespace rig::testing {

// A model header sampled on the default grid (h 0-90, v 0-30, 10° steps).
inline ModelInfo DefaultGridInfo() {
  ModelInfo info;
  for (double v = 0; v <= 30; v += 10)
    for (double h = 0; h <= 90; h += 10) info.lamp_directions.push_back(LightDirection(h, v));
  info.sample_spacing_deg = SampleSpacingDeg(info.lamp_directions);
  return info;
}

inline Model SyntheticShModel(unsigned seed, float amplitude) {
  ModelInfo info = DefaultGridInfo();
  info.lamp_radiance_rgb = {2.0, 1.5, 1.0};
  Model model(Basis(BasisKind::kSh, 2), info, 24, 16);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-amplitude, amplitude);
  for (int k = 0; k < model.basis().size(); ++k) {
    cv::Mat c(16, 24, CV_32FC3);
    for (auto it = c.begin<cv::Vec3f>(); it != c.end<cv::Vec3f>(); ++it)
      *it = cv::Vec3f(u(rng), u(rng), u(rng)) + (k == 0 ? cv::Vec3f(1, 1, 1) : cv::Vec3f());
    model.coefficients().push_back(c);
  }
  return model;
}

}  // namespace rig::testing
