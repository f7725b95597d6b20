// Reflectance of radiance maps as 8-bit codes, for the families that model code values (PCA,
// neural): ρ = radiance ÷ lamp radiance encoded by a curve that keeps a high dynamic range in
// 8 bits, its parameters set from the data and stated in the model, so that loading decodes
// back to linear reflectance (and renders give radiance, as the harmonic families' do).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/light_samples.h"

namespace rig {

enum class HdrCurve {
  kLog,   // code = 255 · ln(1 + ρ/floor) / ln(1 + max/floor): relative steps above the floor,
          // linear below it, code 0 at ρ = 0
  kSrgb,  // code = 255 · sRGB(ρ / max): the photographs' own curve over a scaled range
  kPower, // code = 255 · (ρ / max)^(1/gamma): gamma 1 is linear
};
const char* HdrCurveName(HdrCurve curve);  // "log", "srgb", "power"
Result<HdrCurve> ParseHdrCurve(const std::string& name);

struct HdrCodeCurve {
  HdrCurve curve = HdrCurve::kLog;
  double max = 1;       // reflectance at code 255 (beyond it: clipped, a censored sample)
  double floor = 1e-3;  // log: where the curve turns from linear to logarithmic (unused by srgb)
  double gamma = 1;     // power: the exponent

  double Encode(double rho) const;   // code, 0 .. 255 within range (not clamped, not rounded)
  double Decode(double code) const;  // linear reflectance from a code (0 .. 255 units)
  // Relative size of one code step at the top of the range (what quantisation costs there).
  double TopStep() const { return Decode(255) / Decode(254) - 1; }
};

// The curve's range from the data: `max` at the `high` quantile of every sample-channel's ρ,
// `floor` (log) at the `low` quantile of the positive ones; at least `min_stops` stops below
// max is what the floor may lie at, so that a dim scene keeps its relative steps. The values
// are read from a seeded sample of at most `count` sample-channels.
struct HdrCurveOptions {
  HdrCurve curve = HdrCurve::kLog;
  double gamma = 1;
  double high = 0.9999;
  double low = 0.01;
  double max_stops = 16;  // the floor no lower than max · 2^-max_stops
};
HdrCodeCurve FitHdrCurve(const std::vector<cv::Mat>& rho_bgr, const HdrCurveOptions& options);

// The same choice made from radiance maps read in any order of row bands (a session's maps as
// they are held, never all in floats at once): the sample-channels are FitHdrCurve's own
// (every stride-th of the maps laid end to end, 2^20 in all), ρ = radiance ÷ lamp as
// SamplesFromMaps divides it, and the quantiles do not depend on the order the bands come in,
// so any band order gives the curve of the whole maps.
class HdrCurveSampler {
 public:
  HdrCurveSampler(size_t maps, size_t pixels, const std::array<double, 3>& lamp_radiance_rgb);
  // Rows of map `map` (CV_32FC3 BGR radiance, continuous) whose first pixel is `first_pixel`
  // of the map. Not thread-safe.
  void Add(size_t map, size_t first_pixel, const cv::Mat& radiance_bgr_rows);
  HdrCodeCurve Curve(const HdrCurveOptions& options) const;
  // Another sampler's values (of other rows of the same maps) added: the curve is the one of
  // every row either was given, whatever the split.
  void Merge(const HdrCurveSampler& other);

 private:
  size_t pixels_, stride_;
  std::array<double, 3> lamp_;
  std::vector<float> all_, positive_;
};
// HdrCurveSampler over whole maps (all one size): the curve of their reflectance.
HdrCodeCurve FitHdrCurveOfRadiance(const std::vector<cv::Mat>& radiance_bgr,
                                   const std::array<double, 3>& lamp_radiance_rgb,
                                   const HdrCurveOptions& options);

// One sample's code: radiance ÷ the lamp's radiance in that channel, encoded and rounded
// (negative and NaN as 0, beyond max as 255) — what SamplesFromMaps stores.
inline uint8_t HdrCode(float radiance, double lamp, const HdrCodeCurve& curve) {
  const double code = std::round(curve.Encode(radiance / lamp));
  return static_cast<uint8_t>(std::isfinite(code) ? std::clamp(code, 0.0, 255.0) : 0.0);
}

// Multi-light samples of radiance maps (CV_32FC3 BGR, one per lamp, all one size): ρ =
// radiance ÷ lamp radiance (R, G, B) per channel, encoded and rounded to codes (negative and
// NaN ρ as 0, beyond max as 255). The usable mask is left empty: with the thresholds of
// HdrMaskThresholds the censored samples are exactly the clamped codes.
// `threads` share the maps (the codes do not depend on it).
LightSamples SamplesFromMaps(const std::vector<cv::Mat>& radiance_bgr,
                             const std::vector<Vec3>& directions,
                             const std::array<double, 3>& lamp_radiance_rgb,
                             const HdrCodeCurve& curve, int threads = 1);
// HdrCode of one channel by table: the smallest radiance of each code 1..255 found once (a
// binary search over the floats' bit patterns, the code rising with the radiance), then each
// value's code looked up by the top bits of its float (sign, exponent and 11 bits of mantissa:
// one bucket of 2^12 consecutive floats) where every float of the bucket has one code, and
// found by its place among the first radiances where a code starts inside the bucket — the
// same code as HdrCode for every float, without a power or logarithm, and without a search
// for most samples. Beyond the code-255 threshold, and for NaN and infinities, HdrCode itself.
class HdrCodeTable {
 public:
  HdrCodeTable(const HdrCodeCurve& curve, double lamp);
  uint8_t operator()(float radiance) const {
    if (!(radiance > 0) || !(radiance < top_)) return HdrCode(radiance, lamp_, curve_);
    if (radiance < first_[0]) return 0;
    uint32_t bits;
    std::memcpy(&bits, &radiance, sizeof bits);
    const uint32_t b = (bits >> kBucketShift) - bucket0_;
    const uint8_t code = b < bucket_.size() ? bucket_[b] : kMixed;
    return code != kMixed ? code : Search(radiance);
  }

 private:
  static constexpr int kBucketShift = 12;
  static constexpr uint8_t kMixed = 0;  // a bucket where a code starts (code 0 never reaches here)
  uint8_t Search(float radiance) const {
    return static_cast<uint8_t>(std::upper_bound(first_.begin(), first_.end(), radiance) - first_.begin());
  }
  HdrCodeCurve curve_;
  double lamp_;
  std::array<float, 254> first_;  // first_[k - 1]: the smallest radiance of code k, k = 1..254
  float top_;                     // the smallest of code 255
  uint32_t bucket0_ = 0;          // the bucket of first_[0]
  std::vector<uint8_t> bucket_;   // code of every float in buckets bucket0_.. up to top_'s; kMixed
};

// Reflectance maps (radiance ÷ lamp radiance), CV_32FC3 BGR.
std::vector<cv::Mat> ReflectanceOf(const std::vector<cv::Mat>& radiance_bgr,
                                   const std::array<double, 3>& lamp_radiance_rgb);
// Codes 0 and 255 are the clamped ends: a sample there is censored (below the floor of the
// range, or beyond its max), every other code is exact to half a code.
inline constexpr LdrMaskThresholds kHdrMaskThresholds{0, 255};

}  // namespace rig
