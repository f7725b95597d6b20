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

Vec3 NearLamp::At(int i, int j, int width, int height, const Vec3& dir, double* falloff) const {
  if (!near()) {
    *falloff = 1;
    return dir;
  }
  return AtPosition(i + 0.5, j + 0.5, DepthAt(i, j), width, height, dir, falloff);
}

Vec3 NearLamp::AtPosition(double u, double v, double z, int width, int height, const Vec3& dir,
                          double* falloff) const {
  if (!near()) {
    *falloff = 1;
    return dir;
  }
  const double x = (u - width / 2.0) * mm_per_px, y = (height / 2.0 - v) * mm_per_px;
  const Vec3 d = {distance_mm * dir[0] - x, distance_mm * dir[1] - y, distance_mm * dir[2] - z};
  const double d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  *falloff = distance_mm * distance_mm / d2;
  const double inv = 1 / std::sqrt(d2);
  return {d[0] * inv, d[1] * inv, d[2] * inv};
}

double NearLamp::InverseFalloff(int i, int j, int width, int height, const Vec3& dir) const {
  if (!near()) return 1;
  const double x = (i + 0.5 - width / 2.0) * mm_per_px, y = (height / 2.0 - j - 0.5) * mm_per_px;
  const double z = DepthAt(i, j);
  const double dx = distance_mm * dir[0] - x, dy = distance_mm * dir[1] - y,
               dz = distance_mm * dir[2] - z;
  return (dx * dx + dy * dy + dz * dz) / (distance_mm * distance_mm);
}

int NearLamp::TilePx(int width, int height, double max_deg) const {
  if (!near()) return std::max(width, height);
  double zmax = std::abs(plane_z_mm);
  if (!depth_mm.empty()) {
    double lo = 0, hi = 0;
    cv::minMaxLoc(depth_mm, &lo, &hi);
    zmax = std::max(std::abs(lo), std::abs(hi));
  }
  const double rx = width / 2.0 * mm_per_px, ry = height / 2.0 * mm_per_px;
  const double reach = std::sqrt(rx * rx + ry * ry + zmax * zmax);
  const double nearest = distance_mm - reach;
  if (nearest <= 0) return 1;
  // A tile of side s px reaches s * mm_per_px / sqrt(2) from its centre.
  const double max_rad = max_deg * std::numbers::pi / 180.0;
  const double side = max_rad * nearest * std::numbers::sqrt2 / mm_per_px;
  return std::clamp(static_cast<int>(std::floor(side)), 1, std::max(width, height));
}

NearLamp NearLamp::FromLightFrame(const LightFrameConfig& frame, int height) {
  NearLamp lamp;
  if (frame.lamp_distance_mm > 0 && frame.field_height_mm > 0 && height > 0) {
    lamp.distance_mm = frame.lamp_distance_mm;
    lamp.mm_per_px = frame.field_height_mm / height;
    lamp.plane_z_mm = frame.surface_depth_mm;
  }
  return lamp;
}

bool NearLamp::SameSamplingAs(const NearLamp& o) const {
  if (!near() && !o.near()) return true;
  return distance_mm == o.distance_mm && mm_per_px == o.mm_per_px && plane_z_mm == o.plane_z_mm &&
         depth_mm.empty() && o.depth_mm.empty();
}

double AngleBetweenDeg(const Vec3& a, const Vec3& b) {
  const double na = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
  const double nb = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
  const double c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (na * nb);
  return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

double SampleSpacingDeg(const std::vector<Vec3>& dirs) {
  double spacing = 0;
  for (size_t i = 0; i < dirs.size(); ++i) {
    double nearest = 180;
    for (size_t j = 0; j < dirs.size(); ++j)
      if (j != i) nearest = std::min(nearest, AngleBetweenDeg(dirs[i], dirs[j]));
    if (dirs.size() > 1) spacing = std::max(spacing, nearest);
  }
  return spacing;
}

}  // namespace rig
