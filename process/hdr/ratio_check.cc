// The paper's Fig. 6 check: per exposure, two pixels' intensity ratio and radiance ratio.
#include "process/hdr/ratio_check.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

int LevelAt(const cv::Mat& img, cv::Point p, int c) {
  if (img.depth() == CV_16U) return img.at<cv::Vec<uint16_t, 3>>(p)[c];
  return img.at<cv::Vec3b>(p)[c];
}

// Radiance around pixel p (the mean over a (2r+1)² patch) from frame f alone; false unless
// every level there is well recorded (5% .. 95% of the range: quantisation and the curve's
// ends make the rest unreliable in a single frame).
bool FrameRadiance(const LdrFrame& f, const ResponseCurve& g, cv::Point p, double* out, int r = 0) {
  const int lo = static_cast<int>(0.05 * (g.levels - 1)), hi = static_cast<int>(0.95 * (g.levels - 1));
  double sum = 0;
  int n = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const cv::Point q = p + cv::Point(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= f.image.cols || q.y >= f.image.rows) continue;
      for (int c = 0; c < 3; ++c) {
        const int z = LevelAt(f.image, q, c);
        if (z < lo || z > hi) return false;
        sum += std::exp(g.log_exposure[c][z] - std::log(f.exposure.count()));
        ++n;
      }
    }
  if (n == 0) return false;
  *out = sum / n;
  return true;
}

// Mean level over the patch, all channels.
double PatchIntensity(const cv::Mat& img, cv::Point p, int r) {
  double sum = 0;
  int n = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      const cv::Point q = p + cv::Point(dx, dy);
      if (q.x < 0 || q.y < 0 || q.x >= img.cols || q.y >= img.rows) continue;
      for (int c = 0; c < 3; ++c) sum += LevelAt(img, q, c), ++n;
    }
  return n ? sum / n : 0;
}

int RecordedFrames(std::span<const LdrFrame> frames, const ResponseCurve& g, cv::Point p, int r) {
  int n = 0;
  double v;
  for (const auto& f : frames) n += FrameRadiance(f, g, p, &v, r);
  return n;
}

// "Two random pixels" (the paper), but useful ones: unflagged, flat (both neighbours within
// 5%), recorded by at least a third of the frames, near two radiance percentiles (75th, 25th).
Result<std::pair<cv::Point, cv::Point>> ChooseTwoPixels(std::span<const LdrFrame> frames,
                                                        const ResponseCurve& response,
                                                        const RadianceMap& map,
                                                        const RatioCheckOptions& o) {
  const cv::Rect bounds(0, 0, map.radiance.cols, map.radiance.rows);
  // within 5%), recorded by at least a third of the frames, near two radiance percentiles.
  std::mt19937_64 rng(o.seed);
  struct Cand {
    cv::Point p;
    float lum;
  };
  std::vector<Cand> cands;
  const int min_recorded = std::max(2, int(frames.size()) / 3);
  const int m = o.patch_radius + 1;  // margin: the patch and its flatness probes fit
  for (int i = 0; i < 4000 && cands.size() < 400; ++i) {
    cv::Point p(m + int(rng() % uint64_t(std::max(1, bounds.width - 2 * m))),
                m + int(rng() % uint64_t(std::max(1, bounds.height - 2 * m))));
    if (!bounds.contains(p)) continue;
    if (map.flags.at<uint8_t>(p) != kFlagOk) continue;
    const cv::Vec3f e = map.radiance.at<cv::Vec3f>(p);
    const float lum = (e[0] + e[1] + e[2]) / 3;
    if (!(lum > 0)) continue;
    bool flat = true;
    const int k = std::max(1, o.patch_radius);
    for (cv::Point d : {cv::Point(k, 0), cv::Point(0, k), cv::Point(-k, 0), cv::Point(0, -k)}) {
      if (!bounds.contains(p + d)) {
        flat = false;
        break;
      }
      const cv::Vec3f n = map.radiance.at<cv::Vec3f>(p + d);
      flat = flat && std::abs((n[0] + n[1] + n[2]) / 3 - lum) < 0.05f * lum;
    }
    if (!flat || RecordedFrames(frames, response, p, o.patch_radius) < min_recorded) continue;
    cands.push_back({p, lum});
  }
  if (cands.size() < 2) {
    return MakeError(ErrorCode::kInvalidInput, frames[0].source,
                     "no two flat, well-recorded pixels found; give them with --pixel");
  }
  std::sort(cands.begin(), cands.end(), [](const Cand& x, const Cand& y) { return x.lum < y.lum; });
  return std::pair{cands[cands.size() * 3 / 4].p, cands[cands.size() / 4].p};
}

}  // namespace

std::string RatioCheckResult::Csv() const {
  std::string s = "exposure_s,intensity_a,intensity_b,intensity_ratio,radiance_ratio\n";
  for (const auto& r : rows) {
    s += fmt::format("{:.6g},{:.2f},{:.2f},{:.4f},{}\n", r.exposure_s, r.intensity_a,
                     r.intensity_b, r.intensity_ratio,
                     r.radiance_valid ? fmt::format("{:.4f}", r.radiance_ratio) : "");
  }
  return s;
}

Result<RatioCheckResult> CheckPixelRatios(std::span<const LdrFrame> frames,
                                          const ResponseCurve& response,
                                          const RatioCheckOptions& o) {
  // The merge only guides the choice of the two pixels (each frame's radiance below is its
  // own): the plain photon weighting, no noise model fitted.
  MergeOptions mo;
  mo.max_unrecorded_fraction = 1.0;
  mo.weighting = MergeWeighting::kPhoton;
  RIG_ASSIGN_OR_RETURN(RadianceMap map, MergeBracket(frames, response, mo));
  const cv::Rect bounds(0, 0, map.radiance.cols, map.radiance.rows);
  RatioCheckResult r;
  if (o.a && o.b) {
    r.a = *o.a;
    r.b = *o.b;
    for (cv::Point p : {r.a, r.b}) {
      if (!bounds.contains(p)) {
        return MakeError(ErrorCode::kInvalidInput, frames[0].source,
                         "pixel {},{} is outside the {}x{} image", p.x, p.y, bounds.width,
                         bounds.height);
      }
    }
  } else {
    RIG_ASSIGN_OR_RETURN(auto pair, ChooseTwoPixels(frames, response, map, o));
    r.a = pair.first;
    r.b = pair.second;
  }
  auto patch_mean = [&](cv::Point p) {
    const cv::Rect patch = cv::Rect(p.x - o.patch_radius, p.y - o.patch_radius, 2 * o.patch_radius + 1,
                                    2 * o.patch_radius + 1) & bounds;
    const cv::Scalar m = cv::mean(map.radiance(patch));
    return (m[0] + m[1] + m[2]) / 3;
  };
  const double la = patch_mean(r.a), lb = patch_mean(r.b);
  r.merged_ratio = lb > 0 ? la / lb : 0;
  double imin = 1e300, imax = 0, rmin = 1e300, rmax = 0;
  for (const auto& f : frames) {
    RatioRow row;
    row.exposure_s = f.exposure.count();
    row.intensity_a = PatchIntensity(f.image, r.a, o.patch_radius);
    row.intensity_b = PatchIntensity(f.image, r.b, o.patch_radius);
    if (row.intensity_b > 0) {
      row.intensity_ratio = row.intensity_a / row.intensity_b;
      if (row.intensity_a > 0) {
        imin = std::min(imin, row.intensity_ratio);
        imax = std::max(imax, row.intensity_ratio);
      }
    }
    double ra = 0, rb = 0;
    if (FrameRadiance(f, response, r.a, &ra, o.patch_radius) &&
        FrameRadiance(f, response, r.b, &rb, o.patch_radius) && rb > 0) {
      row.radiance_valid = true;
      row.radiance_ratio = ra / rb;
      rmin = std::min(rmin, row.radiance_ratio);
      rmax = std::max(rmax, row.radiance_ratio);
    }
    r.rows.push_back(row);
  }
  if (rmax == 0) {
    return MakeError(ErrorCode::kInvalidInput, frames[0].source,
                     "no exposure records both pixels ({},{} and {},{})", r.a.x, r.a.y, r.b.x,
                     r.b.y);
  }
  r.intensity_spread = imax > 0 ? imax / imin : 0;
  r.radiance_spread = rmax / rmin;
  return r;
}

cv::Mat PlotPixelRatios(const RatioCheckResult& r) {
  const int w = 720, h = 420, left = 70, right = 20, top = 40, bottom = 60;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  const int n = int(r.rows.size());
  const double lo = std::log(0.25), hi = std::log(4.0);
  auto px = [&](int i) { return left + (n > 1 ? i * (w - left - right) / (n - 1) : 0); };
  auto py = [&](double ratio) {
    const double v = std::clamp(std::log(std::max(ratio, 1e-9)), lo, hi);
    return top + int((hi - v) / (hi - lo) * (h - top - bottom));
  };
  const cv::Scalar grey(200, 200, 200), black(0, 0, 0);
  for (double v : {0.25, 0.5, 1.0, 2.0, 4.0}) {
    cv::line(img, {left, py(v)}, {w - right, py(v)}, v == 1.0 ? cv::Scalar(150, 150, 150) : grey);
    cv::putText(img, fmt::format("{:g}", v), {8, py(v) + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.5, black);
  }
  const double norm = r.merged_ratio > 0 ? r.merged_ratio : 1.0;
  const cv::Scalar red(40, 40, 220), green(40, 160, 40);
  for (int i = 0; i < n; ++i) {
    const auto& row = r.rows[i];
    cv::putText(img, fmt::format("{:.3g}", row.exposure_s), {px(i) - 18, h - bottom + 20},
                cv::FONT_HERSHEY_SIMPLEX, 0.4, black);
    if (row.intensity_ratio > 0) {
      cv::circle(img, {px(i), py(row.intensity_ratio / norm)}, 4, red, cv::FILLED);
      if (i > 0 && r.rows[i - 1].intensity_ratio > 0) {
        cv::line(img, {px(i - 1), py(r.rows[i - 1].intensity_ratio / norm)},
                 {px(i), py(row.intensity_ratio / norm)}, red, 2);
      }
    }
    if (row.radiance_valid) {
      cv::circle(img, {px(i), py(row.radiance_ratio / norm)}, 4, green, cv::FILLED);
      if (i > 0 && r.rows[i - 1].radiance_valid) {
        cv::line(img, {px(i - 1), py(r.rows[i - 1].radiance_ratio / norm)},
                 {px(i), py(row.radiance_ratio / norm)}, green, 2);
      }
    }
  }
  cv::putText(img, "exposure time (s)", {w / 2 - 60, h - 12}, cv::FONT_HERSHEY_SIMPLEX, 0.5, black);
  cv::putText(img,
              fmt::format("pixel ratio / merged radiance ratio ({:.3g}); pixels {},{} / {},{}",
                          r.merged_ratio, r.a.x, r.a.y, r.b.x, r.b.y),
              {left, 20}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black);
  cv::putText(img, fmt::format("intensity (spread {:.2f}x)", r.intensity_spread),
              {left + 10, top + 20}, cv::FONT_HERSHEY_SIMPLEX, 0.5, red);
  cv::putText(img, fmt::format("radiance (spread {:.3f}x)", r.radiance_spread),
              {left + 10, top + 40}, cv::FONT_HERSHEY_SIMPLEX, 0.5, green);
  return img;
}

}  // namespace rig
