// Tone mapping: Ward's histogram adjustment with the linear ceiling, a linear mapping, and
// OpenCV's operators, all ending in one display encoding through a lookup table.
#include "process/render/tonemap.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>

#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

namespace rig {
namespace {

// Rec. 709 / sRGB luminance weights, in OpenCV's B, G, R order.
constexpr float kLumaB = 0.0722f, kLumaG = 0.7152f, kLumaR = 0.2126f;

// Float-bit lookup: a positive float's bits shifted right by kLutShift index a table whose
// entries are 2^(23 - kLutShift) per octave, i.e. evenly spaced in log L (relative step 2^-10).
constexpr int kLutShift = 13;
constexpr uint32_t kLutFracMask = (1u << kLutShift) - 1;
constexpr float kLutFracScale = 1.0f / static_cast<float>(1u << kLutShift);

// The paper's grid: one foveal sample per degree of the horizontal field of view, at least 2
// each way and never more than the image has.
cv::Size PaperFovealSize(int cols, int rows, double field_of_view_deg) {
  const int fw = std::max(2, static_cast<int>(std::lround(field_of_view_deg)));
  const int fh = std::max(2, static_cast<int>(std::lround(field_of_view_deg * rows / cols)));
  return cv::Size(std::min(fw, cols), std::min(fh, rows));
}

// pcond's grid (getahead, getfovimg): samples across a side = the view's image-plane extent
// on that side divided by one degree in radians, plus 0.5, truncated, at least 2. Without a
// usable view, pcond's default: a perspective view whose larger side (pixel aspect counted)
// spans the field of view, the other side 2·tan(fov/2) in proportion.
cv::Size PcondFovealSize(int cols, int rows, double field_of_view_deg,
                         std::array<double, 2> extent, double pixel_aspect) {
  const double one_deg = std::numbers::pi / 180;
  if (!(extent[0] > 0 && extent[1] > 0)) {
    const double span = 2 * std::tan(field_of_view_deg * one_deg / 2);
    if (pixel_aspect * rows < cols) {
      extent = {span, span * pixel_aspect * rows / cols};
    } else {
      extent = {span * cols / (pixel_aspect * rows), span};
    }
  }
  const int fw = std::max(2, static_cast<int>(extent[0] / one_deg + 0.5));
  const int fh = std::max(2, static_cast<int>(extent[1] / one_deg + 0.5));
  return cv::Size(std::min(fw, cols), std::min(fh, rows));
}

inline uint32_t Bits(float v) { return std::bit_cast<uint32_t>(v); }
inline float FromBits(uint32_t b) { return std::bit_cast<float>(b); }

Status CheckRadiance(const cv::Mat& radiance) {
  if (radiance.empty()) {
    return MakeError(ErrorCode::kInvalidInput, "tone mapping", "the radiance map is empty");
  }
  if (radiance.type() != CV_32FC3) {
    return MakeError(ErrorCode::kInvalidInput, "tone mapping",
                     "the radiance map must be CV_32FC3 (linear BGR float), got type {}",
                     radiance.type());
  }
  return Ok();
}

Status CheckOptions(const ToneMapOptions& o) {
  auto bad = [](const std::string& what) {
    return MakeError(ErrorCode::kInvalidInput, "tone mapping options", "{}", what);
  };
  if (!(o.field_of_view_deg > 0 && o.field_of_view_deg < 360)) {
    return bad(fmt::format("field_of_view_deg must be in (0, 360), got {}", o.field_of_view_deg));
  }
  if (o.ward_variant == WardVariant::kPcond && !(o.field_of_view_deg < 179)) {
    return bad(fmt::format("field_of_view_deg must be under 179 for pcond's perspective view, "
                           "got {} (the paper variant takes up to 360)",
                           o.field_of_view_deg));
  }
  if (!RgbToXyzWhiteBalanced(o.picture_primaries).ok()) {
    return bad("the picture's primaries are degenerate");
  }
  if (!RgbToXyzWhiteBalanced(o.display_primaries).ok()) {
    return bad("the display's primaries are degenerate");
  }
  if (!(o.pixel_aspect > 0 && std::isfinite(o.pixel_aspect))) {
    return bad(fmt::format("pixel_aspect must be positive, got {}", o.pixel_aspect));
  }
  if (!(o.view_extent[0] >= 0 && o.view_extent[1] >= 0 && std::isfinite(o.view_extent[0]) &&
        std::isfinite(o.view_extent[1]))) {
    return bad("view_extent must be two non-negative numbers");
  }
  if (o.ward_point_samples_per_foveal < 0 || o.ward_point_samples_per_foveal > 1000) {
    return bad(fmt::format("ward_point_samples_per_foveal must be in [0, 1000], got {}",
                           o.ward_point_samples_per_foveal));
  }
  if (!(o.display_min_cd_m2 > 0 && o.display_max_cd_m2 > o.display_min_cd_m2 &&
        std::isfinite(o.display_max_cd_m2))) {
    return bad(fmt::format("display range must satisfy 0 < min < max, got {} .. {} cd/m2",
                           o.display_min_cd_m2, o.display_max_cd_m2));
  }
  if (!(o.ceiling_tolerance > 0 && o.ceiling_tolerance < 1)) {
    return bad(fmt::format("ceiling_tolerance must be in (0, 1), got {}", o.ceiling_tolerance));
  }
  if (o.bins < 2 || o.bins > 100000) {
    return bad(fmt::format("bins must be in [2, 100000], got {}", o.bins));
  }
  if (!o.srgb && !(o.gamma > 0 && std::isfinite(o.gamma))) {
    return bad(fmt::format("gamma must be positive, got {}", o.gamma));
  }
  if (!(o.linear_scale >= 0 && std::isfinite(o.linear_scale))) {
    return bad(fmt::format("linear_scale must be >= 0, got {}", o.linear_scale));
  }
  if (!(o.linear_percentile > 0 && o.linear_percentile <= 100)) {
    return bad(fmt::format("linear_percentile must be in (0, 100], got {}", o.linear_percentile));
  }
  return Ok();
}

// Scales every pixel's BGR by factor(L) of its luminance: keeps colour ratios exactly.
template <typename Factor>
cv::Mat ScaleByLuminance(const cv::Mat& radiance, const cv::Vec3f& w, const Factor& factor) {
  cv::Mat out(radiance.size(), CV_32FC3);
  cv::parallel_for_(cv::Range(0, radiance.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* in = radiance.ptr<float>(y);
      float* o = out.ptr<float>(y);
      for (int x = 0; x < radiance.cols; ++x, in += 3, o += 3) {
        const float b = in[0], g = in[1], r = in[2];
        const float l = w[0] * b + w[1] * g + w[2] * r;
        float m = 0;
        if (l > 0 && l <= std::numeric_limits<float>::max()) {
          m = factor(l);
        } else if (l > 0) {  // +inf: show white
          o[0] = o[1] = o[2] = 1;
          continue;
        }
        o[0] = b * m;
        o[1] = g * m;
        o[2] = r * m;
      }
    }
  });
  return out;
}

// Ward's factor pixel_luminance(L) / L as a float-bit table over the histogram's domain,
// interpolated linearly inside an entry; outside the domain the mapping is flat (0 below,
// white above), so the factor is 0 or 1 / L there.
class WardFactorLut {
 public:
  explicit WardFactorLut(const WardMapping& m) {
    lo_ = static_cast<float>(std::exp(m.log_min));
    hi_ = static_cast<float>(std::exp(m.log_max));
    if (!(lo_ > 0)) lo_ = std::numeric_limits<float>::denorm_min();
    if (!(hi_ <= std::numeric_limits<float>::max())) hi_ = std::numeric_limits<float>::max();
    first_ = Bits(lo_) >> kLutShift;
    const uint32_t last = (Bits(hi_) >> kLutShift) + 1;
    table_.resize(last - first_ + 2);
    for (size_t k = 0; k < table_.size(); ++k) {
      const float l = FromBits(static_cast<uint32_t>((first_ + k) << kLutShift));
      table_[k] = l > 0 ? static_cast<float>(m.PixelLuminance(l) / l) : 0.0f;
    }
  }
  float operator()(float l) const {
    if (l < lo_) return 0.0f;
    if (l >= hi_) return 1.0f / l;
    const uint32_t bits = Bits(l);
    const size_t k = (bits >> kLutShift) - first_;
    const float frac = static_cast<float>(bits & kLutFracMask) * kLutFracScale;
    return table_[k] + (table_[k + 1] - table_[k]) * frac;
  }

 private:
  float lo_ = 0, hi_ = 0;
  uint32_t first_ = 0;
  std::vector<float> table_;
};

cv::Mat WardPixels(const cv::Mat& radiance, const ToneMapOptions& o, ToneMapReport* report) {
  const WardMapping mapping =
      o.ward_fixed ? *o.ward_fixed : ComputeWardMappingForImage(radiance, o, report);
  if (mapping.linear) {
    const float m = static_cast<float>(mapping.linear_scale / mapping.display_max_cd_m2);
    return ScaleByLuminance(radiance, LuminanceWeightsBgr(o), [m](float) { return m; });
  }
  WardFactorLut lut(mapping);
  return ScaleByLuminance(radiance, LuminanceWeightsBgr(o), lut);
}

cv::Mat LinearPixels(const cv::Mat& radiance, const ToneMapOptions& o, ToneMapReport* report) {
  double scale = o.linear_scale;
  // Luminance on a strided subset: a percentile needs no more than ~1M samples.
  const size_t n = radiance.total();
  const size_t stride = std::max<size_t>(1, n / (1u << 20));
  std::vector<float> lum;
  lum.reserve(n / stride + 1);
  float lo = std::numeric_limits<float>::max(), hi = 0;
  const cv::Vec3f w = LuminanceWeightsBgr(o);
  for (size_t i = 0; i < n; i += stride) {
    const cv::Vec3f p = radiance.at<cv::Vec3f>(static_cast<int>(i / radiance.cols),
                                               static_cast<int>(i % radiance.cols));
    const float l = w[0] * p[0] + w[1] * p[1] + w[2] * p[2];
    if (l > 0 && std::isfinite(l)) {
      lum.push_back(l);
      lo = std::min(lo, l);
      hi = std::max(hi, l);
    }
  }
  if (scale <= 0) {
    scale = 1;
    if (!lum.empty()) {
      const size_t k = std::min(lum.size() - 1, static_cast<size_t>(std::floor(
                                                    o.linear_percentile / 100.0 * lum.size())));
      std::nth_element(lum.begin(), lum.begin() + k, lum.end());
      scale = 1.0 / lum[k];
    }
  }
  if (report) {
    report->linear_scale = scale;
    report->scene_log_range = lum.empty() ? 0 : std::log(static_cast<double>(hi) / lo);
  }
  cv::Mat out;
  radiance.convertTo(out, CV_32FC3, scale);
  return out;
}

Result<cv::Mat> OpenCvPixels(const cv::Mat& radiance, ToneMapMethod method) {
  try {
    cv::Mat src = radiance.clone();
    cv::patchNaNs(src, 0);
    double max_value = 0;
    cv::minMaxLoc(src.reshape(1), nullptr, &max_value);
    if (!(max_value > 0)) return cv::Mat(radiance.size(), CV_32FC3, cv::Scalar::all(0));
    // Drago and Mantiuk take logarithms: a floor far below anything visible keeps black
    // pixels (and negative noise) finite.
    cv::max(src, cv::Scalar::all(max_value * 1e-7), src);
    cv::Ptr<cv::Tonemap> op;
    switch (method) {
      case ToneMapMethod::kReinhard: op = cv::createTonemapReinhard(1.0f); break;
      case ToneMapMethod::kDrago: op = cv::createTonemapDrago(1.0f); break;
      case ToneMapMethod::kMantiuk: op = cv::createTonemapMantiuk(1.0f); break;
      default: RIG_CHECK(false, "not an OpenCV method");
    }
    cv::Mat dst;
    op->process(src, dst);  // gamma 1: linear output; the display encoding is ours
    cv::patchNaNs(dst, 0);
    return dst;
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kInternal, "tone mapping",
                     "OpenCV {} operator failed: {}", ToneMapMethodName(method), e.what());
  }
}

// The linear value a display curve encodes to e (0..1): the inverse of the encoding.
double DecodeValue(double e, const ToneMapOptions& o) {
  if (o.srgb) return e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
  return std::pow(e, o.gamma);
}

}  // namespace

ToneMapOptions ToneMapOptionsFor(const ProcessConfig& process) {
  ToneMapOptions o;
  o.field_of_view_deg = process.field_of_view_deg;
  o.display_min_cd_m2 = process.display_min_cd_m2;
  o.display_max_cd_m2 = process.display_max_cd_m2;
  return o;
}

const char* ToneMapMethodName(ToneMapMethod method) {
  switch (method) {
    case ToneMapMethod::kWard: return "ward";
    case ToneMapMethod::kLinear: return "linear";
    case ToneMapMethod::kReinhard: return "reinhard";
    case ToneMapMethod::kDrago: return "drago";
    case ToneMapMethod::kMantiuk: return "mantiuk";
  }
  return "unknown";
}

const char* WardVariantName(WardVariant variant) {
  return variant == WardVariant::kPcond ? "pcond" : "paper";
}

Result<WardVariant> ParseWardVariant(const std::string& name) {
  if (name == "pcond") return WardVariant::kPcond;
  if (name == "paper") return WardVariant::kPaper;
  return MakeError(ErrorCode::kInvalidInput, "tone mapping",
                   "unknown Ward variant '{}' (pcond or paper)", name);
}

Result<ToneMapMethod> ParseToneMapMethod(const std::string& name) {
  for (ToneMapMethod m : {ToneMapMethod::kWard, ToneMapMethod::kLinear, ToneMapMethod::kReinhard,
                          ToneMapMethod::kDrago, ToneMapMethod::kMantiuk}) {
    if (name == ToneMapMethodName(m)) return m;
  }
  return MakeError(ErrorCode::kInvalidInput, "tone mapping",
                   "unknown method '{}' (ward, linear, reinhard, drago or mantiuk)", name);
}

double FieldOfViewDeg(double focal_length_mm, double sensor_width_mm) {
  return 2 * std::atan(sensor_width_mm / (2 * focal_length_mm)) * 180 / std::numbers::pi;
}

cv::Mat Luminance(const cv::Mat& bgr) { return Luminance(bgr, cv::Vec3f(kLumaB, kLumaG, kLumaR)); }

cv::Mat Luminance(const cv::Mat& bgr, const cv::Vec3f& w) {
  RIG_CHECK(bgr.type() == CV_32FC3, "Luminance takes CV_32FC3");
  cv::Mat lum;
  cv::transform(bgr, lum, cv::Matx13f(w[0], w[1], w[2]));
  return lum;
}

cv::Vec3f LuminanceWeightsBgr(const ToneMapOptions& o) {
  auto m = RgbToXyzWhiteBalanced(o.picture_primaries);
  if (!m.ok()) return cv::Vec3f(kLumaB, kLumaG, kLumaR);  // refused by CheckOptions first
  return cv::Vec3f(static_cast<float>((*m)(1, 2)), static_cast<float>((*m)(1, 1)),
                   static_cast<float>((*m)(1, 0)));
}

Status ApplyPictureHeader(const PictureHeader& header, ToneMapOptions* o) {
  o->picture_primaries = header.primaries;
  o->pixel_aspect = header.pixel_aspect;
  o->view_extent = {0, 0};
  if (header.view) {
    auto extent = ViewExtent(*header.view);
    if (!extent.ok()) return extent.error();
    // pcond keeps its default view for a parallel one or one under 5 degrees on a side.
    if (header.view->type != 'l' && header.view->horizontal_deg > 5 &&
        header.view->vertical_deg > 5) {
      o->view_extent = *extent;
    }
  }
  return Ok();
}

cv::Size FovealSampleSize(int cols, int rows, const ToneMapOptions& o) {
  return o.ward_variant == WardVariant::kPcond
             ? PcondFovealSize(cols, rows, o.field_of_view_deg, o.view_extent, o.pixel_aspect)
             : PaperFovealSize(cols, rows, o.field_of_view_deg);
}

const char* GamutMappingName(GamutMapping g) {
  return g == GamutMapping::kDesaturate ? "desaturate" : "clip";
}

Result<GamutMapping> ParseGamutMapping(const std::string& name) {
  if (name == "desaturate") return GamutMapping::kDesaturate;
  if (name == "clip") return GamutMapping::kClip;
  return MakeError(ErrorCode::kInvalidInput, "tone mapping",
                   "unknown gamut mapping '{}' (desaturate or clip)", name);
}

const char* WardSamplingName(WardSampling s) {
  return s == WardSampling::kStratified ? "stratified" : "random";
}

Result<WardSampling> ParseWardSampling(const std::string& name) {
  if (name == "stratified") return WardSampling::kStratified;
  if (name == "random") return WardSampling::kRandom;
  return MakeError(ErrorCode::kInvalidInput, "tone mapping",
                   "unknown Ward sampling '{}' (stratified or random)", name);
}

std::vector<int64_t> StratifiedPixelIndices(int cols, int rows, cv::Size cells, uint64_t seed) {
  std::vector<int64_t> out;
  if (cols <= 0 || rows <= 0 || cells.width <= 0 || cells.height <= 0) return out;
  const int nx = std::min(cells.width, cols), ny = std::min(cells.height, rows);
  std::mt19937_64 gen(seed);
  out.reserve(static_cast<size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j) {
    const int64_t y0 = int64_t{j} * rows / ny, y1 = int64_t{j + 1} * rows / ny;
    for (int i = 0; i < nx; ++i) {
      const int64_t x0 = int64_t{i} * cols / nx, x1 = int64_t{i + 1} * cols / nx;
      const int64_t x = x0 + static_cast<int64_t>(gen() % static_cast<uint64_t>(x1 - x0));
      const int64_t y = y0 + static_cast<int64_t>(gen() % static_cast<uint64_t>(y1 - y0));
      out.push_back(y * cols + x);
    }
  }
  return out;
}

void MapToDisplayGamut(cv::Mat* pixels, const cv::Matx33d& to_display,
                       const cv::Vec3f& w, GamutMapping gamut) {
  RIG_CHECK(pixels->type() == CV_32FC3, "MapToDisplayGamut takes CV_32FC3");
  const bool convert = to_display != cv::Matx33d::eye();
  if (!convert && gamut == GamutMapping::kClip) return;  // the encoding clips each channel
  // R, G, B matrix applied to B, G, R pixels: rows and columns reversed.
  cv::Matx33f m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(2 - r, 2 - c) = static_cast<float>(to_display(r, c));
  cv::parallel_for_(cv::Range(0, pixels->rows), [&](const cv::Range& range) {
    for (int y = range.start; y < range.end; ++y) {
      float* p = pixels->ptr<float>(y);
      for (int x = 0; x < pixels->cols; ++x, p += 3) {
        cv::Vec3f v(p[0], p[1], p[2]);
        if (convert) v = m * v;
        if (gamut == GamutMapping::kDesaturate) {
          // Radiance's clipgamut against black (0, 0, 0) and white (1, 1, 1).
          const float brt = w[0] * v[0] + w[1] * v[1] + w[2] * v[2];
          if (!(brt > 0)) {
            v = cv::Vec3f(0, 0, 0);
          } else if (brt > 1) {
            v = cv::Vec3f(1, 1, 1);
          } else {
            float keep = 1;
            for (int c = 0; c < 3; ++c) {
              if (v[c] < 0) keep = std::min(keep, -brt / (v[c] - brt));
              else if (v[c] > 1) keep = std::min(keep, (1 - brt) / (v[c] - brt));
            }
            if (keep < 1) {
              for (int c = 0; c < 3; ++c) v[c] = std::clamp(brt + keep * (v[c] - brt), 0.0f, 1.0f);
            }
          }
        }
        p[0] = v[0];
        p[1] = v[1];
        p[2] = v[2];
      }
    }
  });
}

cv::Size FovealSampleSize(int cols, int rows, double field_of_view_deg, WardVariant variant) {
  return variant == WardVariant::kPcond
             ? PcondFovealSize(cols, rows, field_of_view_deg, {0, 0}, 1)
             : PaperFovealSize(cols, rows, field_of_view_deg);
}

cv::Mat FovealLuminance(const cv::Mat& luminance, double field_of_view_deg, WardVariant variant) {
  RIG_CHECK(luminance.type() == CV_32FC1, "FovealLuminance takes CV_32FC1");
  cv::Mat foveal;
  cv::resize(luminance, foveal,
             FovealSampleSize(luminance.cols, luminance.rows, field_of_view_deg, variant), 0, 0,
             cv::INTER_AREA);
  return foveal;
}

std::vector<int64_t> RandomPixelIndices(int64_t pixels, int64_t count, uint64_t seed) {
  std::vector<int64_t> out;
  if (pixels <= 0 || count <= 0) return out;
  if (count >= pixels) {
    out.resize(static_cast<size_t>(pixels));
    for (int64_t i = 0; i < pixels; ++i) out[static_cast<size_t>(i)] = i;
    return out;
  }
  std::mt19937_64 gen(seed);
  std::vector<bool> taken(static_cast<size_t>(pixels), false);
  out.reserve(static_cast<size_t>(count));
  for (int64_t j = pixels - count; j < pixels; ++j) {
    int64_t t = static_cast<int64_t>(gen() % static_cast<uint64_t>(j + 1));
    if (taken[static_cast<size_t>(t)]) t = j;
    taken[static_cast<size_t>(t)] = true;
    out.push_back(t);
  }
  return out;
}

// ---- Ward's histogram ------------------------------------------------------------------

double WardHistogram::Total() const {
  double t = 0;
  for (double c : counts) t += c;
  return t;
}

WardHistogram BuildLogHistogram(const std::vector<float>& luminance_samples, int bins) {
  RIG_CHECK(bins >= 1, "a histogram needs a bin");
  WardHistogram h;
  h.counts.assign(bins, 0.0);
  std::vector<double> logs;
  logs.reserve(luminance_samples.size());
  for (float l : luminance_samples) {
    if (l > 0 && std::isfinite(l)) logs.push_back(std::log(static_cast<double>(l)));
  }
  if (logs.empty()) return h;
  auto [lo, hi] = std::minmax_element(logs.begin(), logs.end());
  h.log_min = *lo;
  h.log_max = *hi;
  h.bin_width = (h.log_max - h.log_min) / bins;
  for (double b : logs) {
    int i = h.bin_width > 0 ? static_cast<int>((b - h.log_min) / h.bin_width) : 0;
    h.counts[std::clamp(i, 0, bins - 1)] += 1;
  }
  h.original_total = static_cast<double>(logs.size());
  return h;
}

WardHistogram BuildPcondHistogram(const std::vector<float>& foveal_samples,
                                  const std::vector<float>& point_samples, int bins) {
  RIG_CHECK(bins >= 2, "pcond's histogram needs two bins");
  WardHistogram h;
  h.counts.assign(bins, 0.0);
  auto usable = [](float l) { return l > 0 && std::isfinite(l); };
  double lmin = std::numeric_limits<double>::infinity(), lmax = 0;
  for (const auto* set : {&foveal_samples, &point_samples}) {
    for (float l : *set) {
      if (!usable(l)) continue;
      lmin = std::min(lmin, static_cast<double>(l));
      lmax = std::max(lmax, static_cast<double>(l));
    }
  }
  if (!(lmax > 0)) return h;
  // The top goes 1% over the brightest sample; the bottom one bin under the darkest.
  h.log_max = std::log(lmax * 1.01);
  h.log_min = h.log_max - (h.log_max - std::log(lmin)) * bins / (bins - 1);
  h.bin_width = (h.log_max - h.log_min) / bins;
  double total = 0, sum_log = 0;
  auto add = [&](float l, double w) {
    if (!usable(l)) return;
    const double b = std::log(static_cast<double>(l));
    const int i = static_cast<int>(bins * (b - h.log_min) / (h.log_max - h.log_min));
    h.counts[std::clamp(i, 0, bins - 1)] += w;
    total += w;
    sum_log += w * b;
  };
  for (float l : foveal_samples) add(l, 1.0);
  // The point samples weigh, together, what the foveal samples weigh (pcond: histot / n).
  if (!point_samples.empty() && total > 0) {
    const double w = total / static_cast<double>(point_samples.size());
    for (float l : point_samples) add(l, w);
  }
  h.original_total = total;
  h.mean_log = total > 0 ? sum_log / total : 0;
  // "False samples at the bottom": half of bin 1 goes to the padding bin 0.
  h.counts[1] *= 0.5;
  h.counts[0] += h.counts[1];
  return h;
}

double CeilingValue(const WardHistogram& h, double display_log_range) {
  return h.Total() * h.bin_width / display_log_range;
}

CeilingOutcome ApplyLinearCeiling(WardHistogram* h, double display_log_range, double tolerance) {
  RIG_CHECK(display_log_range > 0 && tolerance > 0, "ceiling needs a display range and tolerance");
  CeilingOutcome out;
  const double tol = tolerance * h->original_total;
  // Each pass that goes on trims more than tol, so the total falls under tol after at most
  // 1 / tolerance passes: the loop ends.
  while (true) {
    if (h->Total() <= tol) return out;  // emptied: no compression is needed
    const double ceiling = CeilingValue(*h, display_log_range);
    double trimmed = 0;
    for (double& c : h->counts) {
      if (c > ceiling) {
        trimmed += c - ceiling;
        c = ceiling;
      }
    }
    ++out.iterations;
    out.last_trimmed = trimmed;
    if (trimmed <= tol) {
      out.converged = true;
      return out;
    }
  }
}

CeilingOutcome ApplyPcondCeiling(WardHistogram* h, double display_log_range, double tolerance,
                                 std::vector<double>* cumulative_before) {
  RIG_CHECK(display_log_range > 0 && tolerance > 0, "ceiling needs a display range and tolerance");
  CeilingOutcome out;
  // A pass that goes on trims more than tolerance · total, and the total stays over
  // tolerance · original: at most 1 / tolerance² passes.
  const int max_passes = static_cast<int>(std::ceil(1 / (tolerance * tolerance))) + 1;
  while (out.iterations < max_passes) {
    const double total = h->Total();
    *cumulative_before = CumulativeDistribution(*h);
    if (total <= tolerance * h->original_total) return out;  // no compression needed
    const double ceiling = total * h->bin_width / display_log_range;
    double trimmed = 0;
    for (double& c : h->counts) {
      if (c > ceiling) {
        trimmed += c - ceiling;
        c = ceiling;
      }
    }
    ++out.iterations;
    out.last_trimmed = trimmed;
    if (trimmed <= tolerance * total) {
      out.converged = true;
      return out;
    }
  }
  return out;
}

std::vector<double> CumulativeDistribution(const WardHistogram& h) {
  std::vector<double> p(h.counts.size() + 1, 0.0);
  const double total = h.Total();
  double sum = 0;
  for (size_t i = 0; i < h.counts.size(); ++i) {
    p[i] = total > 0 ? sum / total : static_cast<double>(i) / h.counts.size();
    sum += h.counts[i];
  }
  p.back() = 1.0;
  return p;
}

double WardMapping::DisplayLogLuminance(double world_luminance) const {
  const double ld_lo = std::log(display_min_cd_m2), ld_hi = std::log(display_max_cd_m2);
  if (linear) return std::log(linear_scale * world_luminance);
  if (!(world_luminance > 0)) return ld_lo;
  const double b = std::log(world_luminance);
  if (b <= log_min) return ld_lo;
  if (b >= log_max) return ld_hi;
  const int bins = static_cast<int>(cumulative.size()) - 1;
  const double x = (b - log_min) / (log_max - log_min) * bins;
  const int i = std::clamp(static_cast<int>(x), 0, bins - 1);
  const double f = x - i;
  const double p = cumulative[i] * (1 - f) + cumulative[i + 1] * f;
  return ld_lo + (ld_hi - ld_lo) * p;
}

double WardMapping::DisplayLuminance(double world_luminance) const {
  if (linear) return linear_scale * std::max(0.0, world_luminance);
  return std::exp(DisplayLogLuminance(world_luminance));
}

double WardMapping::PixelLuminance(double world_luminance) const {
  if (!(world_luminance > 0)) return 0;
  if (linear) return linear_scale * world_luminance / display_max_cd_m2;
  const double v = (DisplayLuminance(world_luminance) - display_min_cd_m2) /
                   (display_max_cd_m2 - display_min_cd_m2);
  return std::clamp(v, 0.0, 1.0);  // exp(ln x) may land an ulp outside
}

WardMapping ComputeWardMapping(const std::vector<float>& foveal_samples, const ToneMapOptions& o,
                               ToneMapReport* report) {
  return ComputeWardMapping(foveal_samples, {}, o, report);
}

WardMapping ComputeWardMapping(const std::vector<float>& foveal_samples,
                               const std::vector<float>& point_samples, const ToneMapOptions& o,
                               ToneMapReport* report) {
  const bool pcond = o.ward_variant == WardVariant::kPcond;
  WardMapping m;
  m.display_min_cd_m2 = o.display_min_cd_m2;
  m.display_max_cd_m2 = o.display_max_cd_m2;
  WardHistogram h = pcond ? BuildPcondHistogram(foveal_samples, point_samples, o.bins)
                          : BuildLogHistogram(foveal_samples, o.bins);
  m.log_min = h.log_min;
  m.log_max = h.log_max;
  const double display_log_range = std::log(o.display_max_cd_m2 / o.display_min_cd_m2);
  // The range pcond compares with the display's is the padded one.
  const double histogram_range = h.log_max - h.log_min;
  int iterations = 0;
  bool linear = histogram_range <= display_log_range;
  std::vector<double> cumulative;
  if (!linear) {
    CeilingOutcome c = pcond ? ApplyPcondCeiling(&h, display_log_range, o.ceiling_tolerance,
                                                 &cumulative)
                             : ApplyLinearCeiling(&h, display_log_range, o.ceiling_tolerance);
    iterations = c.iterations;
    linear = !c.converged;
    if (!pcond) cumulative = CumulativeDistribution(h);
  }
  double mean_log = 0;
  int n = 0;
  if (pcond) {
    mean_log = h.mean_log;
    n = h.original_total > 0 ? 1 : 0;
  } else {
    double sum = 0;
    for (float l : foveal_samples) {
      if (l > 0 && std::isfinite(l)) {
        sum += std::log(static_cast<double>(l));
        ++n;
      }
    }
    mean_log = n > 0 ? sum / n : 0;
  }
  if (linear) {
    // Radiance's pcond: the log-average of the samples goes to the display's geometric
    // middle, sqrt(L_dmin · L_dmax).
    m.linear = true;
    m.linear_scale =
        n > 0 ? std::sqrt(o.display_min_cd_m2 * o.display_max_cd_m2) / std::exp(mean_log) : 1.0;
  } else {
    m.cumulative = std::move(cumulative);
  }
  if (report) {
    report->linear_fallback = m.linear;
    report->trim_iterations = iterations;
    double lo = std::numeric_limits<double>::infinity(), hi = 0;
    for (const auto* set : {&foveal_samples, &point_samples}) {
      if (!pcond && set == &point_samples) continue;
      for (float l : *set) {
        if (!(l > 0 && std::isfinite(l))) continue;
        lo = std::min(lo, static_cast<double>(l));
        hi = std::max(hi, static_cast<double>(l));
      }
    }
    report->scene_log_range = hi > 0 ? std::log(hi / lo) : 0;
    report->linear_scale = m.linear ? m.linear_scale : 0;
  }
  return m;
}

WardMapping ComputeWardMappingForImage(const cv::Mat& radiance, const ToneMapOptions& o,
                                       ToneMapReport* report) {
  RIG_CHECK(radiance.type() == CV_32FC3 && !radiance.empty(), "Ward takes CV_32FC3");
  cv::Mat foveal_rgb;
  // Resizing is linear and so is luminance: averaging RGB then weighting equals averaging
  // the luminance, at a third of the cost on the full image.
  const cv::Size fov = FovealSampleSize(radiance.cols, radiance.rows, o);
  cv::resize(radiance, foveal_rgb, fov, 0, 0, cv::INTER_AREA);
  const cv::Vec3f w = LuminanceWeightsBgr(o);
  cv::Mat foveal = Luminance(foveal_rgb, w);
  std::vector<float> samples(foveal.begin<float>(), foveal.end<float>());
  std::vector<float> points;
  if (o.ward_variant == WardVariant::kPcond && o.ward_point_samples_per_foveal > 0) {
    const int64_t pixels = static_cast<int64_t>(radiance.total());
    const int64_t wanted = static_cast<int64_t>(samples.size()) * o.ward_point_samples_per_foveal;
    std::vector<int64_t> idx;
    if (o.ward_sampling == WardSampling::kStratified) {
      const int k = std::max(1, static_cast<int>(std::lround(
                                    std::sqrt(static_cast<double>(o.ward_point_samples_per_foveal)))));
      idx = StratifiedPixelIndices(radiance.cols, radiance.rows,
                                   cv::Size(fov.width * k, fov.height * k), o.ward_seed);
    } else {
      idx = RandomPixelIndices(pixels, wanted, o.ward_seed);
    }
    points.reserve(idx.size());
    const int cols = radiance.cols;
    for (int64_t i : idx) {
      const float* p = radiance.ptr<float>(static_cast<int>(i / cols)) + 3 * (i % cols);
      points.push_back(w[0] * p[0] + w[1] * p[1] + w[2] * p[2]);
    }
  }
  WardMapping mapping = ComputeWardMapping(samples, points, o, report);
  if (report) {
    report->foveal_width = foveal.cols;
    report->foveal_height = foveal.rows;
    report->point_samples = static_cast<int>(points.size());
  }
  return mapping;
}

// ---- Whole images ----------------------------------------------------------------------

Result<cv::Mat> ToneMapLinearPixels(const cv::Mat& radiance, const ToneMapOptions& o,
                                    ToneMapReport* report) {
  RIG_TRY(CheckRadiance(radiance));
  RIG_TRY(CheckOptions(o));
  try {
    Result<cv::Mat> pixels = MakeError(ErrorCode::kInvalidInput, "tone mapping", "unknown method");
    switch (o.method) {
      case ToneMapMethod::kWard: pixels = WardPixels(radiance, o, report); break;
      case ToneMapMethod::kLinear: pixels = LinearPixels(radiance, o, report); break;
      case ToneMapMethod::kReinhard:
      case ToneMapMethod::kDrago:
      case ToneMapMethod::kMantiuk: pixels = OpenCvPixels(radiance, o.method); break;
    }
    if (!pixels.ok()) return pixels;
    RIG_ASSIGN_OR_RETURN(cv::Matx33d to_display,
                         RgbToRgbWhiteBalanced(o.picture_primaries, o.display_primaries));
    ToneMapOptions display = o;
    display.picture_primaries = o.display_primaries;
    MapToDisplayGamut(&*pixels, to_display, LuminanceWeightsBgr(display), o.gamut);
    return pixels;
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kInternal, "tone mapping", "OpenCV failed: {}", e.what());
  }
}

cv::Mat EncodeForDisplay(const cv::Mat& linear_pixels, const ToneMapOptions& o,
                         ToneMapReport* report) {
  RIG_CHECK(linear_pixels.type() == CV_32FC3, "EncodeForDisplay takes CV_32FC3");
  // Code k is chosen for linear values in [threshold[k], threshold[k+1]): the thresholds are
  // the decoded midpoints between neighbouring codes, so the code is the rounded encoding.
  std::array<double, 257> threshold;
  threshold[0] = -1;
  for (int k = 1; k <= 255; ++k) threshold[k] = DecodeValue((k - 0.5) / 255.0, o);
  threshold[256] = 2;
  // Float-bit table over [0, 1]: 1024 entries per octave, each holding the code of its
  // lowest value. Neighbouring thresholds are further apart (relatively) than an entry is
  // wide, so at most one falls inside an entry: one comparison makes the code exact.
  std::array<float, 257> threshold_f;
  for (int k = 0; k <= 256; ++k) threshold_f[k] = static_cast<float>(threshold[k]);
  const uint32_t entries = (Bits(1.0f) >> kLutShift) + 1;
  std::vector<uint8_t> table(entries);
  int code = 0;
  for (uint32_t i = 0; i < entries; ++i) {
    const float v = FromBits(i << kLutShift);
    while (code < 255 && v >= threshold_f[code + 1]) ++code;
    table[i] = static_cast<uint8_t>(code);
  }
  cv::Mat out(linear_pixels.size(), CV_8UC3);
  std::atomic<int64_t> low{0}, high{0};
  cv::parallel_for_(cv::Range(0, linear_pixels.rows), [&](const cv::Range& rows) {
    int64_t lo = 0, hi = 0;
    for (int y = rows.start; y < rows.end; ++y) {
      const float* in = linear_pixels.ptr<float>(y);
      uint8_t* o8 = out.ptr<uint8_t>(y);
      for (int x = 0; x < linear_pixels.cols; ++x, in += 3, o8 += 3) {
        for (int c = 0; c < 3; ++c) {
          const float v = in[c];
          // NaN compares false both ways and lands on 0.
          if (v >= 1.0f) {
            o8[c] = 255;
          } else if (v > 0) {
            const int k = table[Bits(v) >> kLutShift];
            o8[c] = static_cast<uint8_t>(k + (v >= threshold_f[k + 1]));
          } else {
            o8[c] = 0;
          }
        }
        lo += (o8[0] | o8[1] | o8[2]) == 0;
        hi += (o8[0] == 255) | (o8[1] == 255) | (o8[2] == 255);
      }
    }
    low += lo;
    high += hi;
  });
  if (report) {
    const double n = static_cast<double>(linear_pixels.total());
    report->clipped_low_fraction = n > 0 ? low.load() / n : 0;
    report->clipped_high_fraction = n > 0 ? high.load() / n : 0;
  }
  return out;
}

Result<cv::Mat> ToneMap(const cv::Mat& radiance, const ToneMapOptions& o, ToneMapReport* report) {
  RIG_ASSIGN_OR_RETURN(cv::Mat pixels, ToneMapLinearPixels(radiance, o, report));
  return EncodeForDisplay(pixels, o, report);
}

}  // namespace rig
