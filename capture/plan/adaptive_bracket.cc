// Adaptive bracket planning: a cover of the metered radiance range by exposure windows.
#include "capture/plan/adaptive_bracket.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <fmt/format.h>

namespace rig {

Result<AdaptivePlan> PlanAdaptiveBracket(std::span<const float> metered,
                                         const std::vector<Seconds>& offered,
                                         const AdaptiveBracketOptions& o) {
  if (!(o.x_lo > 0) || !(o.x_hi > o.x_lo) || !std::isfinite(o.x_hi))
    return MakeError(ErrorCode::kInvalidInput, "bracket", "adaptive window [{}, {}] is empty", o.x_lo,
                     o.x_hi);
  if (offered.empty())
    return MakeError(ErrorCode::kInvalidInput, "bracket", "no shutter speeds offered");
  if (!(o.overlap_stops >= 0) || std::log2(o.x_hi / o.x_lo) <= o.overlap_stops)
    return MakeError(ErrorCode::kInvalidInput, "bracket",
                     "the window ({:.2f} stops) must be wider than the overlap ({:.2f} stops)",
                     std::log2(o.x_hi / o.x_lo), o.overlap_stops);
  std::vector<float> v;
  v.reserve(metered.size());
  for (float x : metered) {
    if (x > 0 && std::isfinite(x)) v.push_back(x);
  }
  if (v.empty()) return MakeError(ErrorCode::kInvalidInput, "bracket", "the metering holds no light");
  auto quantile = [&](double q) {
    const size_t i = std::min(v.size() - 1, size_t(q * double(v.size() - 1)));
    std::nth_element(v.begin(), v.begin() + i, v.end());
    return double(v[i]);
  };
  AdaptivePlan plan;
  plan.e_max = quantile(1.0 - o.top_fraction) * std::exp2(o.headroom_stops);
  plan.e_min = std::min(quantile(o.bottom_fraction), plan.e_max);

  std::vector<Seconds> speeds = offered;
  std::sort(speeds.begin(), speeds.end());
  const Seconds t_min = o.min_exposure.count() > 0 ? o.min_exposure : speeds.front();
  const Seconds t_max = o.max_exposure.count() > 0 ? o.max_exposure : speeds.back();
  std::erase_if(speeds, [&](Seconds t) { return t < t_min * (1 - 1e-9) || t > t_max * (1 + 1e-9); });
  if (speeds.empty())
    return MakeError(ErrorCode::kInvalidInput, "bracket", "no offered shutter speed within {} .. {} s",
                     t_min.count(), t_max.count());

  // The top frame: the longest exposure that keeps E_max at or below x_hi.
  auto longest_at_most = [&](double t) -> std::optional<Seconds> {
    std::optional<Seconds> best;
    for (Seconds s : speeds) {
      if (s.count() <= t * (1 + 1e-9)) best = s;
    }
    return best;
  };
  Seconds t = longest_at_most(o.x_hi / plan.e_max).value_or(speeds.front());
  plan.frames.push_back({t, fmt::format("top: radiance up to {:.4g} within the window (clips above {:.4g})",
                                        plan.e_max, o.x_hi / t.count())});
  double covered = o.x_lo / t.count();
  const double step = (o.x_hi / o.x_lo) * std::exp2(-o.overlap_stops);  // ratio between frames
  while ((covered > plan.e_min || int(plan.frames.size()) < o.min_frames) &&
         int(plan.frames.size()) < o.max_frames) {
    // The longest exposure whose window still overlaps the last by overlap_stops.
    auto next = longest_at_most(t.count() * step);
    if (!next || *next <= t) {
      // The next wanted time lies below the next offered speed (speeds coarser than the
      // window): take the next longer one.
      auto longer = std::find_if(speeds.begin(), speeds.end(), [&](Seconds s) { return s > t; });
      if (longer == speeds.end()) break;  // the longest allowed is already in
      next = *longer;
    }
    t = *next;
    const double lo = o.x_lo / t.count();
    plan.frames.push_back(
        {t, covered > plan.e_min
                ? fmt::format("radiance {:.4g} .. {:.4g} (below {:.4g} is not yet recorded)", lo,
                              o.x_hi / t.count(), covered)
                : fmt::format("radiance {:.4g} .. {:.4g} (the range is covered; a bracket has at "
                              "least {} frames)", lo, o.x_hi / t.count(), o.min_frames)});
    covered = lo;
  }
  plan.covered_min = covered;
  size_t below = 0, above = 0;
  const double top = o.x_hi / plan.frames.front().exposure.count();
  for (float x : v) {
    below += x < covered;
    above += x > top;
  }
  plan.below_fraction = double(below) / double(v.size());
  plan.above_fraction = double(above) / double(v.size());
  return plan;
}

}  // namespace rig
