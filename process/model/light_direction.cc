// The one mapping from rig angles to light directions.
#include "process/model/light_direction.h"

#include <cmath>
#include <algorithm>
#include <numbers>

namespace rig {

Vec3 LightDirection(double h_deg, double v_deg, const LightFrameConfig& f) {
  const double kRad = std::numbers::pi / 180.0;
  double h = (f.h_sign * h_deg + f.h_offset_deg) * kRad;
  double v = (f.v_sign * v_deg + f.v_offset_deg) * kRad;
  return {std::sin(h) * std::cos(v), std::sin(v), std::cos(h) * std::cos(v)};
}

void DirectionToAngles(const Vec3& d, double* h_deg, double* v_deg) {
  const double kDeg = 180.0 / std::numbers::pi;
  double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  *v_deg = std::asin(std::clamp(d[1] / n, -1.0, 1.0)) * kDeg;
  *h_deg = std::atan2(d[0], d[2]) * kDeg;
}

}  // namespace rig
