// What every family shares: adding a lamp, and where a direction lies among the lamps.
#include "process/model/reflectance_model.h"

#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>

#include "process/model/samples.h"

namespace rig {
cv::Mat ReflectanceModel::EvaluateEncoded(const Vec3& direction) const {
  cv::Mat v = EvaluateRho(direction);
  if (encoding() == ValueEncoding::kLinear) return v;
  v = v.clone();
  float* p = v.ptr<float>();
  const size_t n = v.total() * 3;
  for (size_t i = 0; i < n; ++i) p[i] = SrgbEncode(p[i]);
  return v;
}

void ReflectanceModel::AddLamp(const Vec3& direction, const std::array<double, 3>& rgb_scale,
                               cv::Mat* sum) const {
  const cv::Mat rho = EvaluateRho(direction);
  const auto e = lamp_radiance_rgb();
  const float gain[3] = {static_cast<float>(e[2] * rgb_scale[2]),
                         static_cast<float>(e[1] * rgb_scale[1]),
                         static_cast<float>(e[0] * rgb_scale[0])};  // B, G, R
  if (sum->empty()) *sum = cv::Mat::zeros(height(), width(), CV_32FC3);
  for (int y = 0; y < rho.rows; ++y) {
    const float* r = rho.ptr<float>(y);
    float* out = sum->ptr<float>(y);
    for (int x = 0; x < rho.cols; ++x)
      for (int c = 0; c < 3; ++c) out[3 * x + c] += gain[c] * r[3 * x + c];
  }
}

RegionCheck CheckAgainstLamps(const std::vector<Vec3>& lamps, double spacing_deg,
                              const Vec3& direction) {
  RegionCheck r;
  r.nearest_deg = 180;
  for (const auto& d : lamps) r.nearest_deg = std::min(r.nearest_deg, AngleBetweenDeg(direction, d));
  r.spacing_deg = spacing_deg;
  r.inside = !lamps.empty() && r.nearest_deg <= spacing_deg + 0.5;
  return r;
}

}  // namespace rig
