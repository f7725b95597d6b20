// Reflectance of radiance maps as 8-bit codes.
#include "process/model/hdr_codes.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <thread>

#include "process/model/samples.h"

namespace rig {

const char* HdrCurveName(HdrCurve curve) {
  return curve == HdrCurve::kLog ? "log" : curve == HdrCurve::kSrgb ? "srgb" : "power";
}

Result<HdrCurve> ParseHdrCurve(const std::string& name) {
  if (name == "log") return HdrCurve::kLog;
  if (name == "srgb") return HdrCurve::kSrgb;
  if (name == "power") return HdrCurve::kPower;
  return MakeError(ErrorCode::kInvalidInput, name, "unknown value curve (log, srgb, power)");
}

double HdrCodeCurve::Encode(double rho) const {
  if (!(rho > 0)) return 0;
  if (curve == HdrCurve::kSrgb) return 255.0 * SrgbEncode(static_cast<float>(rho / max));
  if (curve == HdrCurve::kPower) return 255.0 * std::pow(rho / max, 1.0 / gamma);
  return 255.0 * std::log1p(rho / floor) / std::log1p(max / floor);
}

double HdrCodeCurve::Decode(double code) const {
  if (curve == HdrCurve::kSrgb) {
    // SrgbDecode is defined for any value (linear toe, power above it): codes beyond the range
    // that a model predicts decode monotonically.
    return max * SrgbDecode(static_cast<float>(code / 255.0));
  }
  if (curve == HdrCurve::kPower) return max * std::copysign(std::pow(std::abs(code) / 255.0, gamma), code);
  return floor * std::expm1(code / 255.0 * std::log1p(max / floor));
}

namespace {

double Quantile(std::vector<float> v, double q) {
  if (v.empty()) return 1.0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return static_cast<double>(v[k]);
}

HdrCodeCurve CurveOfSample(const std::vector<float>& all, const std::vector<float>& positive,
                           const HdrCurveOptions& o) {
  HdrCodeCurve c;
  c.curve = o.curve;
  c.gamma = o.gamma;
  c.max = Quantile(all, o.high);
  if (!(c.max > 0)) c.max = 1;
  c.floor = std::max(Quantile(positive, o.low), c.max * std::exp2(-o.max_stops));
  c.floor = std::min(c.floor, c.max);
  return c;
}

constexpr size_t kCurveSampleChannels = size_t{1} << 20;

}  // namespace

HdrCodeCurve FitHdrCurve(const std::vector<cv::Mat>& rho_bgr, const HdrCurveOptions& o) {
  std::vector<float> all, positive;
  size_t total = 0;
  for (const auto& m : rho_bgr) total += m.total() * 3;
  const size_t stride = std::max<size_t>(1, total / kCurveSampleChannels);
  size_t i = 0;
  for (const auto& m : rho_bgr) {
    const float* p = m.ptr<float>();
    const size_t n = m.total() * 3;
    for (size_t j = 0; j < n; ++j, ++i) {
      if (i % stride != 0) continue;
      const float v = std::isfinite(p[j]) ? std::max(p[j], 0.0f) : 0.0f;
      all.push_back(v);
      if (v > 0) positive.push_back(v);
    }
  }
  return CurveOfSample(all, positive, o);
}

HdrCurveSampler::HdrCurveSampler(size_t maps, size_t pixels, const std::array<double, 3>& lamp)
    : pixels_(pixels), stride_(std::max<size_t>(1, maps * pixels * 3 / kCurveSampleChannels)), lamp_(lamp) {}

void HdrCurveSampler::Add(size_t map, size_t first_pixel, const cv::Mat& rows) {
  const float* p = rows.ptr<float>();
  const size_t base = (map * pixels_ + first_pixel) * 3, n = rows.total() * 3;
  // The first index of this run that is a multiple of the stride.
  for (size_t j = (stride_ - base % stride_) % stride_; j < n; j += stride_) {
    const float rho = static_cast<float>(p[j] / lamp_[2 - j % 3]);
    const float v = std::isfinite(rho) ? std::max(rho, 0.0f) : 0.0f;
    all_.push_back(v);
    if (v > 0) positive_.push_back(v);
  }
}

void HdrCurveSampler::Merge(const HdrCurveSampler& other) {
  all_.insert(all_.end(), other.all_.begin(), other.all_.end());
  positive_.insert(positive_.end(), other.positive_.begin(), other.positive_.end());
}

HdrCodeCurve HdrCurveSampler::Curve(const HdrCurveOptions& o) const {
  return CurveOfSample(all_, positive_, o);
}

HdrCodeCurve FitHdrCurveOfRadiance(const std::vector<cv::Mat>& radiance,
                                   const std::array<double, 3>& lamp, const HdrCurveOptions& o) {
  if (radiance.empty()) return CurveOfSample({}, {}, o);
  HdrCurveSampler sampler(radiance.size(), radiance[0].total(), lamp);
  for (size_t l = 0; l < radiance.size(); ++l) sampler.Add(l, 0, radiance[l]);
  return sampler.Curve(o);
}

std::vector<cv::Mat> ReflectanceOf(const std::vector<cv::Mat>& radiance_bgr,
                                   const std::array<double, 3>& lamp) {
  std::vector<cv::Mat> out;
  for (const auto& r : radiance_bgr) {
    cv::Mat rho;
    cv::divide(r, cv::Scalar(lamp[2], lamp[1], lamp[0]), rho);
    out.push_back(rho);
  }
  return out;
}

namespace {

// The smallest positive finite float whose code is at least `code` (+inf: none).
float FirstOfCode(const HdrCodeCurve& curve, double lamp, int code) {
  uint32_t lo = 1, hi = 0x7f800000u;  // [lo, hi): candidates; hi is +inf
  while (lo < hi) {
    const uint32_t mid = lo + (hi - lo) / 2;
    float f;
    std::memcpy(&f, &mid, sizeof f);
    if (HdrCode(f, lamp, curve) >= code) {
      hi = mid;
    } else {
      lo = mid + 1;
    }
  }
  float f;
  std::memcpy(&f, &lo, sizeof f);
  return f;
}

}  // namespace

HdrCodeTable::HdrCodeTable(const HdrCodeCurve& curve, double lamp) : curve_(curve), lamp_(lamp) {
  for (int k = 1; k <= 254; ++k) first_[k - 1] = FirstOfCode(curve, lamp, k);
  top_ = FirstOfCode(curve, lamp, 255);
  // Buckets from first_[0]'s to top_'s (both finite when the curve has 255 codes; a curve whose
  // top is +inf, or one without code 1, keeps no buckets and searches or calls HdrCode).
  // Buckets from first_[0]'s to top_'s; none (every value searched) for a curve without both.
  if (!(first_[0] < top_) || !std::isfinite(top_)) return;
  uint32_t lo, hi;
  std::memcpy(&lo, &first_[0], sizeof lo);
  std::memcpy(&hi, &top_, sizeof hi);
  bucket0_ = lo >> kBucketShift;
  const uint32_t last = hi >> kBucketShift;
  bucket_.assign(last - bucket0_ + 1, kMixed);
  for (uint32_t b = bucket0_; b <= last; ++b) {
    const uint32_t first_bits = std::max(b << kBucketShift, lo);
    const uint32_t last_bits = std::min(((b + 1) << kBucketShift) - 1, hi - 1);
    float f0, f1;
    std::memcpy(&f0, &first_bits, sizeof f0);
    std::memcpy(&f1, &last_bits, sizeof f1);
    // The code rises with the radiance: one code at both ends is the bucket's only code.
    const uint8_t c0 = Search(f0), c1 = Search(f1);
    if (c0 == c1) bucket_[b - bucket0_] = c0;
  }
}

LightSamples SamplesFromMaps(const std::vector<cv::Mat>& radiance_bgr,
                             const std::vector<Vec3>& directions,
                             const std::array<double, 3>& lamp, const HdrCodeCurve& curve,
                             int threads) {
  LightSamples s;
  if (radiance_bgr.empty()) return s;
  s.width = radiance_bgr[0].cols;
  s.height = radiance_bgr[0].rows;
  s.directions = directions;
  const size_t lights = radiance_bgr.size();
  const size_t pixels = s.pixels();
  s.values.resize(pixels * lights * 3);
  const std::array<HdrCodeTable, 3> code = {HdrCodeTable(curve, lamp[0]), HdrCodeTable(curve, lamp[1]),
                                            HdrCodeTable(curve, lamp[2])};
  threads = std::max(1, std::min<int>(threads, static_cast<int>(lights)));
  auto body = [&](size_t first) {
  for (size_t l = first; l < lights; l += static_cast<size_t>(threads)) {
    const cv::Mat& m = radiance_bgr[l];
    for (int y = 0; y < s.height; ++y) {
      const float* row = m.ptr<float>(y);
      for (int x = 0; x < s.width; ++x) {
        const size_t p = static_cast<size_t>(y) * s.width + x;
        for (int c = 0; c < 3; ++c)
          s.values[(p * lights + l) * 3 + c] = code[c](row[x * 3 + (2 - c)]);
      }
    }
  }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(body, static_cast<size_t>(t));
  body(0);
  for (auto& t : pool) t.join();
  return s;
}

}  // namespace rig
