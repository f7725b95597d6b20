// The reflectance model: evaluation, the EXR layout and header, and the in-memory fit.
#include "process/model/harmonic/model.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <sstream>

#include <fmt/format.h>

#include "config/log.h"

namespace rig {
namespace {

Result<double> ParseNumber(const std::map<std::string, std::string>& a, const std::string& key,
                           const std::string& context) {
  auto it = a.find(key);
  if (it == a.end()) {
    return MakeError(ErrorCode::kInvalidInput, context, "model header lacks '{}'", key);
  }
  char* end = nullptr;
  const char* text = it->second.c_str();
  const double v = std::strtod(text, &end);
  while (end != text && (*end == ' ' || *end == '\t')) ++end;
  if (end == text || *end != '\0') {
    return MakeError(ErrorCode::kInvalidInput, context, "model header '{}' is not a number: '{}'",
                     key, it->second.substr(0, 80));
  }
  if (!std::isfinite(v)) {
    return MakeError(ErrorCode::kInvalidInput, context, "model header '{}' is not finite: '{}'",
                     key, it->second.substr(0, 80));
  }
  return v;
}

// A header number that must lie in [lo, hi] (and be whole when `integer`); no cast happens
// before this check.
Result<double> ParseRanged(const std::map<std::string, std::string>& a, const std::string& key,
                           const std::string& context, double lo, double hi, bool integer) {
  RIG_ASSIGN_OR_RETURN(double v, ParseNumber(a, key, context));
  if (v < lo || v > hi || (integer && v != std::floor(v))) {
    return MakeError(ErrorCode::kInvalidInput, context,
                     "model header '{}' = {} is out of range: expected {} in [{}, {}]", key, v,
                     integer ? "a whole number" : "a number", lo, hi);
  }
  return v;
}

std::string Num(double v) { return fmt::format("{:.17g}", v); }

}  // namespace

ModelInfo FittedModelInfo(const FitOptions& options, const Projector& projector, double loo_rmse,
                          const std::array<double, 3>& lamp_radiance_rgb,
                          const LightFrameConfig& light_frame, const std::vector<Vec3>& directions) {
  ModelInfo info;
  info.method = options.method;
  info.transform = options.transform;
  info.lambda_relative = projector.lambda_relative;
  info.lamp_radiance_rgb = lamp_radiance_rgb;
  info.light_frame = light_frame;
  info.loo_rmse = loo_rmse;
  info.condition = projector.condition;
  info.solved_condition = projector.solved_condition;
  info.lamp_directions = directions;
  info.sample_spacing_deg = SampleSpacingDeg(directions);
  return info;
}

Model::Model(Basis basis, ModelInfo info, int width, int height)
    : basis_(basis), info_(std::move(info)), width_(width), height_(height) {}

std::string CoefficientChannelName(int term, char channel) {
  return fmt::format("c{:02d}.{}", term, channel);
}

cv::Mat Model::EvaluateRho(const Vec3& direction) const {
  const std::vector<double> b = basis_.Eval(direction);
  std::vector<float> w(b.begin(), b.end());
  cv::Mat sum(height_, width_, CV_32FC3);
  const int terms = basis_.size();
  const size_t row_values = static_cast<size_t>(width_) * 3;
  // Row by row: the row being summed stays in cache while every coefficient plane streams
  // through once, so evaluation costs about one read of the coefficients.
  cv::parallel_for_(cv::Range(0, height_), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* out = sum.ptr<float>(y);
      const float* c0 = coefficients_[0].ptr<float>(y);
      const float w0 = w[0];
      for (size_t i = 0; i < row_values; ++i) out[i] = w0 * c0[i];
      for (int k = 1; k < terms; ++k) {
        const float* ck = coefficients_[k].ptr<float>(y);
        const float wk = w[k];
        for (size_t i = 0; i < row_values; ++i) out[i] += wk * ck[i];
      }
      info_.transform.InverseInPlace(out, row_values);
      if (!valid_.empty()) {
        const uint8_t* v = valid_.ptr<uint8_t>(y);
        for (int x = 0; x < width_; ++x)
          if (!v[x]) out[3 * x] = out[3 * x + 1] = out[3 * x + 2] = 0;
      }
    }
  });
  return sum;
}

void Model::AddLamp(const Vec3& direction, const std::array<double, 3>& rgb_scale,
                    cv::Mat* sum) const {
  const cv::Mat rho = EvaluateRho(direction);
  const auto& e = info_.lamp_radiance_rgb;
  const float gain[3] = {static_cast<float>(e[2] * rgb_scale[2]), static_cast<float>(e[1] * rgb_scale[1]),
                         static_cast<float>(e[0] * rgb_scale[0])};  // B, G, R
  if (sum->empty()) *sum = cv::Mat::zeros(height_, width_, CV_32FC3);
  cv::parallel_for_(cv::Range(0, height_), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* r = rho.ptr<float>(y);
      float* out = sum->ptr<float>(y);
      for (int x = 0; x < width_; ++x)
        for (int c = 0; c < 3; ++c) out[3 * x + c] += gain[c] * r[3 * x + c];
    }
  });
}

RegionCheck Model::CheckRegion(const Vec3& direction) const {
  return CheckAgainstLamps(info_.lamp_directions, info_.sample_spacing_deg, direction);
}

std::map<std::string, std::string> ModelHeaderAttributes(const Model& m) {
  const ModelInfo& i = m.info();
  std::map<std::string, std::string> a;
  a["rig.model"] = "reflectance 1";
  a["basis"] = m.basis().name();
  a["order"] = std::to_string(m.basis().order());
  a["terms"] = std::to_string(m.basis().size());
  a["fit_method"] = FitMethodName(i.method);
  a["fit_space"] = FitSpaceName(i.transform.space);
  a["fit_space_log_epsilon"] = Num(i.transform.log_epsilon);
  a["lambda_relative"] = Num(i.lambda_relative);
  a["lamp_radiance_rgb"] = fmt::format("{} {} {}", Num(i.lamp_radiance_rgb[0]),
                                       Num(i.lamp_radiance_rgb[1]), Num(i.lamp_radiance_rgb[2]));
  a["light_frame.h_offset_deg"] = Num(i.light_frame.h_offset_deg);
  a["light_frame.v_offset_deg"] = Num(i.light_frame.v_offset_deg);
  a["light_frame.h_sign"] = std::to_string(i.light_frame.h_sign);
  a["light_frame.v_sign"] = std::to_string(i.light_frame.v_sign);
  a["light_frame"] =
      "object frame: x right, y up, z towards the camera; direction(h,v) = (sin h cos v, "
      "sin v, cos h cos v), h = h_sign*h_rig + h_offset_deg, v likewise";
  a["loo_rmse"] = Num(i.loo_rmse);
  a["condition_number"] = Num(i.condition);
  a["solved_condition_number"] = Num(i.solved_condition);
  a["poses"] = std::to_string(i.lamp_directions.size());
  std::string dirs;
  for (const auto& d : i.lamp_directions) {
    if (!dirs.empty()) dirs += ";";
    dirs += fmt::format("{:.9g} {:.9g} {:.9g}", d[0], d[1], d[2]);
  }
  a["lamp_directions"] = dirs;
  a["sample_spacing_deg"] = Num(i.sample_spacing_deg);
  a["flagged_pixels"] = std::to_string(i.flagged_pixels);
  a["source_encoding"] = i.source_encoding == ValueEncoding::kSrgb ? "srgb" : "linear";
  if (!i.near_lamp.empty()) a["near_lamp"] = i.near_lamp;
  a["channel_layout"] =
      "cKK.R/G/B: coefficient of basis term KK (sh/hsh: k = l*l+l+m; ptm: 1, lu, lv, lu^2, "
      "lu*lv, lv^2, ...); rho = inverse_fit_space(sum_k b_k(dir) cKK); radiance = rho * "
      "lamp_radiance_rgb; 'valid' = 0 marks pixels with too few samples";
  return a;
}

Result<Model> ModelFromHeader(const std::map<std::string, std::string>& a, int width,
                              int height, const std::string& context) {
  auto get = [&](const std::string& key) -> Result<std::string> {
    auto it = a.find(key);
    if (it == a.end()) {
      return MakeError(ErrorCode::kInvalidInput, context,
                       "not a reflectance model: header lacks '{}'", key);
    }
    return it->second;
  };
  RIG_ASSIGN_OR_RETURN(std::string basis_name, get("basis"));
  RIG_ASSIGN_OR_RETURN(double order, ParseRanged(a, "order", context, 0, 64, true));
  auto basis = Basis::Create(basis_name, static_cast<int>(order));
  if (!basis.ok()) return basis.error().Within(context);
  ModelInfo i;
  RIG_ASSIGN_OR_RETURN(std::string method, get("fit_method"));
  RIG_ASSIGN_OR_RETURN(std::string space, get("fit_space"));
  auto pm = ParseFitMethod(method);
  if (!pm.ok()) return pm.error().Within(context);
  auto ps = ParseFitSpace(space);
  if (!ps.ok()) return ps.error().Within(context);
  i.method = *pm;
  i.transform.space = *ps;
  RIG_ASSIGN_OR_RETURN(i.transform.log_epsilon,
                       ParseRanged(a, "fit_space_log_epsilon", context, 0, 1e6, false));
  RIG_ASSIGN_OR_RETURN(std::string e, get("lamp_radiance_rgb"));
  std::istringstream es(e);
  if (!(es >> i.lamp_radiance_rgb[0] >> i.lamp_radiance_rgb[1] >> i.lamp_radiance_rgb[2])) {
    return MakeError(ErrorCode::kInvalidInput, context, "bad lamp_radiance_rgb '{}'", e.substr(0, 80));
  }
  for (double c : i.lamp_radiance_rgb) {
    if (!std::isfinite(c) || c <= 0 || c > 1e30) {
      return MakeError(ErrorCode::kInvalidInput, context,
                       "lamp_radiance_rgb '{}' must be three finite positive numbers", e.substr(0, 80));
    }
  }
  // Optional numbers: the fallback when absent; present and wrong is an error.
  auto opt = [&](const std::string& key, double fallback, double lo, double hi,
                 bool integer) -> Result<double> {
    if (a.find(key) == a.end()) return fallback;
    return ParseRanged(a, key, context, lo, hi, integer);
  };
  // Figures only reported (a fit may record an infinite condition number): read as written.
  auto info = [&](const std::string& key) {
    auto it = a.find(key);
    if (it == a.end()) return 0.0;
    char* end = nullptr;
    const double v = std::strtod(it->second.c_str(), &end);
    return end == it->second.c_str() ? 0.0 : v;
  };
  i.lambda_relative = info("lambda_relative");
  RIG_ASSIGN_OR_RETURN(i.light_frame.h_offset_deg, opt("light_frame.h_offset_deg", 0, -360, 360, false));
  RIG_ASSIGN_OR_RETURN(i.light_frame.v_offset_deg, opt("light_frame.v_offset_deg", 0, -360, 360, false));
  RIG_ASSIGN_OR_RETURN(double h_sign, opt("light_frame.h_sign", 1, -1, 1, true));
  RIG_ASSIGN_OR_RETURN(double v_sign, opt("light_frame.v_sign", 1, -1, 1, true));
  if (h_sign == 0 || v_sign == 0) {
    return MakeError(ErrorCode::kInvalidInput, context,
                     "model header light_frame.h_sign/v_sign must be 1 or -1");
  }
  i.light_frame.h_sign = static_cast<int>(h_sign);
  i.light_frame.v_sign = static_cast<int>(v_sign);
  i.loo_rmse = info("loo_rmse");
  i.condition = info("condition_number");
  i.solved_condition = info("solved_condition_number");
  i.sample_spacing_deg = info("sample_spacing_deg");
  const double pixels = static_cast<double>(std::max(width, 0)) * std::max(height, 0);
  // A streamed fit writes a note here instead of a count: only a number is checked.
  double flagged = 0;
  if (auto it = a.find("flagged_pixels"); it != a.end()) {
    char* end = nullptr;
    std::strtod(it->second.c_str(), &end);
    if (end != it->second.c_str()) {
      RIG_ASSIGN_OR_RETURN(flagged, opt("flagged_pixels", 0, 0, pixels, true));
    }
  }
  i.flagged_pixels = static_cast<size_t>(flagged);
  // Absent in models written before it was recorded: those are linear (radiance maps) or were
  // rendered as such.
  if (auto it = a.find("source_encoding"); it != a.end()) {
    if (it->second == "srgb") {
      i.source_encoding = ValueEncoding::kSrgb;
    } else if (it->second != "linear") {
      return MakeError(ErrorCode::kInvalidInput, context,
                       "model header source_encoding '{}' is neither 'srgb' nor 'linear'",
                       it->second.substr(0, 40));
    }
  }
  if (auto it = a.find("near_lamp"); it != a.end()) i.near_lamp = it->second.substr(0, 1000);
  if (auto it = a.find("lamp_directions"); it != a.end()) {
    std::istringstream ds(it->second);
    std::string item;
    while (std::getline(ds, item, ';')) {
      std::istringstream is(item);
      Vec3 d;
      if (item.find_first_not_of(" \t") == std::string::npos) continue;
      if (!(is >> d[0] >> d[1] >> d[2]) || !std::isfinite(d[0]) || !std::isfinite(d[1]) ||
          !std::isfinite(d[2]))
        return MakeError(ErrorCode::kInvalidInput, context,
                         "model header lamp_directions: '{}' is not three finite numbers",
                         item.substr(0, 80));
      i.lamp_directions.push_back(d);
    }
  }
  return Model(*basis, i, width, height);
}

Status SaveModel(const std::string& path, const Model& m, ExrPixelType type) {
  ExrImage img;
  img.width = m.width();
  img.height = m.height();
  img.attributes = ModelHeaderAttributes(m);
  for (int k = 0; k < m.basis().size(); ++k) {
    cv::Mat planes[3];
    cv::split(m.coefficients()[k], planes);  // B, G, R
    for (int c = 0; c < 3; ++c) {
      img.channel_names.push_back(CoefficientChannelName(k, "BGR"[c]));
      img.channels.push_back(planes[c]);
    }
  }
  if (!m.valid().empty() && cv::countNonZero(m.valid()) != m.valid().rows * m.valid().cols) {
    cv::Mat v;
    m.valid().convertTo(v, CV_32F);
    img.channel_names.push_back("valid");
    img.channels.push_back(v);
  }
  return WriteExr(path, img, type);
}

Result<Model> LoadModel(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(ExrImage img, ReadExr(path));
  RIG_ASSIGN_OR_RETURN(Model m, ModelFromHeader(img.attributes, img.width, img.height, path));
  auto find = [&](const std::string& name) -> const cv::Mat* {
    for (size_t i = 0; i < img.channel_names.size(); ++i)
      if (img.channel_names[i] == name) return &img.channels[i];
    return nullptr;
  };
  for (int k = 0; k < m.basis().size(); ++k) {
    cv::Mat planes[3];
    for (int c = 0; c < 3; ++c) {
      const std::string name = CoefficientChannelName(k, "BGR"[c]);
      const cv::Mat* ch = find(name);
      if (!ch) {
        return MakeError(ErrorCode::kInvalidInput, path, "model lacks channel '{}'", name);
      }
      // A NaN or infinity renders as a black or white picture: refused, naming the channel.
      if (!cv::checkRange(*ch)) {
        return MakeError(ErrorCode::kInvalidInput, path,
                         "channel '{}': a coefficient is not a finite value", name);
      }
      planes[c] = *ch;
    }
    cv::Mat merged;
    cv::merge(planes, 3, merged);
    m.coefficients().push_back(merged);
  }
  if (const cv::Mat* v = find("valid")) {
    cv::Mat v8;
    v->convertTo(v8, CV_8U);
    m.valid() = v8;
  }
  return m;
}

Result<FitOutput> FitModel(const FitInput& in, const FitOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t n = in.radiance.size();
  if (n == 0) return MakeError(ErrorCode::kInvalidInput, "fit", "no radiance maps");
  if (in.directions.size() != n) {
    return MakeError(ErrorCode::kInvalidInput, "fit", "{} directions for {} maps",
                     in.directions.size(), n);
  }
  const std::vector<double> weights =
      in.weights.empty() ? UniformHemisphereWeights(n) : in.weights;
  SampleMatrix y;
  std::vector<uint8_t> missing;
  RIG_TRY(BuildSamples(in.radiance, in.valid, in.lamp_radiance_rgb, o.transform, &y, &missing));
  const size_t values = static_cast<size_t>(y.cols());
  const size_t stride =
      o.selection_values == 0 ? 1 : std::max<size_t>(1, values / o.selection_values);
  double count = 0;
  const Eigen::MatrixXd gram = SampleGram(y, missing, stride, &count);
  FitOutput out;
  RIG_ASSIGN_OR_RETURN(out.selection,
                       SelectProjector(in.directions, weights, gram, count, o));
  const Projector& pr = out.selection.projector;
  SampleMatrix c;
  std::vector<uint8_t> valid;
  out.missing = ApplyProjector(pr, in.directions, weights, o.max_condition, y, missing, &c, &valid);

  double loo_rmse = 0;
  for (const auto& r : out.selection.orders)
    if (r.order == out.selection.order) loo_rmse = r.loo_rmse;
  ModelInfo info = FittedModelInfo(o, pr, loo_rmse, in.lamp_radiance_rgb, in.light_frame, in.directions);
  info.flagged_pixels = out.missing.flagged;
  const int rows = in.radiance[0].rows, cols = in.radiance[0].cols;
  out.model = Model(pr.basis, info, cols, rows);
  for (int k = 0; k < pr.basis.size(); ++k) {
    cv::Mat plane(rows, cols, CV_32FC3, c.row(k).data());
    out.model.coefficients().push_back(plane.clone());
  }
  if (out.missing.flagged > 0) {
    out.model.valid() = cv::Mat(rows, cols, CV_8U, valid.data()).clone();
  }
  out.fit_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  Log("process")->info(
      "fit basis={} order={} terms={} method={} space={} lambda_rel={:.3g} loo_rmse={:.5g} "
      "cond={:.3g} missing_pixels={} flagged={} time_s={:.3f}",
      pr.basis.name(), pr.basis.order(), pr.basis.size(), FitMethodName(o.method),
      FitSpaceName(o.transform.space), pr.lambda_relative, info.loo_rmse, pr.condition,
      out.missing.pixels_with_missing, out.missing.flagged, out.fit_time_s);
  return out;
}

std::string FitReportMarkdown(const FitOutput& out, const FitOptions& o) {
  std::string s = fmt::format(
      "# Reflectance fit\n\nbasis {}, method {}, fit space {}, order {} ({}), tolerance {:.3g}\n\n"
      "The leave-one-out column is the one the order (and λ) were chosen by: a preview, "
      "optimistic for the order it chose. An honest figure refits without each image with "
      "every choice inside the fold (`rig fit --lp ... --loo-report`).\n\n"
      "| order | terms | LOO RMSE (fit space, selection preview) | condition of B | solved condition "
      "| lambda (rel.) | build time (s) | note |\n|---|---|---|---|---|---|---|---|\n",
      BasisKindName(o.basis), FitMethodName(o.method), FitSpaceName(o.transform.space),
      out.selection.order, o.order >= 0 ? "requested" : "chosen: smallest within tolerance",
      o.order_tolerance);
  for (const auto& r : out.selection.orders) {
    s += fmt::format("| {} | {} | {} | {} | {} | {} | {:.4f} | {} |\n", r.order, r.terms,
                     r.supported ? fmt::format("{:.6g}", r.loo_rmse) : "-",
                     ConditionCell(r.condition, r.lambda_relative),
                     r.supported ? fmt::format("{:.3g}", r.solved_condition) : "-",
                     r.supported ? fmt::format("{:.3g}", r.lambda_relative) : "-",
                     r.build_time_s,
                     r.order == out.selection.order ? "**chosen**"
                                                    : (r.supported ? "" : r.refusal));
  }
  s += fmt::format("\npixels with missing samples: {} (distinct patterns {}), flagged: {}; fit "
                   "time {:.3f} s\n",
                   out.missing.pixels_with_missing, out.missing.patterns, out.missing.flagged,
                   out.fit_time_s);
  return s;
}

namespace {

class HarmonicModel final : public ReflectanceModel {
 public:
  explicit HarmonicModel(Model m) : m_(std::move(m)) {}
  std::string family() const override { return m_.basis().name(); }
  std::string Describe() const override {
    return fmt::format("{} order {} ({} terms per channel), {} fit in {} space", m_.basis().name(),
                       m_.basis().order(), m_.basis().size(), FitMethodName(m_.info().method),
                       FitSpaceName(m_.info().transform.space));
  }
  int width() const override { return m_.width(); }
  int height() const override { return m_.height(); }
  ValueEncoding encoding() const override { return m_.info().source_encoding; }
  const LightFrameConfig& light_frame() const override { return m_.info().light_frame; }
  std::array<double, 3> lamp_radiance_rgb() const override { return m_.info().lamp_radiance_rgb; }
  cv::Mat EvaluateRho(const Vec3& d) const override { return m_.EvaluateRho(d); }
  void AddLamp(const Vec3& d, const std::array<double, 3>& rgb, cv::Mat* sum) const override {
    m_.AddLamp(d, rgb, sum);
  }
  RegionCheck CheckRegion(const Vec3& d) const override { return m_.CheckRegion(d); }
  cv::Mat valid() const override { return m_.valid(); }
  Status Save(const std::string& path) const override {
    return SaveModel(path, m_, ExrPixelType::kHalf);
  }

 private:
  Model m_;
};

}  // namespace

std::unique_ptr<ReflectanceModel> WrapHarmonic(Model model) {
  return std::make_unique<HarmonicModel>(std::move(model));
}

}  // namespace rig
