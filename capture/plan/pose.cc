// Pose names and grid planning.
#include "capture/plan/pose.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

namespace rig {
namespace {

std::string AngleText(double deg, int width) {
  std::string sign = deg < 0 ? "m" : "";
  double a = std::fabs(deg);
  double r = std::round(a);
  if (std::fabs(a - r) < 1e-6) return sign + fmt::format("{:0{}d}", static_cast<int>(r), width);
  // As few decimals as name the angle to a millionth of a degree: "32.5", "0.05", "0.125"
  // (one fixed decimal made 0.01-degree steps collide).
  int decimals = 1;
  while (decimals < 6) {
    const double scale = std::pow(10.0, decimals);
    if (std::fabs(std::round(a * scale) / scale - a) < 1e-7) break;
    ++decimals;
  }
  return sign + fmt::format("{:0{}.{}f}", a, width + 1 + decimals, decimals);
}

bool ParseAngle(const std::string& s, double* out) {
  if (s.empty()) return false;
  bool neg = s[0] == 'm';
  std::string body = neg ? s.substr(1) : s;
  if (body.empty()) return false;
  char* end = nullptr;
  double v = std::strtod(body.c_str(), &end);
  if (*end != '\0') return false;
  *out = neg ? -v : v;
  return true;
}

}  // namespace

std::string Pose::Name() const { return "h" + AngleText(h_deg, 3) + "_v" + AngleText(v_deg, 2); }

Result<Pose> ParsePoseName(const std::string& name) {
  auto us = name.find('_');
  Pose p;
  if (name.size() < 4 || name[0] != 'h' || us == std::string::npos || us + 1 >= name.size() ||
      name[us + 1] != 'v' || !ParseAngle(name.substr(1, us - 1), &p.h_deg) ||
      !ParseAngle(name.substr(us + 2), &p.v_deg))
    return MakeError(ErrorCode::kInvalidInput, name, "not a pose name (expected e.g. h030_v10)");
  return p;
}

std::vector<Pose> PlanGrid(const GridConfig& g) {
  // The configuration bounds the grid (kMaxGridPoses) before anything allocates it.
  RIG_CHECK((g.h_max_deg - g.h_min_deg) / g.h_step_deg < kMaxGridPoses &&
                (g.v_max_deg - g.v_min_deg) / g.v_step_deg < kMaxGridPoses,
            "grid not bounded by the configuration");
  int nh = static_cast<int>(std::lround((g.h_max_deg - g.h_min_deg) / g.h_step_deg)) + 1;
  int nv = static_cast<int>(std::lround((g.v_max_deg - g.v_min_deg) / g.v_step_deg)) + 1;
  std::vector<Pose> poses;
  for (int j = 0; j < nv; ++j) {
    double v = g.v_min_deg + j * g.v_step_deg;
    for (int i = 0; i < nh; ++i) {
      int ii = (g.order == "serpentine" && j % 2 == 1) ? nh - 1 - i : i;
      poses.push_back({g.h_min_deg + ii * g.h_step_deg, v});
    }
  }
  return poses;
}

std::string SoftLimitViolation(const MotorConfig& m, const Pose& pose) {
  if (pose.h_deg >= m.h_limit_min_deg && pose.h_deg <= m.h_limit_max_deg &&
      pose.v_deg >= m.v_limit_min_deg && pose.v_deg <= m.v_limit_max_deg)
    return "";
  return fmt::format("h {} v {} deg is outside the soft limits h {}..{} v {}..{}", pose.h_deg,
                     pose.v_deg, m.h_limit_min_deg, m.h_limit_max_deg, m.v_limit_min_deg,
                     m.v_limit_max_deg);
}

double MoveSeconds(const MotorConfig& m, const Pose& from, const Pose& to) {
  auto axis = [&](double d) {
    d = std::fabs(d);
    const double v = std::max(m.speed_deg_per_s, 1e-9), a = std::max(m.accel_deg_per_s2, 1e-9);
    // Too short to reach the speed: a triangle, accelerating half the way.
    if (d < v * v / a) return 2 * std::sqrt(d / a);
    return d / v + v / a;
  };
  return std::max(axis(to.h_deg - from.h_deg), axis(to.v_deg - from.v_deg));
}

}  // namespace rig
