// Speed against accuracy of every reflectance-model choice on the same data.
#include "process/evaluate/evaluate.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>

#include <fmt/format.h>

#include "config/console.h"
#include "config/log.h"
#include "process/evaluate/plot.h"
#include "process/model/hdr_codes.h"
#include "process/model/light_direction.h"
#include "process/model/pca/pca.h"
#include "process/model/session/family_choice.h"
#include "process/model/session/pca_session.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Σ over pixels and channels of (a·s − t)² and of t², optionally on a pixel mask.
struct ErrorSum {
  double err = 0, ref = 0;
  void Add(const cv::Mat& estimate, double scale, const cv::Mat& truth, const cv::Mat& mask) {
    for (int y = 0; y < truth.rows; ++y) {
      const float* e = estimate.ptr<float>(y);
      const float* t = truth.ptr<float>(y);
      const uint8_t* m = mask.empty() ? nullptr : mask.ptr<uint8_t>(y);
      for (int x = 0; x < truth.cols; ++x) {
        if (m && !m[x]) continue;
        for (int c = 0; c < 3; ++c) {
          const double d = e[3 * x + c] / scale - t[3 * x + c];
          err += d * d;
          ref += double(t[3 * x + c]) * t[3 * x + c];
        }
      }
    }
  }
  double Relative() const { return ref > 0 ? std::sqrt(err / ref) : kNan; }
};

struct Candidate {
  BasisKind basis;
  FitMethod method;
  int order;
};

}  // namespace

double MedianSeconds(std::vector<double> seconds) {
  if (seconds.empty()) return kNan;
  std::sort(seconds.begin(), seconds.end());
  const size_t n = seconds.size();
  return n % 2 ? seconds[n / 2] : 0.5 * (seconds[n / 2 - 1] + seconds[n / 2]);
}

std::string MethodResult::Name() const { return basis + "-" + method; }

double MethodResult::Error() const {
  return std::isfinite(truth_relative) ? truth_relative : loo_relative;
}

void MarkParetoFronts(std::vector<MethodResult>* rows) {
  auto front = [&](auto cost, bool MethodResult::*flag) {
    for (auto& a : *rows) {
      a.*flag = false;
      if (!a.supported || !std::isfinite(a.Error())) continue;
      bool dominated = false;
      for (const auto& b : *rows) {
        if (&a == &b || !b.supported || !std::isfinite(b.Error())) continue;
        const bool no_worse = cost(b) <= cost(a) && b.Error() <= a.Error();
        const bool better = cost(b) < cost(a) || b.Error() < a.Error();
        if (no_worse && better) {
          dominated = true;
          break;
        }
      }
      a.*flag = !dominated;
    }
  };
  front([](const MethodResult& r) { return r.fit_time_s; }, &MethodResult::pareto_time);
  front([](const MethodResult& r) { return r.bytes_per_pixel; }, &MethodResult::pareto_storage);
}

namespace {

FitInput FitInputOf(const MethodEvalInput& in) {
  FitInput fit_in;
  fit_in.radiance = in.radiance;
  fit_in.lamp_radiance_rgb = in.lamp_radiance_rgb;
  fit_in.light_frame = in.light_frame;
  for (size_t i = 0; i < in.radiance.size(); ++i)
    fit_in.directions.push_back(LightDirection(in.h_deg[i], in.v_deg[i], in.light_frame));
  fit_in.weights = GridQuadratureWeights(in.h_deg, in.v_deg);
  return fit_in;
}

// RMS of the data's ρ: the scale the LOO error is reported against.
double RhoRms(const MethodEvalInput& in, const cv::Scalar& lamp_bgr) {
  double sum_sq = 0, count = 0;
  for (const auto& r : in.radiance) {
    cv::Mat rho;
    cv::divide(r, lamp_bgr, rho);
    sum_sq += cv::norm(rho, cv::NORM_L2SQR);
    count += static_cast<double>(rho.total() * 3);
  }
  return std::sqrt(sum_sq / count);
}

// Truth: the shadow mask (CV_8U: 1 where the truth is 0 in some channel at some sampled
// pose) and its complement, the held-out and outside truth maps.
struct TruthMaps {
  cv::Mat shadowed, lit;
  std::vector<cv::Mat> held, outside;
};

// Fills out's truth_scale and pixel counts.
TruthMaps TruthMapsOf(const MethodEvalInput& in, const cv::Scalar& lamp_bgr, MethodEvaluation* out) {
  TruthMaps t;
  double st = 0, tt = 0;
  t.shadowed = cv::Mat::zeros(in.radiance[0].size(), CV_8U);
  for (size_t i = 0; i < in.radiance.size(); ++i) {
    cv::Mat truth = in.truth_rho(in.h_deg[i], in.v_deg[i]), rho;
    cv::divide(in.radiance[i], lamp_bgr, rho);
    st += rho.dot(truth);
    tt += truth.dot(truth);
    for (int y = 0; y < truth.rows; ++y)
      for (int x = 0; x < truth.cols; ++x) {
        const cv::Vec3f v = truth.at<cv::Vec3f>(y, x);
        if (v[0] <= 0 || v[1] <= 0 || v[2] <= 0) t.shadowed.at<uint8_t>(y, x) = 1;
      }
  }
  out->truth_scale = tt > 0 ? st / tt : 1;
  out->shadowed_pixels = static_cast<size_t>(cv::countNonZero(t.shadowed));
  out->lit_pixels = t.shadowed.total() - out->shadowed_pixels;
  for (auto [h, v] : in.held_out) t.held.push_back(in.truth_rho(h, v));
  for (auto [h, v] : in.outside) t.outside.push_back(in.truth_rho(h, v));
  t.lit = t.shadowed == 0;
  return t;
}

std::vector<Candidate> CandidatesUpTo(int max_order) {
  std::vector<Candidate> candidates;
  for (FitMethod m : {FitMethod::kQuadrature, FitMethod::kLs, FitMethod::kRls})
    for (int l = 0; l <= max_order; ++l) candidates.push_back({BasisKind::kSh, m, l});
  for (FitMethod m : {FitMethod::kLs, FitMethod::kRls})
    for (int l = 0; l <= max_order; ++l) candidates.push_back({BasisKind::kHsh, m, l});
  for (FitMethod m : {FitMethod::kLs, FitMethod::kRls})
    for (int l = 1; l <= 4; ++l) candidates.push_back({BasisKind::kPtm, m, l});
  return candidates;
}

// The truth's relative errors of a fitted model: at held-out poses (all, shadowed, lit pixels)
// and outside the sampled range.
template <class M>
void CompareWithTruth(const M& model, const MethodEvalInput& in, const TruthMaps& truth,
                      double truth_scale, MethodResult* r) {
  ErrorSum all, sh, li, ex;
  for (size_t k = 0; k < in.held_out.size(); ++k) {
    const auto [h, v] = in.held_out[k];
    cv::Mat rho = model.EvaluateRho(LightDirection(h, v, in.light_frame));
    all.Add(rho, truth_scale, truth.held[k], cv::Mat());
    sh.Add(rho, truth_scale, truth.held[k], truth.shadowed);
    li.Add(rho, truth_scale, truth.held[k], truth.lit);
  }
  for (size_t k = 0; k < in.outside.size(); ++k) {
    const auto [h, v] = in.outside[k];
    ex.Add(model.EvaluateRho(LightDirection(h, v, in.light_frame)), truth_scale, truth.outside[k],
           cv::Mat());
  }
  r->truth_relative = all.Relative();
  r->truth_relative_shadowed = sh.Relative();
  r->truth_relative_lit = li.Relative();
  r->extrapolation_relative = ex.Relative();
}

MethodResult BlankRow() {
  MethodResult r;
  r.fit_time_s = r.render_s_per_mp = r.condition = r.loo_relative = kNan;
  r.truth_relative = r.truth_relative_lit = r.truth_relative_shadowed = r.extrapolation_relative = kNan;
  return r;
}

// Render time of a model: ρ for every pixel at three of the sampled lamps, per run; the
// median run, per megapixel.
template <class M>
double RenderSecondsPerMp(const M& model, const FitInput& fit_in, int runs) {
  const size_t n = fit_in.directions.size();
  const double megapixels = fit_in.radiance[0].total() / 1e6;
  std::vector<double> render_s;
  for (int run = 0; run < runs; ++run) {
    const auto t0 = Clock::now();
    for (size_t k = 0; k < 3; ++k) {
      cv::Mat rho = model.EvaluateRho(fit_in.directions[k * (n - 1) / 2]);
      (void)rho;
    }
    render_s.push_back(Since(t0) / 3 / megapixels);
  }
  return MedianSeconds(render_s);
}

// "power1.25-q95" ("power1.25-g32-q95" when several grids are measured).
std::string PcaMethodName(const std::string& curve, int resolution, int quality, bool grids) {
  return grids ? fmt::format("{}-g{}-q{}", curve, resolution, quality) : fmt::format("{}-q{}", curve, quality);
}

// The PCA family's rows: per value curve, grid and size one fit to every map (timed as a
// session fits it: the curve, the codes, the components and the light basis), then per JPEG
// quality the model as it ships — encoded, its bytes counted, read back from them — measured
// as the harmonic rows are. No leave-one-out: the family is judged at held-out lamps (the
// truth's, or the session's own family choice).
void AddPcaRows(const MethodEvalInput& in, const FitInput& fit_in, const TruthMaps& truth,
                const std::vector<int>& components, MethodEvaluation* out) {
  const int runs = std::max(1, in.timing_runs);
  const double pixels = static_cast<double>(in.radiance[0].total());
  const bool grids = in.pca.resolutions.size() > 1;
  ProgressTask task("evaluating PCA models",
                    static_cast<int64_t>(in.pca.curves.size() * in.pca.resolutions.size() * components.size()));
  for (const auto& cc : in.pca.curves)
    for (int res : in.pca.resolutions)
      for (int k : components) {
        task.Advance(1, fmt::format("pca {} {} components", cc.Name(), k));
        const int q0 = in.pca.qualities.empty() ? 95 : in.pca.qualities.front();
        std::vector<double> fit_s;
        std::optional<PcaModel> model;
        std::string refusal;
        for (int run = 0; run < runs && refusal.empty(); ++run) {
          const auto t0 = Clock::now();
          const HdrCodeCurve curve =
              FitHdrCurveOfRadiance(in.radiance, in.lamp_radiance_rgb, PcaHdrCurveOptions(cc, in.pca.high));
          auto m = FitPca(SamplesFromMaps(in.radiance, fit_in.directions, in.lamp_radiance_rgb, curve),
                          PcaHdrModelOptions(in.pca, k, res, q0));
          fit_s.push_back(Since(t0));
          if (!m.ok()) {
            refusal = m.error().message;
          } else if (!model) {
            m->set_hdr({curve, in.lamp_radiance_rgb, in.light_frame});
            model = std::move(*m);
          }
        }
        for (int q : in.pca.qualities) {
          MethodResult r = BlankRow();
          r.basis = "pca";
          r.method = PcaMethodName(cc.Name(), res, q, grids);
          r.order = r.terms = k;
          uint64_t bytes = 0;
          Result<PcaModel> back = refusal.empty() ? (model->set_jpeg_quality(q), model->AsStored(&bytes))
                                                  : Result<PcaModel>(MakeError(ErrorCode::kInvalidInput, "pca", "{}", refusal));
          if (!back.ok()) {
            r.refusal = back.error().message;
            out->rows.push_back(r);
            continue;
          }
          r.supported = true;
          r.bytes_per_pixel = static_cast<double>(bytes) / pixels;
          r.fit_time_s = MedianSeconds(fit_s);
          const std::unique_ptr<ReflectanceModel> stored = WrapPca(std::move(*back));
          r.render_s_per_mp = RenderSecondsPerMp(*stored, fit_in, runs);
          if (out->has_truth) CompareWithTruth(*stored, in, truth, out->truth_scale, &r);
          out->rows.push_back(r);
        }
      }
}

// The session's default family, chosen as `rig process` chooses it (null: harmonic without a
// choice, the reason in *why); with the other held-out rule too, in *other (for the report).
std::optional<SessionFamilyChoice> SessionChoice(const MethodEvalInput& in, const FitInput& fit_in,
                                                 std::string* why,
                                                 std::optional<SessionFamilyChoice>* other) {
  if (in.model_family == "harmonic") {
    *why = "harmonic, as configured (model_family)";
    return std::nullopt;
  }
  if (NearLamp::FromLightFrame(in.light_frame, in.radiance[0].rows).near()) {
    *why = "harmonic: the lamp is near, and only the harmonic family models its fall-off";
    return std::nullopt;
  }
  if (in.radiance.size() < 8) {
    *why = fmt::format("harmonic: {} maps, and the PCA family needs 8 or more", in.radiance.size());
    return std::nullopt;
  }
  ProgressTask task("choosing the session's model family", 2);
  PcaHdrChoiceOptions po = in.pca;
  po.warn_over_budget = false;
  // On the maps' central region, as `rig process` chooses (the whole map up to 512 × 512).
  const cv::Rect region = PcaHdrChoiceRegion(in.radiance[0].cols, in.radiance[0].rows);
  std::vector<cv::Mat> maps;
  maps.reserve(in.radiance.size());
  for (const cv::Mat& m : in.radiance) maps.push_back(region.size() == m.size() ? m : m(region).clone());
  auto chosen = ChooseSessionFamily(maps, fit_in.directions, in.lamp_radiance_rgb, in.selection,
                                    in.bytes_per_coefficient, po);
  task.Advance(1);
  PcaHdrChoiceOptions alt = po;
  alt.held_out = po.held_out == "interior" ? "every" : "interior";
  if (HeldOutRuleName(fit_in.directions, alt) != HeldOutRuleName(fit_in.directions, po)) {
    auto again = ChooseSessionFamily(maps, fit_in.directions, in.lamp_radiance_rgb, in.selection,
                                     in.bytes_per_coefficient, alt);
    if (again.ok()) *other = std::move(*again);
  }
  task.Advance(1);
  if (!chosen.ok()) {
    *why = "none: " + chosen.error().message;
    return std::nullopt;
  }
  if (in.model_family == "pca") chosen->family = "pca";
  *why = in.model_family == "pca" ? "pca, as configured (model_family)" : chosen->reason;
  return std::move(*chosen);
}

}  // namespace

Result<MethodEvaluation> EvaluateMethods(const MethodEvalInput& in) {
  auto log = Log("evaluate");
  const size_t n = in.radiance.size();
  if (n < 2 || in.h_deg.size() != n || in.v_deg.size() != n) {
    return MakeError(ErrorCode::kInvalidInput, "evaluate", "{} radiance maps for {} poses", n,
                     in.h_deg.size());
  }
  MethodEvaluation out;
  out.has_truth = static_cast<bool>(in.truth_rho);
  const FitInput fit_in = FitInputOf(in);
  const cv::Scalar lamp_bgr(in.lamp_radiance_rgb[2], in.lamp_radiance_rgb[1], in.lamp_radiance_rgb[0]);
  const double rho_rms = RhoRms(in, lamp_bgr);
  const TruthMaps truth = out.has_truth ? TruthMapsOf(in, lamp_bgr, &out) : TruthMaps{};

  const std::vector<Candidate> candidates = CandidatesUpTo(in.max_order);
  const int runs = std::max(1, in.timing_runs);
  out.timing_runs = runs;
  ProgressTask task("evaluating models", static_cast<int64_t>(candidates.size()));
  for (const auto& c : candidates) {
    task.Advance(1, fmt::format("{} {} order {}", BasisKindName(c.basis), FitMethodName(c.method), c.order));
    MethodResult r = BlankRow();
    r.basis = BasisKindName(c.basis);
    r.method = FitMethodName(c.method);
    r.order = c.order;
    r.terms = Basis::SizeFor(c.basis, c.order);
    r.bytes_per_pixel = 3.0 * r.terms * in.bytes_per_coefficient;
    FitOptions o = in.selection;
    o.basis = c.basis;
    o.method = c.method;
    o.order = c.order;
    o.max_order = std::max(c.order, 0);
    // Only this order: the selection table of the automatic fit covers the others.
    auto fit = FitModel(fit_in, o);
    if (!fit.ok()) {
      r.refusal = fit.error().message;
      out.rows.push_back(r);
      continue;
    }
    r.supported = true;
    // The same fit again for its time: the median of the runs (the first run's model is kept).
    std::vector<double> fit_s = {fit->fit_time_s};
    for (int run = 1; run < runs; ++run) {
      auto again = FitModel(fit_in, o);
      if (again.ok()) fit_s.push_back(again->fit_time_s);
    }
    r.fit_time_s = MedianSeconds(fit_s);
    r.condition = fit->model.info().condition;
    r.loo_relative = fit->model.info().loo_rmse / rho_rms;
    r.render_s_per_mp = RenderSecondsPerMp(fit->model, fit_in, runs);
    if (out.has_truth) CompareWithTruth(fit->model, in, truth, out.truth_scale, &r);
    log->debug("{} order {}: fit {:.3f} s, LOO {:.4f}, truth {:.4f}", r.Name(), r.order,
               r.fit_time_s, r.loo_relative, r.truth_relative);
    out.rows.push_back(r);
  }

  // The automatic choice, with the session's own settings.
  auto chosen = FitModel(fit_in, in.selection);
  if (chosen.ok()) {
    const std::string basis = BasisKindName(in.selection.basis), method = FitMethodName(in.selection.method);
    out.selected = fmt::format("{}-{} order {}", basis, method, chosen->selection.order);
    for (auto& r : out.rows)
      r.selected = r.basis == basis && r.method == method && r.order == chosen->selection.order;
  } else {
    out.selected = "none: " + chosen.error().message;
  }

  // The session's default: the family chosen per byte at held-out lamps, then its model
  // among the rows (the PCA size it chose is measured even when not in pca_components).
  std::optional<SessionFamilyChoice> other_rule;
  const std::optional<SessionFamilyChoice> family =
      SessionChoice(in, fit_in, &out.session_default_reason, &other_rule);
  std::vector<int> components = in.pca_components;
  const PcaHdrCandidate* pick = nullptr;
  if (family && family->family == "pca" && family->pca.chosen >= 0) {
    pick = &family->pca.candidates[static_cast<size_t>(family->pca.chosen)];
    if (std::find(components.begin(), components.end(), pick->components) == components.end()) {
      components.push_back(pick->components);
      std::sort(components.begin(), components.end());
    }
  }
  if (other_rule && other_rule->pca.chosen >= 0) {
    const int k = other_rule->pca.candidates[static_cast<size_t>(other_rule->pca.chosen)].components;
    if (std::find(components.begin(), components.end(), k) == components.end()) {
      components.push_back(k);
      std::sort(components.begin(), components.end());
    }
  }
  if (in.pca_family && n >= 8) AddPcaRows(in, fit_in, truth, components, &out);
  if (pick) {
    const bool grids = in.pca.resolutions.size() > 1;
    for (auto& r : out.rows) {
      r.session_default = r.basis == "pca" && r.order == pick->components &&
                          r.method == PcaMethodName(pick->curve, pick->resolution, pick->quality, grids);
      if (r.session_default) out.session_default = fmt::format("{}, {} components", r.Name(), r.order);
    }
  } else if (out.session_default_reason.rfind("none", 0) != 0 && chosen.ok()) {
    for (auto& r : out.rows) {
      r.session_default = r.selected;
      if (r.selected) out.session_default = out.selected;
    }
  }
  if (out.session_default.empty() && pick)
    out.session_default = fmt::format("pca {}: not among the rows", pick->curve);
  // Each held-out rule's verdict beside the truth of what each family would make.
  const std::optional<SessionFamilyChoice>* rules[] = {&family, &other_rule};
  for (const auto* f : rules) {
    if (!*f) continue;
    const SessionFamilyChoice& c = **f;
    FamilyFold fold;
    fold.rule = c.held_out_rule;
    fold.held_out = c.held_out;
    fold.chosen = c.family;
    fold.session = f == &family;
    fold.pca_held_out = c.pca_candidate.held_out_relative;
    fold.harmonic_held_out = c.harmonic_candidate.held_out_relative;
    fold.pca_components = c.pca_candidate.size;
    fold.harmonic_order = c.harmonic_candidate.size;
    fold.pca_bytes_per_pixel = c.pca_candidate.bytes_per_pixel;
    fold.harmonic_bytes_per_pixel = c.harmonic_candidate.bytes_per_pixel;
    fold.pca_truth = fold.harmonic_truth = std::numeric_limits<double>::quiet_NaN();
    const bool grids = in.pca.resolutions.size() > 1;
    if (c.pca.chosen >= 0) {
      const PcaHdrCandidate& p = c.pca.candidates[static_cast<size_t>(c.pca.chosen)];
      for (const auto& r : out.rows)
        if (r.supported && r.basis == "pca" && r.order == p.components &&
            r.method == PcaMethodName(p.curve, p.resolution, p.quality, grids))
          fold.pca_truth = r.truth_relative;
    }
    const std::string hb = BasisKindName(in.selection.basis), hm = FitMethodName(in.selection.method);
    for (const auto& r : out.rows)
      if (r.supported && r.basis == hb && r.method == hm && r.order == fold.harmonic_order)
        fold.harmonic_truth = r.truth_relative;
    out.family_folds.push_back(fold);
  }
  MarkParetoFronts(&out.rows);
  return out;
}

namespace {

std::string FormatNum(double v, const char* fmt_spec = "{:.4g}") {
  return std::isfinite(v) ? fmt::format(fmt::runtime(fmt_spec), v) : "";
}

// Round-trip precision for the CSV (its readers compare values).
std::string NumFull(double v) { return std::isfinite(v) ? fmt::format("{}", v) : ""; }

}  // namespace

std::string MethodsCsv(const MethodEvaluation& e) {
  std::string s =
      "basis,method,order,terms,supported,fit_time_s,render_s_per_mp,bytes_per_pixel,condition,"
      "loo_relative_rmse,truth_relative_rmse,truth_relative_rmse_shadowed,"
      "truth_relative_rmse_lit,extrapolation_relative_rmse,pareto_time,pareto_storage,selected,"
      "session_default,refusal\n";
  for (const auto& r : e.rows) {
    std::string refusal = r.refusal;
    for (char& ch : refusal)
      if (ch == '"') ch = '\'';
    s += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},\"{}\"\n", r.basis,
                     r.method, r.order, r.terms, r.supported ? 1 : 0, NumFull(r.fit_time_s),
                     NumFull(r.render_s_per_mp), r.bytes_per_pixel, NumFull(r.condition),
                     NumFull(r.loo_relative), NumFull(r.truth_relative), NumFull(r.truth_relative_shadowed),
                     NumFull(r.truth_relative_lit), NumFull(r.extrapolation_relative), r.pareto_time ? 1 : 0,
                     r.pareto_storage ? 1 : 0, r.selected ? 1 : 0, r.session_default ? 1 : 0, refusal);
  }
  return s;
}

std::string MethodsMarkdown(const MethodEvaluation& e) {
  std::string s = fmt::format(
      "| model | order | terms | fit s ({}) | render s/MP ({}) | bytes/px | cond | LOO rel. | "
      "truth rel. (shadowed / lit) | beyond region | front |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|\n",
      e.timing_runs > 1 ? fmt::format("median of {}", e.timing_runs) : "one run",
      e.timing_runs > 1 ? fmt::format("median of {}", e.timing_runs) : "one run");
  for (const auto& r : e.rows) {
    if (!r.supported) {
      // The fit's own message usually begins with "refused:"; not said twice.
      const bool said = r.refusal.rfind("refused", 0) == 0;
      s += fmt::format("| {} | {} | {} | {}{} |||||||\n", r.Name(), r.order, r.terms,
                       said ? "" : "refused: ", r.refusal);
      continue;
    }
    std::string front = r.selected ? "**selected** " : "";
    if (r.session_default) front += "**session default** ";
    if (r.pareto_time) front += "time ";
    if (r.pareto_storage) front += "storage";
    s += fmt::format("| {}{}{} | {} | {} | {:.4f} | {:.4f} | {:g} | {} | {} | {} ({} / {}) | {} | {} |\n",
                     r.selected ? "**" : "", r.Name(), r.selected ? "**" : "", r.order, r.terms,
                     r.fit_time_s, r.render_s_per_mp, r.bytes_per_pixel,
                     std::isinf(r.condition) ? std::string("ill-conditioned") : FormatNum(r.condition, "{:.3g}"),
                     FormatNum(r.loo_relative), FormatNum(r.truth_relative), FormatNum(r.truth_relative_shadowed),
                     FormatNum(r.truth_relative_lit), FormatNum(r.extrapolation_relative), front);
  }
  return s;
}

namespace {

// One series per method (its orders in order), the fronts ringed, the selection highlighted.
cv::Mat ChartAgainst(const MethodEvaluation& e, bool storage) {
  std::vector<PlotSeries> series;
  std::vector<PlotMarker> markers;
  double min_x = std::numeric_limits<double>::infinity(), max_x = 0;
  for (const auto& r : e.rows) {
    if (!r.supported) continue;
    auto it = std::find_if(series.begin(), series.end(), [&](const PlotSeries& s) { return s.label == r.Name(); });
    if (it == series.end()) {
      series.push_back({r.Name(), {}, {}, {}, true});
      it = series.end() - 1;
    }
    it->x.push_back(storage ? r.bytes_per_pixel : r.fit_time_s);
    it->y.push_back(r.Error());
    it->point_labels.push_back(std::to_string(r.order));
    if (storage ? r.pareto_storage : r.pareto_time)
      markers.push_back({it->x.back(), r.Error(), PlotMarker::Style::kRing, {0, 0, 0}, "Pareto front"});
    if (r.selected)
      markers.push_back({it->x.back(), r.Error(), PlotMarker::Style::kBigRing, {0, 0, 230},
                         "selected: " + e.selected});
    if (r.session_default)
      markers.push_back({it->x.back(), r.Error(), PlotMarker::Style::kSquare, {0, 150, 0},
                         "session default"});
    if (storage && std::isfinite(r.bytes_per_pixel) && r.bytes_per_pixel > 0) {
      min_x = std::min(min_x, r.bytes_per_pixel);
      max_x = std::max(max_x, r.bytes_per_pixel);
    }
  }
  PlotOptions o;
  o.title = storage ? "Error against storage" : "Error against fit time";
  o.x_label = storage ? "bytes per pixel (3 colours)" : (e.timing_runs > 1 ? fmt::format("fit time (s, median of {} runs)", e.timing_runs) : "fit time (s)");
  o.y_label = e.has_truth ? "relative RMS error vs truth, held-out lamps" : "relative LOO RMS error";
  // Bytes on a log axis when the families span more than a decade (PCA's few bytes beside
  // harmonic planes of hundreds).
  o.log_x = !storage || max_x > 10 * min_x;
  o.log_y = true;
  o.notes = {"one line per method, numbers = order (PCA: components); black rings: Pareto front",
             "red: the harmonic family's automatic order; green square: the session's default model"};
  return DrawPlot(series, markers, o);
}

}  // namespace

cv::Mat ChartErrorVsTime(const MethodEvaluation& e) { return ChartAgainst(e, false); }
cv::Mat ChartErrorVsStorage(const MethodEvaluation& e) { return ChartAgainst(e, true); }

cv::Mat ChartConditionVsOrder(const MethodEvaluation& e) {
  std::vector<PlotSeries> series;
  for (const char* method : {"quadrature", "ls", "rls"}) {
    PlotSeries cond{std::string("sh-") + method + " condition", {}, {}, {}, true};
    PlotSeries err{std::string("sh-") + method + " error x1e4", {}, {}, {}, true};
    for (const auto& r : e.rows) {
      if (r.basis != "sh" || r.method != method) continue;
      cond.x.push_back(r.order);
      cond.y.push_back(r.supported ? r.condition : kNan);
      err.x.push_back(r.order);
      err.y.push_back(r.supported ? r.Error() * 1e4 : kNan);
    }
    if (std::string(method) != "rls") series.push_back(cond);
    series.push_back(err);
  }
  PlotOptions o;
  o.title = "Stability: condition number and error against SH order";
  o.x_label = "SH order";
  o.y_label = "condition number / error x 1e4";
  o.log_y = true;
  o.notes = {"missing points: refused (rank deficient, or beyond the condition limit)"};
  return DrawPlot(series, {}, o);
}

cv::Mat ChartExtrapolation(const MethodEvaluation& e) {
  std::vector<PlotSeries> series;
  for (const auto& r : e.rows) {
    if (!r.supported) continue;
    auto it = std::find_if(series.begin(), series.end(), [&](const PlotSeries& s) { return s.label == r.Name(); });
    if (it == series.end()) {
      series.push_back({r.Name(), {}, {}, {}, true});
      it = series.end() - 1;
    }
    it->x.push_back(r.order);
    it->y.push_back(r.extrapolation_relative);
  }
  PlotOptions o;
  o.title = "Extrapolation: error at lamps outside the sampled region";
  o.x_label = "order";
  o.y_label = "relative RMS error vs truth";
  o.log_y = true;
  return DrawPlot(series, {}, o);
}

}  // namespace rig
