// Fixed against adaptive brackets on the simulator (see adaptive_eval.h).
#include "sim/adaptive_eval.h"

#include <algorithm>
#include <functional>
#include <array>
#include <cmath>

#include <fmt/format.h>

#include "capture/plan/bracket.h"
#include "capture/plan/pose.h"
#include "process/hdr/hdr.h"
#include "process/io/image_io.h"
#include "process/model/light_direction.h"
#include "sim/sim_camera.h"
#include "sim/world.h"

namespace rig {
namespace {

struct Scored {
  double sum = 0;
  size_t n = 0;
  double Rms() const { return n ? std::sqrt(sum / double(n)) : 0.0; }
};

// Log-radiance squared error of `estimate` on the pixel-channels of `mask` (255), leaving out
// pixels `skip` flags (a merge flags pixels black or saturated in every frame: they hold 0 or
// a lower bound, by design, and are counted apart).
void Score(const cv::Mat& estimate, const cv::Mat& truth, const cv::Mat& mask, const cv::Mat& skip,
           Scored* s) {
  for (int y = 0; y < truth.rows; ++y) {
    const float* t = truth.ptr<float>(y);
    const float* e = estimate.ptr<float>(y);
    const uint8_t* m = mask.ptr<uint8_t>(y);
    const uint8_t* f = skip.ptr<uint8_t>(y);
    for (int k = 0; k < truth.cols * 3; ++k) {
      if (!m[k] || f[k / 3]) continue;
      const double d = std::log(std::max<double>(e[k], 1e-30)) - std::log(double(t[k]));
      s->sum += d * d;
      ++s->n;
    }
  }
}

// Pixels of `mask` flagged in `flags`.
int Flagged(const cv::Mat& flags, const cv::Mat& mask) {
  int n = 0;
  for (int y = 0; y < flags.rows; ++y) {
    const uint8_t* f = flags.ptr<uint8_t>(y);
    const uint8_t* m = mask.ptr<uint8_t>(y);
    for (int x = 0; x < flags.cols; ++x) n += f[x] && (m[3 * x] || m[3 * x + 1] || m[3 * x + 2]);
  }
  return n;
}

// Pixel-channels whose exact exposure in some frame of `exposures` falls at a level in
// [5%, 95%] of the true response: recordable by the fixed bracket, whatever the noise did.
cv::Mat WellRecorded(const std::vector<Seconds>& exposures, const cv::Mat& truth,
                     const ResponseCurve& g) {
  cv::Mat mask(truth.rows, truth.cols * 3, CV_8U, cv::Scalar(0));
  std::array<double, 3> lo{}, hi{};
  for (int c = 0; c < 3; ++c) {
    lo[c] = std::exp(g.log_exposure[c][13]);
    hi[c] = std::exp(g.log_exposure[c][242]);
  }
  for (int y = 0; y < truth.rows; ++y) {
    const float* t = truth.ptr<float>(y);
    uint8_t* m = mask.ptr<uint8_t>(y);
    for (int k = 0; k < truth.cols * 3; ++k) {
      if (!(t[k] > 0)) continue;
      for (Seconds e : exposures) {
        const double x = t[k] * e.count();
        if (x >= lo[k % 3] && x <= hi[k % 3]) {
          m[k] = 255;
          break;
        }
      }
    }
  }
  return mask;
}

// A radiance map as the next pose's metering: pixels saturated in every frame hold lower
// bounds, metered 4x (two stops) brighter.
cv::Mat Metering(const RadianceMap& map) {
  cv::Mat m = map.radiance.clone();
  for (int y = 0; y < map.flags.rows; ++y) {
    const uint8_t* fl = map.flags.ptr<uint8_t>(y);
    float* r = m.ptr<float>(y);
    for (int x = 0; x < map.flags.cols; ++x) {
      if (fl[x] == kFlagSaturated) {
        for (int c = 0; c < 3; ++c) r[3 * x + c] *= 4.0f;
      }
    }
  }
  return m;
}

// One frame as a metering: E = exp(g(z)) / t; black pixels 0 (ignored), saturated ones 4x.
cv::Mat MeteringFrame(const LdrFrame& f, const ResponseCurve& g) {
  cv::Mat m(f.image.size(), CV_32FC3);
  const double t = f.exposure.count();
  for (int y = 0; y < m.rows; ++y) {
    const uint8_t* z = f.image.ptr<uint8_t>(y);
    float* r = m.ptr<float>(y);
    for (int k = 0; k < m.cols * 3; ++k) {
      const int c = k % 3;
      r[k] = z[k] == 0 ? 0.f : float(std::exp(g.log_exposure[c][z[k]]) / t * (z[k] == 255 ? 4 : 1));
    }
  }
  return m;
}

ResponseCurve TruthResponse(const SimResponse& sr) {
  ResponseCurve g;
  for (int c = 0; c < 3; ++c) {
    for (int z = 0; z < 256; ++z) g.log_exposure[c].push_back(sr.LogExposure(c, z));
  }
  g.id = "truth";
  return g;
}

// The planner's window: what every channel records usefully, never longer than the fixed
// bracket's longest (no chasing darkness it leaves too).
AdaptiveBracketOptions PlannerOptions(const SimResponse& sr, const AdaptiveEvalOptions& eo,
                                      const std::vector<Seconds>& fixed,
                                      const std::vector<Seconds>& offered) {
  AdaptiveBracketOptions ao;
  ao.x_lo = 0;
  ao.x_hi = 1e300;
  for (int c = 0; c < 3; ++c) {
    ao.x_lo = std::max(ao.x_lo, std::exp(sr.LogExposure(c, eo.z_lo)));
    ao.x_hi = std::min(ao.x_hi, std::exp(sr.LogExposure(c, eo.z_hi)));
  }
  ao.overlap_stops = eo.overlap_stops;
  ao.headroom_stops = eo.headroom_stops;
  ao.max_exposure = fixed.back();
  ao.min_exposure = offered.front();
  return ao;
}

// Share of pixel-channels clipped in a frame: at level 250 or above (a JPEG's clipped
// highlight decodes a few levels below 255).
double ClippedShare(const LdrFrame& f) {
  const cv::Mat flat = f.image.reshape(1);
  return double(cv::countNonZero(flat >= 250)) / double(flat.total());
}

using Shooter = std::function<Result<LdrFrame>(Seconds)>;

// One pose's adaptive bracket: at the first pose a metering frame at the fixed bracket's
// centre, then the frames planned from the metering (the previous pose's map), then, while
// the top frame clips more than planned (a brighter pose), one shorter frame at a time.
// Sorted by exposure; the plan written into row->plan.
Result<Bracket> AdaptiveBracketFor(const Shooter& shoot, const ResponseCurve& g,
                                   const std::vector<Seconds>& fixed,
                                   const std::vector<Seconds>& offered,
                                   const AdaptiveBracketOptions& ao, const AdaptiveEvalOptions& eo,
                                   cv::Mat* metering, AdaptivePoseRow* row) {
  Bracket ab;
  if (metering->empty()) {
    RIG_ASSIGN_OR_RETURN(LdrFrame f, shoot(fixed[fixed.size() / 2]));
    *metering = MeteringFrame(f, g);
    ab.push_back(std::move(f));
    row->plan = fmt::format("metering {:.4g} s; ", ab.back().exposure.count());
  }
  const cv::Mat flat = metering->reshape(1, 1);
  RIG_ASSIGN_OR_RETURN(AdaptivePlan plan,
                       PlanAdaptiveBracket(std::span<const float>(flat.ptr<float>(), flat.total()),
                                           offered, ao));
  for (const auto& pf : plan.frames) {
    RIG_ASSIGN_OR_RETURN(LdrFrame f, shoot(pf.exposure));
    ab.push_back(std::move(f));
    row->plan += fmt::format("{:.4g} s ({}); ", pf.exposure.count(), pf.reason);
  }
  for (int extra = 0; extra < 8; ++extra) {
    auto top = std::min_element(ab.begin(), ab.end(), [](const LdrFrame& a, const LdrFrame& b) {
      return a.exposure < b.exposure;
    });
    if (ClippedShare(*top) <= eo.reshoot_clipped_fraction) break;
    auto shorter = std::find_if(offered.rbegin(), offered.rend(), [&](Seconds s) {
      return s.count() <= top->exposure.count() * std::exp2(-2.0);
    });
    if (shorter == offered.rend()) break;
    RIG_ASSIGN_OR_RETURN(LdrFrame f, shoot(*shorter));
    row->plan += fmt::format("{:.4g} s (re-shot: the top frame clipped {:.2f}%); ",
                             shorter->count(), 100 * ClippedShare(*top));
    ab.push_back(std::move(f));
  }
  std::sort(ab.begin(), ab.end(), [](const LdrFrame& a, const LdrFrame& b) { return a.exposure < b.exposure; });
  return ab;
}

}  // namespace

Result<AdaptiveComparison> CompareAdaptiveBracket(const Config& config,
                                                  const AdaptiveEvalOptions& eo) {
  auto world = std::make_shared<SimWorld>();
  RIG_ASSIGN_OR_RETURN(std::unique_ptr<SimCamera> cam, SimCamera::Create(config, world));
  const SimResponse& sr = cam->response();
  const ResponseCurve g = TruthResponse(sr);
  const auto& k = config.sim.camera;
  const std::vector<Seconds> offered =
      ThirdStopShutterSpeeds(Seconds(k.shutter_min_s), Seconds(k.shutter_max_s));
  RIG_ASSIGN_OR_RETURN(std::vector<Seconds> fixed,
                       SnapToShutterSpeeds(WantedExposures(config.bracket), offered));
  std::sort(fixed.begin(), fixed.end());

  const AdaptiveBracketOptions ao = PlannerOptions(sr, eo, fixed, offered);

  MergeOptions mo;
  mo.weighting = MergeWeighting::kNoise;
  mo.max_unrecorded_fraction = 1.0;
  uint64_t seed = 1000;
  auto shoot = [&](const cv::Mat& radiance, Seconds t) -> Result<LdrFrame> {
    RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, cam->Encode(cam->Expose(radiance, t, ++seed)));
    const std::string name = fmt::format("frame_{}.{}", seed, k.format);
    RIG_ASSIGN_OR_RETURN(cv::Mat img, DecodeImageBytes(bytes, name));
    return LdrFrame{img, t, name};
  };
  auto frame_time = [&](const Bracket& b) {
    double s = 0;
    for (const auto& f : b) s += f.exposure.count() + k.download_time_s;
    return s;
  };
  AdaptiveComparison out;
  Scored all_fixed, all_adaptive;
  cv::Mat metering;  // the previous pose's adaptive radiance map
  const std::vector<Pose> poses = PlanGrid(config.grid);
  for (const Pose& pose : poses) {
    const cv::Mat truth =
        cam->scene().Radiance(LightDirection(pose.h_deg, pose.v_deg, config.light_frame),
                              config.lamp.radiance_rgb);
    AdaptivePoseRow row;
    row.pose = pose.Name();
    Bracket fb;
    for (Seconds t : fixed) {
      RIG_ASSIGN_OR_RETURN(LdrFrame f, shoot(truth, t));
      fb.push_back(std::move(f));
    }
    RIG_ASSIGN_OR_RETURN(RadianceMap fmap, MergeBracket(fb, g, mo));
    const cv::Mat mask = WellRecorded(fixed, truth, g);

    RIG_ASSIGN_OR_RETURN(Bracket ab,
                         AdaptiveBracketFor([&](Seconds t) { return shoot(truth, t); }, g, fixed,
                                            offered, ao, eo, &metering, &row));
    RIG_ASSIGN_OR_RETURN(RadianceMap amap, MergeBracket(ab, g, mo));
    metering = Metering(amap);

    Scored sf, sa;
    const cv::Mat skip = fmap.flags | amap.flags;
    Score(fmap.radiance, truth, mask, skip, &sf);
    Score(amap.radiance, truth, mask, skip, &sa);
    Score(fmap.radiance, truth, mask, skip, &all_fixed);
    Score(amap.radiance, truth, mask, skip, &all_adaptive);
    row.fixed_flagged = Flagged(fmap.flags, mask);
    row.adaptive_flagged = Flagged(amap.flags, mask);
    out.fixed_flagged += row.fixed_flagged;
    out.adaptive_flagged += row.adaptive_flagged;
    out.scored += int(sf.n);
    row.fixed_frames = int(fb.size());
    row.adaptive_frames = int(ab.size());
    row.fixed_rms = sf.Rms();
    row.adaptive_rms = sa.Rms();
    out.fixed_frames += row.fixed_frames;
    out.adaptive_frames += row.adaptive_frames;
    out.fixed_capture_s += frame_time(fb);
    out.adaptive_capture_s += frame_time(ab);
    out.poses.push_back(std::move(row));
  }
  out.fixed_rms = all_fixed.Rms();
  out.adaptive_rms = all_adaptive.Rms();
  return out;
}

}  // namespace rig
