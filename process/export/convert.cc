// Exact maps between our bases and relight's, least-squares refits, and what each costs.
#include "process/export/convert.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <functional>
#include <limits>
#include <mutex>
#include <thread>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "process/model/harmonic/fit.h"

namespace rig {
namespace {

// 255 · sRGB(ρ): the model's values in relight's units (CV_32FC3, B, G, R).
// A photographs' model gives its code values as they are (no sRGB decode and encode: that
// round trip was two thirds of an export's time).
cv::Mat EncodedValues(const ReflectanceModel& m, const Vec3& d, double gain = 1) {
  if (gain == 1 && m.encoding() == ValueEncoding::kSrgb) {
    cv::Mat v = m.EvaluateEncoded(d);
    v *= 255.0;
    return v;
  }
  cv::Mat v = m.EvaluateRho(d).clone();
  float* p = v.ptr<float>();
  const size_t n = v.total() * 3;
  const float g = static_cast<float>(gain);
  for (size_t i = 0; i < n; ++i) p[i] = 255.0f * SrgbEncode(g * p[i]);
  return v;
}

// 1, or the scale that puts the 99.5th percentile of ρ over `lights` at white when ρ goes
// beyond 1 (radiance-map models: ρ relative to the capture lamp, not a display value).
double DisplayGain(const ReflectanceModel& m, const std::vector<Vec3>& lights) {
  std::vector<float> sample;
  const size_t step = std::max<size_t>(1, lights.size() / 12);
  for (size_t i = 0; i < lights.size(); i += step) {
    const cv::Mat v = m.EvaluateRho(lights[i]);
    const float* p = v.ptr<float>();
    const size_t n = v.total() * 3, stride = std::max<size_t>(1, n / 20000);
    for (size_t k = 0; k < n; k += stride) sample.push_back(p[k]);
  }
  if (sample.empty()) return 1;
  const size_t q = static_cast<size_t>(0.995 * (sample.size() - 1));
  std::nth_element(sample.begin(), sample.begin() + q, sample.end());
  return sample[q] > 1 ? 1.0 / sample[q] : 1.0;
}

// fn(i) for i in [0, n) on up to `hardware_concurrency` threads (renders are const and
// independent); fn must guard whatever it shares.
void ForEachLight(size_t n, const std::function<void(size_t)>& fn, const LightProgress& progress = {},
                  const char* stage = "") {
  const size_t threads = std::clamp<size_t>(std::thread::hardware_concurrency(), 1, 8);
  std::atomic<size_t> next{0};
  std::mutex told;
  size_t done = 0;
  auto work = [&] {
    for (size_t i = next++; i < n; i = next++) {
      fn(i);
      if (progress) {
        const std::lock_guard<std::mutex> lock(told);
        progress(stage, ++done, n);
      }
    }
  };
  std::vector<std::thread> pool;
  for (size_t t = 1; t < std::min(threads, n); ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

// Σ over lights of f(light), summed in light order whatever thread ran it (reproducible).
double SumOverLights(const std::vector<Vec3>& lights, const std::function<double(const Vec3&)>& f,
                     const LightProgress& progress = {}) {
  std::vector<double> each(lights.size(), 0);
  ForEachLight(lights.size(), [&](size_t i) { each[i] = f(lights[i]); }, progress, "measuring the error");
  double sum = 0;
  for (double v : each) sum += v;
  return sum;
}

double SquaredError(const cv::Mat& a, const cv::Mat& b) {
  double sum = 0;
  const float* pa = a.ptr<float>();
  const float* pb = b.ptr<float>();
  const size_t n = a.total() * 3;
  for (size_t i = 0; i < n; ++i) {
    const double d = std::clamp(pa[i], 0.0f, 255.0f) - std::clamp(pb[i], 0.0f, 255.0f);
    sum += d * d;
  }
  return sum;
}

double PsnrFromSse(double sse, double count) {
  if (sse <= 0) return std::numeric_limits<double>::infinity();
  return 10 * std::log10(255.0 * 255.0 / (sse / count));
}

Eigen::MatrixXd RelightDesign(RelightType type, int terms, const std::vector<Vec3>& dirs) {
  Eigen::MatrixXd w(static_cast<Eigen::Index>(dirs.size()), terms);
  double row[kMaxRelightTerms];
  for (size_t i = 0; i < dirs.size(); ++i) {
    RelightWeights(type, terms, dirs[i], row);
    for (int t = 0; t < terms; ++t) w(static_cast<Eigen::Index>(i), t) = row[t];
  }
  return w;
}

RelightCoefficients EmptyLike(const RelightTarget& t, int width, int height, bool lrgb) {
  RelightCoefficients c;
  c.type = t.type;
  c.terms = t.terms;
  c.lrgb = lrgb;
  c.width = width;
  c.height = height;
  for (int j = 0; j < t.terms; ++j)
    c.planes.push_back(cv::Mat::zeros(height, width, lrgb ? CV_32FC1 : CV_32FC3));
  if (lrgb) c.albedo = cv::Mat::zeros(height, width, CV_32FC3);
  return c;
}

Status CheckTarget(const RelightTarget& t) {
  const bool ok = t.type == RelightType::kPtm ? t.terms == 6 : (t.terms == 16 || t.terms == 9 || t.terms == 4);
  if (!ok || (t.lrgb && t.type != RelightType::kPtm)) {
    return MakeError(ErrorCode::kInvalidInput, "export",
                     "relight has no {} basis of {} terms{}", RelightTypeName(t.type), t.terms,
                     t.lrgb ? " in lrgb" : "");
  }
  return Ok();
}

// Least squares of the model's values at `lights` onto the target's rgb terms.
Result<RelightCoefficients> Refit(const ReflectanceModel& m, RelightTarget t,
                                  const std::vector<Vec3>& lights, double gain,
                                  const LightProgress& progress) {
  const Eigen::MatrixXd w = RelightDesign(t.type, t.terms, lights);
  if (lights.size() < static_cast<size_t>(t.terms)) {
    return MakeError(ErrorCode::kInvalidInput, "export",
                     "{} lights cannot determine {} {} terms", lights.size(), t.terms,
                     RelightTypeName(t.type));
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(w, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const auto& s = svd.singularValues();
  if (s(s.size() - 1) < 1e-9 * s(0)) {
    return MakeError(ErrorCode::kInvalidInput, "export",
                     "the {} lights do not determine the {} {} terms (rank deficient)",
                     lights.size(), t.terms, RelightTypeName(t.type));
  }
  const Eigen::MatrixXd p =
      svd.matrixV() * s.cwiseInverse().asDiagonal() * svd.matrixU().transpose();  // T × N
  t.lrgb = false;
  RelightCoefficients c = EmptyLike(t, m.width(), m.height(), false);
  // Renders in parallel, added in light order (one set of planes however many threads, and the
  // same file from every run): lights are handed out in order, so the one whose turn it is is
  // always being rendered.
  std::mutex add;
  std::condition_variable turn;
  size_t next_to_add = 0;
  ForEachLight(lights.size(), [&](size_t i) {
    const cv::Mat v = EncodedValues(m, lights[i], gain);
    std::unique_lock<std::mutex> lock(add);
    turn.wait(lock, [&] { return next_to_add == i; });
    for (int j = 0; j < t.terms; ++j)
      cv::scaleAdd(v, p(j, static_cast<Eigen::Index>(i)), c.planes[j], c.planes[j]);
    ++next_to_add;
    turn.notify_all();
  }, progress, "refitting");
  return c;
}

}  // namespace

// A luminance PTM times a per-pixel RGB albedo from an rgb PTM, by least squares over
// `lights`: luminance a = the mean of the channels' polynomials; albedo ρ_c = aᵀGc_c / aᵀGa
// (G = WᵀW), scaled so the largest channel is 255.
RelightCoefficients FactoriseLrgb(const RelightCoefficients& rgb, const std::vector<Vec3>& lights) {
  const Eigen::MatrixXd w = RelightDesign(RelightType::kPtm, 6, lights);
  const Eigen::Matrix<double, 6, 6> g = w.transpose() * w;
  RelightTarget t;
  RelightCoefficients out = EmptyLike(t, rgb.width, rgb.height, true);
  out.lights = rgb.lights;
  for (int y = 0; y < rgb.height; ++y)
    for (int x = 0; x < rgb.width; ++x) {
      Eigen::Matrix<double, 6, 3> c;
      for (int j = 0; j < 6; ++j) {
        const float* p = rgb.planes[j].ptr<float>(y) + 3 * x;
        for (int k = 0; k < 3; ++k) c(j, k) = p[2 - k];  // R, G, B
      }
      const Eigen::Matrix<double, 6, 1> a = c.rowwise().mean();
      const double aga = a.dot(g * a);
      if (!(aga > 1e-12)) continue;  // renders black
      Eigen::Vector3d rho = (c.transpose() * (g * a)) / aga;
      const double k = rho.maxCoeff();
      if (!(k > 1e-9)) continue;
      float* alb = out.albedo.ptr<float>(y) + 3 * x;
      for (int ch = 0; ch < 3; ++ch)
        alb[2 - ch] = static_cast<float>(std::clamp(std::nearbyint(255.0 * rho(ch) / k), 0.0, 255.0));
      for (int j = 0; j < 6; ++j) out.planes[j].ptr<float>(y)[x] = static_cast<float>(a(j) * k);
    }
  return out;
}

namespace {

double PsnrAt(const ReflectanceModel& source, const RelightCoefficients& c,
              const std::vector<Vec3>& lights, double gain, const LightProgress& progress) {
  const double sse = SumOverLights(lights, [&](const Vec3& l) {
    return SquaredError(EncodedValues(source, l, gain), RenderRelight(c, l));
  }, progress);
  return PsnrFromSse(sse, 3.0 * c.width * c.height * static_cast<double>(lights.size()));
}

void ZeroFlagged(const cv::Mat& valid, RelightCoefficients* c) {
  if (valid.empty()) return;
  const cv::Mat flagged = valid == 0;
  for (auto& p : c->planes) p.setTo(0, flagged);
  if (c->lrgb) c->albedo.setTo(0, flagged);
}

// The rest of a conversion once rgb coefficients are there: lrgb, the PSNR, the summary.
Result<Conversion> Finish(const ReflectanceModel& source, RelightCoefficients rgb,
                          const RelightTarget& target, const std::vector<Vec3>& lights,
                          bool exact, std::string how, double residual, double gain,
                          const LightProgress& progress) {
  Conversion out;
  out.gain = gain;
  out.exact = exact && !target.lrgb;
  out.map_residual = residual;
  if (target.lrgb) {
    out.coefficients = FactoriseLrgb(rgb, lights);
    how += fmt::format("; factorised into a luminance PTM x RGB albedo by least squares at {} lights",
                       lights.size());
  } else {
    out.coefficients = std::move(rgb);
  }
  ZeroFlagged(source.valid(), &out.coefficients);
  out.psnr_db = PsnrAt(source, out.coefficients, lights, gain, progress);
  out.lights = static_cast<int>(lights.size());
  out.how = std::move(how);
  return out;
}

}  // namespace

Result<Conversion> ConvertToRelight(const Model& model, const RelightTarget& target,
                                    const LightProgress& progress) {
  RIG_TRY(CheckTarget(target));
  const auto wrapped = WrapHarmonic(model);
  const std::vector<Vec3> lights =
      model.info().lamp_directions.empty() ? HemisphereDirections() : model.info().lamp_directions;
  const char* lights_name = model.info().lamp_directions.empty() ? "hemisphere directions"
                                                                 : "sampled lights";
  const bool srgb = model.info().transform.space == FitSpace::kSrgb;
  if (srgb) {
    // The same functions? Our basis onto relight's over the hemisphere: B_relight · M = B_ours.
    const std::vector<Vec3> dirs = HemisphereDirections();
    const Eigen::MatrixXd bt = RelightDesign(target.type, target.terms, dirs);
    const Eigen::MatrixXd bs = model.basis().Design(dirs);
    const Eigen::MatrixXd m = bt.colPivHouseholderQr().solve(bs);  // T × S
    const double residual = (bt * m - bs).cwiseAbs().maxCoeff();
    if (residual < 1e-9 * std::max(1.0, bs.cwiseAbs().maxCoeff())) {
      RelightTarget rgb_target = target;
      rgb_target.lrgb = false;
      RelightCoefficients c = EmptyLike(rgb_target, model.width(), model.height(), false);
      for (int t = 0; t < target.terms; ++t)
        for (int s = 0; s < model.basis().size(); ++s)
          if (m(t, s) != 0)
            cv::scaleAdd(model.coefficients()[s], 255.0 * m(t, s), c.planes[t], c.planes[t]);
      c.lights = model.info().lamp_directions;
      // relight evaluates HSH at θ = min(θ, π/2 − 0.01): lights at the horizon render there.
      size_t grazing = 0;
      for (const auto& l : lights) {
        const double n = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
        const double lxy = std::min(1.0, std::hypot(l[0], l[1]) / n);
        if (std::acos(std::sqrt(1 - lxy * lxy)) > M_PI / 2 - 0.01) ++grazing;
      }
      std::string how = fmt::format(
          "{} order {} mapped exactly onto relight's {} terms (map residual {:.1e}); PSNR over {} {}",
          model.basis().name(), model.basis().order(), RelightTypeName(target.type), residual,
          lights.size(), lights_name);
      if (target.type == RelightType::kHsh && grazing > 0) {
        how += fmt::format(", {} of them at the horizon, where relight clamps theta at pi/2 - 0.01",
                           grazing);
      }
      return Finish(*wrapped, std::move(c), target, lights, true, std::move(how), residual, 1, progress);
    }
  }
  const double gain = srgb ? 1.0 : DisplayGain(*wrapped, lights);
  RIG_ASSIGN_OR_RETURN(RelightCoefficients c, Refit(*wrapped, target, lights, gain, progress));
  c.lights = model.info().lamp_directions;
  std::string how = fmt::format("{} order {} ({} fit space) refitted onto relight's {} {} terms by "
                                "least squares at {} {}",
                                model.basis().name(), model.basis().order(),
                                FitSpaceName(model.info().transform.space),
                                RelightTypeName(target.type), target.terms, lights.size(), lights_name);
  if (gain != 1) {
    how += fmt::format("; rho scaled by {:.4g} (its 99.5th percentile at those lights is white)", gain);
  }
  return Finish(*wrapped, std::move(c), target, lights, false, std::move(how), 0, gain, progress);
}

Result<Conversion> ConvertToRelight(const ReflectanceModel& model, const RelightTarget& target,
                                    std::vector<Vec3> lights, const LightProgress& progress) {
  RIG_TRY(CheckTarget(target));
  const RelightCoefficients* rc = RelightCoefficientsOf(model);
  if (lights.empty() && rc) lights = rc->lights;
  if (lights.empty()) {
    for (const auto& d : HemisphereDirections())
      if (model.CheckRegion(d).inside) lights.push_back(d);
    if (lights.size() < 20) lights = HemisphereDirections();
  }
  if (rc && rc->type == target.type && rc->terms == target.terms) {
    if (rc->lrgb == target.lrgb) {
      Conversion out;
      out.coefficients = *rc;
      out.exact = true;
      out.psnr_db = std::numeric_limits<double>::infinity();
      out.lights = static_cast<int>(lights.size());
      out.how = fmt::format("{} copied as it is", rc->Summary());
      return out;
    }
    if (rc->lrgb) {  // luminance × albedo is an rgb PTM exactly
      RelightTarget rgb_target = target;
      RelightCoefficients c = EmptyLike(rgb_target, rc->width, rc->height, false);
      for (int j = 0; j < 6; ++j) {
        cv::Mat lum3;
        cv::merge(std::vector<cv::Mat>(3, rc->planes[j]), lum3);
        c.planes[j] = lum3.mul(rc->albedo, 1.0 / 255.0);
      }
      c.lights = rc->lights;
      return Finish(model, std::move(c), target, lights, true,
                    "ptm lrgb expanded exactly into rgb (coefficient x albedo / 255)", 0, 1, progress);
    }
    // rgb PTM to lrgb: factorised below, from the coefficients themselves.
    return Finish(model, *rc, target, lights, false, "ptm rgb", 0, 1, progress);
  }
  // A model of radiance maps (linear ρ, relative to the capture lamp) is scaled to display
  // values as a harmonic session's model is; a photographs' model holds display values.
  // It is refitted at the lights it was fitted to, when it knows them (as a harmonic session's).
  const bool linear = model.encoding() == ValueEncoding::kLinear;
  const std::vector<Vec3> fitted = model.fitted_lights();
  if (linear && !fitted.empty()) lights = fitted;
  const double gain = linear ? DisplayGain(model, lights) : 1.0;
  RIG_ASSIGN_OR_RETURN(RelightCoefficients c, Refit(model, target, lights, gain, progress));
  c.lights = rc ? rc->lights : std::vector<Vec3>{};
  if (linear && !fitted.empty()) c.lights = fitted;
  std::string how = fmt::format("{} refitted onto relight's {} {} terms by least squares at {} {}",
                                model.family(), RelightTypeName(target.type), target.terms,
                                lights.size(), linear && !fitted.empty() ? "sampled lights" : "lights");
  if (gain != 1) {
    how += fmt::format("; rho scaled by {:.4g} (its 99.5th percentile at those lights is white)", gain);
  }
  return Finish(model, std::move(c), target, lights, false, std::move(how), 0, gain, progress);
}

double RenderPsnrDb(const ReflectanceModel& a, const ReflectanceModel& b,
                    const std::vector<Vec3>& directions, double gain_a,
                    const LightProgress& progress) {
  const double sse = SumOverLights(directions, [&](const Vec3& d) {
    return SquaredError(EncodedValues(a, d, gain_a), EncodedValues(b, d));
  }, progress);
  return PsnrFromSse(sse, 3.0 * a.width() * a.height() * static_cast<double>(directions.size()));
}

}  // namespace rig
