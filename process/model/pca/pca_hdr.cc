// The PCA model of radiance maps, curve and size chosen at held-out lamps per byte.
#include "process/model/pca/pca_hdr.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numbers>
#include <thread>

#include <fmt/format.h>

#include "config/log.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

double SumOf(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s;
}

HdrCodeCurve CurveOf(const PcaHdrCurveCandidate& c, const std::vector<cv::Mat>& radiance,
                     const std::array<double, 3>& lamp, double high) {
  return FitHdrCurveOfRadiance(radiance, lamp, PcaHdrCurveOptions(c, high));
}

PcaOptions BaseOptions(const PcaHdrChoiceOptions& o) {
  PcaOptions po;
  po.thresholds = kHdrMaskThresholds;
  po.threads = o.threads;
  return po;
}

// Every candidate of one curve, fitted to the fold's maps and scored at the held-out lamps.
// The candidates of one (grid, components) share one fit — the qualities differ only in the
// planes' encoding — and each is scored as it would be read back from its files
// (PcaModel::AsStored: encoded and decoded in memory, the files' bytes counted).
Status ScoreCurve(const PcaHdrCurveCandidate& cc, const std::vector<cv::Mat>& radiance,
                  const std::vector<Vec3>& directions, const std::vector<int>& held,
                  const std::array<double, 3>& lamp, const PcaHdrChoiceOptions& o,
                  std::vector<PcaHdrCandidate>* out) {
  std::vector<cv::Mat> train;
  std::vector<Vec3> train_dirs;
  for (size_t l = 0; l < radiance.size(); ++l) {
    if (std::find(held.begin(), held.end(), static_cast<int>(l)) != held.end()) continue;
    train.push_back(radiance[l]);
    train_dirs.push_back(directions[l]);
  }
  const HdrCodeCurve curve = CurveOf(cc, train, lamp, o.high);
  const LightSamples samples = SamplesFromMaps(train, train_dirs, lamp, curve);
  const PcaOptions po = BaseOptions(o);
  const int kmax = *std::max_element(o.components.begin(), o.components.end());
  RIG_ASSIGN_OR_RETURN(PcaComponents comps, ComputePcaComponents(samples, po, kmax));
  const double pixels = static_cast<double>(samples.pixels());
  for (int res : o.resolutions)
    for (int k : o.components) {
      PcaOptions c = po;
      c.components = k;
      c.grid_resolution = res;
      RIG_ASSIGN_OR_RETURN(PcaModel m, FitPcaWith(samples, comps, c));
      m.set_hdr({curve, lamp, {}});
      for (int q : o.qualities) {
        m.set_jpeg_quality(q);
        uint64_t bytes = 0;
        RIG_ASSIGN_OR_RETURN(PcaModel back, m.AsStored(&bytes));
        PcaHdrCandidate r;
        r.curve = cc.Name();
        r.components = k;
        r.resolution = res;
        r.quality = q;
        r.bytes_per_pixel = static_cast<double>(bytes) / pixels;
        r.per_lamp = HeldOutErrors(*WrapPca(std::move(back)), radiance, directions, held, lamp);
        r.held_out_relative = std::sqrt(SumOf(r.per_lamp));
        r.within_budget = r.bytes_per_pixel <= o.max_bytes_per_pixel;
        out->push_back(r);
      }
    }
  return Ok();
}

// The curves' candidates in the order of o.curves (then grid, components, quality), the curves
// scored on up to o.threads threads at once: each curve's work is its own, so the scores do not
// depend on how many run together.
Status ScoreCurves(const std::vector<cv::Mat>& radiance, const std::vector<Vec3>& directions,
                   const std::vector<int>& held, const std::array<double, 3>& lamp,
                   const PcaHdrChoiceOptions& o, std::vector<PcaHdrCandidate>* out) {
  const size_t n = o.curves.size();
  std::vector<std::vector<PcaHdrCandidate>> per(n);
  std::vector<Status> status(n, Ok());
  std::atomic<size_t> next{0};
  auto worker = [&] {
    for (size_t i = next++; i < n; i = next++)
      status[i] = ScoreCurve(o.curves[i], radiance, directions, held, lamp, o, &per[i]);
  };
  std::vector<std::thread> pool;
  const int threads = std::max(1, std::min<int>(o.threads, static_cast<int>(n)));
  for (int t = 1; t < threads; ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  for (size_t i = 0; i < n; ++i) {
    if (!status[i].ok()) return status[i];
    out->insert(out->end(), per[i].begin(), per[i].end());
  }
  return Ok();
}

}  // namespace

// The model's squared error of ρ against the measured ρ at each held-out lamp, as a share of
// the measured ρ's squares over all of them (the shares sum to the relative error squared).
// Samples that are not finite in the map (a merged map can hold a few) are left out of both.
std::vector<double> HeldOutErrors(const ReflectanceModel& m, const std::vector<cv::Mat>& radiance,
                                  const std::vector<Vec3>& directions, const std::vector<int>& held,
                                  const std::array<double, 3>& lamp) {
  std::vector<double> err;
  double ref = 0;
  const double inv[3] = {1 / lamp[2], 1 / lamp[1], 1 / lamp[0]};  // B, G, R
  for (int l : held) {
    const cv::Mat pred = m.EvaluateRho(directions[l]);
    const cv::Mat& map = radiance[l];
    double e = 0;
    for (int y = 0; y < map.rows; ++y) {
      const auto* t = map.ptr<cv::Vec3f>(y);
      const auto* p = pred.ptr<cv::Vec3f>(y);
      for (int x = 0; x < map.cols; ++x)
        for (int c = 0; c < 3; ++c) {
          const double truth = t[x][c] * inv[c];
          if (!std::isfinite(truth)) continue;
          const double d = p[x][c] - truth;
          e += d * d;
          ref += truth * truth;
        }
    }
    err.push_back(e);
  }
  for (double& e : err) e = ref > 0 ? e / ref : 0;
  return err;
}

// The excess of a's squared relative error over b's, summed over the lamps, and its standard
// error: the lamps held out taken as a sample of the lamps, the excess a sum of n paired terms.
void PairedExcess(const std::vector<double>& a, const std::vector<double>& b, double* excess,
                  double* se) {
  const size_t n = std::min(a.size(), b.size());
  double mean = 0;
  for (size_t i = 0; i < n; ++i) mean += a[i] - b[i];
  *excess = mean;
  mean /= std::max<size_t>(1, n);
  double ss = 0;
  for (size_t i = 0; i < n; ++i) ss += (a[i] - b[i] - mean) * (a[i] - b[i] - mean);
  *se = n > 1 ? std::sqrt(static_cast<double>(n) * ss / static_cast<double>(n - 1)) : 0;
}

std::vector<int> HeldOutLamps(size_t lamps, int every) {
  std::vector<int> held;
  for (size_t l = 0; l < lamps; l += static_cast<size_t>(std::max(2, every)))
    held.push_back(static_cast<int>(l));
  return held;
}

std::vector<int> InteriorLamps(const std::vector<Vec3>& directions) {
  const size_t n = directions.size();
  std::vector<Vec3> d(n);
  for (size_t i = 0; i < n; ++i) {
    const Vec3& v = directions[i];
    const double len = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    d[i] = len > 0 ? Vec3{v[0] / len, v[1] / len, v[2] / len} : Vec3{0, 0, 1};
  }
  auto dot = [](const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  auto angle = [&](size_t i, size_t j) { return std::acos(std::clamp(dot(d[i], d[j]), -1.0, 1.0)); };
  std::vector<int> interior;
  for (size_t i = 0; i < n; ++i) {
    double nearest = INFINITY;
    for (size_t j = 0; j < n; ++j)
      if (j != i) nearest = std::min(nearest, angle(i, j));
    if (!(nearest > 1e-9)) continue;
    // Two axes of the tangent plane at the lamp; the neighbours' bearings in it.
    Vec3 a = std::abs(d[i][2]) < 0.9 ? Vec3{0, 0, 1} : Vec3{1, 0, 0};
    const double ad = dot(a, d[i]);
    for (int k = 0; k < 3; ++k) a[k] -= ad * d[i][k];
    const double an = std::sqrt(dot(a, a));
    for (double& v : a) v /= an;
    const Vec3 b{d[i][1] * a[2] - d[i][2] * a[1], d[i][2] * a[0] - d[i][0] * a[2],
                 d[i][0] * a[1] - d[i][1] * a[0]};
    std::vector<double> bearing;
    for (size_t j = 0; j < n; ++j)
      if (j != i && angle(i, j) <= 2 * nearest) bearing.push_back(std::atan2(dot(d[j], b), dot(d[j], a)));
    if (bearing.size() < 3) continue;
    std::sort(bearing.begin(), bearing.end());
    double gap = bearing.front() + 2 * std::numbers::pi - bearing.back();
    for (size_t k = 1; k < bearing.size(); ++k) gap = std::max(gap, bearing[k] - bearing[k - 1]);
    // Surrounded: no side of it without neighbours (an edge leaves a gap of about 180°, a
    // corner more; inside a grid or a dome the gaps are 60-90°).
    if (gap < 0.75 * std::numbers::pi) interior.push_back(static_cast<int>(i));
  }
  return interior;
}

std::vector<int> ChoiceHeldOutLamps(const std::vector<Vec3>& directions, const PcaHdrChoiceOptions& o) {
  const std::vector<int> every = HeldOutLamps(directions.size(), o.validation_every);
  if (o.held_out != "interior") return every;
  const std::vector<int> inner = InteriorLamps(directions);
  if (inner.size() < 3) return every;
  const size_t want = every.size();
  if (inner.size() <= want) return inner;
  std::vector<int> held;
  // Evenly spread over the interior lamps in their order (the grid's), ends included.
  for (size_t i = 0; i < want; ++i)
    held.push_back(inner[want > 1 ? (i * (inner.size() - 1) + (want - 1) / 2) / (want - 1) : inner.size() / 2]);
  held.erase(std::unique(held.begin(), held.end()), held.end());
  return held;
}

std::string HeldOutRuleName(const std::vector<Vec3>& directions, const PcaHdrChoiceOptions& o) {
  if (o.held_out == "interior" && InteriorLamps(directions).size() >= 3) return "spread inside the lamps' outline";
  const int n = std::max(2, o.validation_every);
  return fmt::format("every {}{}", n, n % 10 == 2 && n % 100 != 12 ? "nd" : n % 10 == 3 && n % 100 != 13 ? "rd" : "th");
}

HdrCurveOptions PcaHdrCurveOptions(const PcaHdrCurveCandidate& c, double high) {
  HdrCurveOptions o;
  o.curve = c.curve;
  o.gamma = c.gamma;
  o.high = high;
  return o;
}

PcaOptions PcaHdrModelOptions(const PcaHdrChoiceOptions& o, int components, int resolution,
                              int quality) {
  PcaOptions po = BaseOptions(o);
  po.components = components;
  po.grid_resolution = resolution;
  po.jpeg_quality = quality;
  return po;
}

std::string PcaHdrCurveCandidate::Name() const {
  return curve == HdrCurve::kPower ? fmt::format("power{:g}", gamma) : HdrCurveName(curve);
}

Result<PcaHdrFit> ChoosePcaHdr(const std::vector<cv::Mat>& radiance,
                               const std::vector<Vec3>& directions,
                               const std::array<double, 3>& lamp, const PcaHdrChoiceOptions& o) {
  const auto t0 = Clock::now();
  if (radiance.size() != directions.size() || radiance.size() < 8) {
    return MakeError(ErrorCode::kInvalidInput, "pca", "{} maps for {} directions: 8 or more needed",
                     radiance.size(), directions.size());
  }
  if (o.curves.empty() || o.components.empty() || o.resolutions.empty() || o.qualities.empty()) {
    return MakeError(ErrorCode::kInvalidInput, "pca", "no candidates");
  }
  const std::vector<int> held = ChoiceHeldOutLamps(directions, o);
  PcaHdrFit fit;
  RIG_TRY(ScoreCurves(radiance, directions, held, lamp, o, &fit.candidates));
  for (size_t i = 0; i < fit.candidates.size(); ++i) {
    const auto& c = fit.candidates[i];
    if (c.within_budget && (fit.best < 0 || c.held_out_relative < fit.candidates[fit.best].held_out_relative))
      fit.best = static_cast<int>(i);
  }
  bool over_budget = false;
  if (fit.best < 0) {
    // A small image: the grid's JSON alone may exceed the budget. The smallest candidate, said.
    over_budget = true;
    for (auto& c : fit.candidates) c.within_budget = true;
    for (size_t i = 0; i < fit.candidates.size(); ++i)
      if (fit.best < 0 || fit.candidates[i].bytes_per_pixel < fit.candidates[fit.best].bytes_per_pixel)
        fit.best = static_cast<int>(i);
  }
  for (auto& c : fit.candidates)
    PairedExcess(c.per_lamp, fit.candidates[fit.best].per_lamp, &c.excess, &c.excess_se);
  for (size_t i = 0; i < fit.candidates.size(); ++i) {
    const auto& c = fit.candidates[i];
    if (c.within_budget && c.excess <= o.noise_z * c.excess_se &&
        (fit.chosen < 0 || c.bytes_per_pixel < fit.candidates[fit.chosen].bytes_per_pixel))
      fit.chosen = static_cast<int>(i);
  }
  const PcaHdrCandidate& ch = fit.candidates[fit.chosen];
  const auto& best = fit.candidates[fit.best];
  for (const auto& c : o.curves)
    if (c.Name() == ch.curve) fit.curve = c;
  fit.options = PcaHdrModelOptions(o, ch.components, ch.resolution, ch.quality);
  fit.reason = fmt::format(
      "{} curve, {} components on a {}x{} grid at JPEG q{}: {:.4f} relative error at the {} lamps "
      "held out, {:.2f} B/px — the smallest of {} candidates within {:g} standard error of the "
      "best under {:.1f} B/px, the error's noise measured across the lamps held out ({} k{} {}x{} "
      "q{}: {:.4f}, {:.2f} B/px)",
      ch.curve, ch.components, ch.resolution, ch.resolution, ch.quality, ch.held_out_relative,
      held.size(), ch.bytes_per_pixel, fit.candidates.size(), o.noise_z, o.max_bytes_per_pixel, best.curve, best.components, best.resolution, best.resolution,
      best.quality, best.held_out_relative, best.bytes_per_pixel);
  if (over_budget) {
    fit.reason = fmt::format("no candidate fits {:.1f} B/px at {}x{} (the grid is stored whatever the "
                             "image's size), so the smallest: ", o.max_bytes_per_pixel,
                             radiance[0].cols, radiance[0].rows) + fit.reason;
    if (o.warn_over_budget) Log("process")->warn("pca of radiance maps: {}", fit.reason);
  }
  fit.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return fit;
}

Result<PcaHdrFit> FitPcaHdrAuto(const std::vector<cv::Mat>& radiance,
                                const std::vector<Vec3>& directions,
                                const std::array<double, 3>& lamp,
                                const LightFrameConfig& light_frame,
                                const PcaHdrChoiceOptions& o) {
  const auto t0 = Clock::now();
  RIG_ASSIGN_OR_RETURN(PcaHdrFit fit, ChoosePcaHdr(radiance, directions, lamp, o));
  const HdrCodeCurve curve = CurveOf(fit.curve, radiance, lamp, o.high);
  RIG_ASSIGN_OR_RETURN(fit.model, FitPca(SamplesFromMaps(radiance, directions, lamp, curve), fit.options));
  fit.model.set_hdr({curve, lamp, light_frame});
  fit.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  Log("process")->info("pca of radiance maps: {} ({:.2f} s)", fit.reason, fit.time_s);
  return fit;
}

std::string PcaHdrChoiceMarkdown(const PcaHdrFit& fit) {
  std::string md =
      "| curve | components | grid | JPEG q | B/px | held-out relative error | excess of its "
      "square over the best's (± standard error across the lamps) | |\n"
      "|---|---|---|---|---|---|---|---|\n";
  for (size_t i = 0; i < fit.candidates.size(); ++i) {
    const auto& c = fit.candidates[i];
    md += fmt::format("| {} | {} | {} | {} | {:.2f} | {:.4f} | {:.2e} ± {:.2e} | {} |\n", c.curve,
                      c.components, c.resolution, c.quality, c.bytes_per_pixel, c.held_out_relative,
                      c.excess, c.excess_se,
                      static_cast<int>(i) == fit.chosen ? "**chosen**"
                      : static_cast<int>(i) == fit.best ? "best"
                      : c.within_budget                 ? ""
                                                        : "over budget");
  }
  return md;
}

}  // namespace rig
