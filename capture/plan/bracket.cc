// Bracket planning from config and a body's shutter speed list.
#include "capture/plan/bracket.h"

#include <algorithm>
#include <cmath>

namespace rig {

std::vector<Seconds> WantedExposures(const BracketConfig& b) {
  std::vector<Seconds> out;
  if (!b.exposure_times_s.empty()) {
    for (double t : b.exposure_times_s) out.emplace_back(t);
    return out;
  }
  for (int i = 0; i < b.count; ++i) {
    double stops = (i - (b.count - 1) / 2.0) * b.ev_step;
    out.emplace_back(b.center_s * std::pow(2.0, stops));
  }
  return out;
}

Result<std::vector<Seconds>> SnapToShutterSpeeds(const std::vector<Seconds>& wanted,
                                                 const std::vector<Seconds>& offered) {
  if (offered.empty())
    return MakeError(ErrorCode::kUnsupported, "camera", "the camera offers no shutter speeds");
  std::vector<Seconds> out;
  for (Seconds w : wanted) {
    size_t best = 0;
    double best_d = 1e300;
    for (size_t i = 0; i < offered.size(); ++i) {
      double d = std::fabs(std::log2(offered[i].count() / w.count()));
      if (d < best_d) best_d = d, best = i;
    }
    if (best_d > 1.0)
      return MakeError(ErrorCode::kUnsupported, "camera",
                       "exposure {:.6g} s is {:.1f} stops from the nearest speed the body offers "
                       "({:.6g} s)",
                       w.count(), best_d, offered[best].count());
    Seconds s = offered[best];
    if (!out.empty() && std::find(out.begin(), out.end(), s) != out.end())
      return MakeError(ErrorCode::kInvalidInput, "bracket",
                       "exposures snap to the same shutter speed {:.6g} s; widen ev_step", s.count());
    out.push_back(s);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Seconds> ThirdStopShutterSpeeds(Seconds min, Seconds max) {
  // The nominal third-stop series bodies display; the true values are 2^(k/3).
  static const double kLong[] = {1, 1.3, 1.6, 2, 2.5, 3.2, 4, 5, 6, 8, 10, 13, 15, 20, 25, 30};
  static const double kShort[] = {8000, 6400, 5000, 4000, 3200, 2500, 2000, 1600, 1250, 1000,
                                  800,  640,  500,  400,  320,  250,  200,  160,  125,  100,
                                  80,   60,   50,   40,   30,   25,   20,   15,   13,   10,
                                  8,    6,    5,    4,    3};
  static const double kTenths[] = {0.4, 0.5, 0.6, 0.8};
  std::vector<Seconds> out;
  for (double d : kShort) out.emplace_back(1.0 / d);
  for (double t : kTenths) out.emplace_back(t);
  for (double t : kLong) out.emplace_back(t);
  std::sort(out.begin(), out.end());
  std::vector<Seconds> kept;
  for (Seconds s : out)
    if (s.count() >= min.count() * 0.999 && s.count() <= max.count() * 1.001) kept.push_back(s);
  return kept;
}

}  // namespace rig
