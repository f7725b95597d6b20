// Samples of ρ in a fit space: the transforms (linear, sRGB, log) every family fits in,
// the sample matrix built from radiance maps (missing samples listed), its Gram matrix, and
// the lamp radiance from a reference patch. Shared by every family and the session's fit.
#include "process/model/samples.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

namespace rig {

const char* FitSpaceName(FitSpace s) {
  switch (s) {
    case FitSpace::kLinear: return "linear";
    case FitSpace::kSrgb: return "srgb";
    case FitSpace::kLog: return "log";
  }
  return "?";
}

Result<FitSpace> ParseFitSpace(const std::string& name) {
  if (name == "linear") return FitSpace::kLinear;
  if (name == "srgb") return FitSpace::kSrgb;
  if (name == "log") return FitSpace::kLog;
  return MakeError(ErrorCode::kInvalidInput, "space", "unknown fit space '{}' (linear, srgb or log)",
                   name);
}

float SrgbEncode(float x) {
  const float a = std::fabs(x);
  const float e = a <= 0.0031308f ? 12.92f * a : 1.055f * std::pow(a, 1.0f / 2.4f) - 0.055f;
  return std::copysign(e, x);
}

float SrgbDecode(float y) {
  const float a = std::fabs(y);
  const float l = a <= 0.04045f ? a / 12.92f : std::pow((a + 0.055f) / 1.055f, 2.4f);
  return std::copysign(l, y);
}

float FitTransform::Forward(float rho) const {
  switch (space) {
    case FitSpace::kLinear: return rho;
    case FitSpace::kSrgb: return SrgbEncode(rho);
    case FitSpace::kLog:
      return static_cast<float>(std::log(std::max(0.0, static_cast<double>(rho)) + log_epsilon));
  }
  return rho;
}

float FitTransform::Inverse(float y) const {
  switch (space) {
    case FitSpace::kLinear: return y;
    case FitSpace::kSrgb: return SrgbDecode(y);
    case FitSpace::kLog: return static_cast<float>(std::exp(static_cast<double>(y)) - log_epsilon);
  }
  return y;
}

// The transcendental transforms go through OpenCV's vectorised log/exp on the linear part
// of the sRGB curve's complement; a scalar pow per value would cost 10x the matrix product.
void FitTransform::ForwardInPlace(float* data, size_t n) const {
  if (space == FitSpace::kLinear || n == 0) return;
  cv::Mat m(1, static_cast<int>(n), CV_32F, data);
  if (space == FitSpace::kLog) {
    cv::max(m, 0.0, m);
    m += log_epsilon;
    cv::log(m, m);
    return;
  }
  // sRGB: 1.055·exp(ln(x)/2.4) - 0.055 above the knee, 12.92·x below (odd extension).
  cv::Mat a = cv::abs(m), l;
  cv::max(a, 1e-30, l);
  cv::log(l, l);
  l *= 1.0 / 2.4;
  cv::exp(l, l);
  l = l * 1.055 - 0.055;
  float* lp = l.ptr<float>();
  const float* ap = a.ptr<float>();
  for (size_t i = 0; i < n; ++i) {
    const float e = ap[i] <= 0.0031308f ? 12.92f * ap[i] : lp[i];
    data[i] = data[i] < 0 ? -e : e;
  }
}

void FitTransform::InverseInPlace(float* data, size_t n) const {
  if (space == FitSpace::kLinear || n == 0) return;
  cv::Mat m(1, static_cast<int>(n), CV_32F, data);
  if (space == FitSpace::kLog) {
    cv::exp(m, m);
    m -= log_epsilon;
    return;
  }
  cv::Mat a = cv::abs(m), l;
  l = (a + 0.055) * (1.0 / 1.055);
  cv::max(l, 1e-30, l);
  cv::log(l, l);
  l *= 2.4;
  cv::exp(l, l);
  float* lp = l.ptr<float>();
  const float* ap = a.ptr<float>();
  for (size_t i = 0; i < n; ++i) {
    const float v = ap[i] <= 0.04045f ? ap[i] / 12.92f : lp[i];
    data[i] = data[i] < 0 ? -v : v;
  }
}

Status BuildSamples(const std::vector<cv::Mat>& radiance, const std::vector<cv::Mat>& valid,
                    const std::array<double, 3>& e_rgb, const FitTransform& transform,
                    SampleMatrix* samples, std::vector<uint8_t>* missing) {
  const size_t n = radiance.size();
  if (n == 0) return MakeError(ErrorCode::kInvalidInput, "samples", "no radiance maps");
  const int rows = radiance[0].rows, cols = radiance[0].cols;
  for (size_t i = 0; i < n; ++i) {
    if (radiance[i].type() != CV_32FC3 || radiance[i].rows != rows || radiance[i].cols != cols) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("pose {}", i),
                       "radiance must be CV_32FC3 {}x{} like the first map", cols, rows);
    }
    if (!valid.empty() && (valid[i].type() != CV_8UC1 || valid[i].size() != radiance[i].size())) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("pose {}", i),
                       "validity mask must be CV_8UC1 of the radiance map's size");
    }
  }
  if (!valid.empty() && valid.size() != n) {
    return MakeError(ErrorCode::kInvalidInput, "samples", "{} validity masks for {} maps",
                     valid.size(), n);
  }
  return BuildSamplesFromRows(
      n, rows, cols, [&](size_t i, int y) { return radiance[i].ptr<float>(y); },
      [&](size_t i, int y) -> const uint8_t* { return valid.empty() ? nullptr : valid[i].ptr<uint8_t>(y); },
      e_rgb, transform, samples, missing);
}

Status BuildSamplesFromRows(size_t n, int rows, int cols,
                            const std::function<const float*(size_t, int)>& row,
                            const std::function<const uint8_t*(size_t, int)>& valid_row,
                            const std::array<double, 3>& e_rgb, const FitTransform& transform,
                            SampleMatrix* samples, std::vector<uint8_t>* missing) {
  if (n == 0) return MakeError(ErrorCode::kInvalidInput, "samples", "no radiance maps");
  const size_t pixels = static_cast<size_t>(rows) * cols;
  samples->resize(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(pixels * 3));
  missing->clear();
  // BGR order in memory; lamp radiance is R, G, B.
  const float inv[3] = {static_cast<float>(1.0 / e_rgb[2]), static_cast<float>(1.0 / e_rgb[1]),
                        static_cast<float>(1.0 / e_rgb[0])};
  // The lamp's 1/E per channel repeated over 24 floats (8 pixels, a whole number of SIMD
  // registers), so that the scaling is one straight vectorised loop.
  float pattern[24];
  for (int k = 0; k < 24; ++k) pattern[k] = inv[k % 3];
  constexpr float kMax = std::numeric_limits<float>::max();
  std::vector<uint8_t> bad;
  for (size_t i = 0; i < n; ++i) {
    float* out = samples->row(static_cast<Eigen::Index>(i)).data();
    bool pose_missing = false;
    for (int y = 0; y < rows; ++y) {
      const float* in = row(i, y);
      const uint8_t* vm = valid_row(i, y);
      float* o = out + static_cast<size_t>(y) * cols * 3;
      const size_t values = static_cast<size_t>(cols) * 3;
      // Every sample scaled by 1/E; the missing ones are set to 0 below.
      size_t j = 0;
      for (; j + 24 <= values; j += 24)
        for (int k = 0; k < 24; ++k) o[j + k] = in[j + k] * pattern[k];
      for (; j < values; ++j) o[j] = in[j] * inv[j % 3];
      // A sample is valid when its mask says so and every channel is finite and >= 0
      // (v >= 0 && v <= FLT_MAX fails for NaN, ±inf and negatives alike): per pixel,
      // branch-free; the row is walked again only when some sample of it is missing.
      bad.resize(static_cast<size_t>(cols));
      uint8_t any_bad = 0;
      for (int x = 0; x < cols; ++x) {
        const float b = in[3 * x], g = in[3 * x + 1], r = in[3 * x + 2];
        const bool ok = (b >= 0.f) & (b <= kMax) & (g >= 0.f) & (g <= kMax) & (r >= 0.f) &
                        (r <= kMax) & (vm == nullptr || vm[x] != 0);
        bad[static_cast<size_t>(x)] = static_cast<uint8_t>(!ok);
        any_bad |= static_cast<uint8_t>(!ok);
      }
      if (!any_bad) continue;
      if (missing->empty()) missing->assign(n * pixels, 0);
      pose_missing = true;
      uint8_t* mrow = missing->data() + i * pixels + static_cast<size_t>(y) * cols;
      for (int x = 0; x < cols; ++x) {
        if (!bad[static_cast<size_t>(x)]) continue;
        mrow[x] = 1;
        o[3 * x] = o[3 * x + 1] = o[3 * x + 2] = 0;
      }
    }
    transform.ForwardInPlace(out, pixels * 3);
    if (pose_missing) {
      // Missing samples stay 0 in fit space, whatever the transform maps 0 to.
      const uint8_t* mrow = missing->data() + i * pixels;
      for (size_t p = 0; p < pixels; ++p)
        if (mrow[p]) out[3 * p] = out[3 * p + 1] = out[3 * p + 2] = 0;
    }
  }
  return Ok();
}

Eigen::MatrixXd SampleGram(const SampleMatrix& y, const std::vector<uint8_t>& missing,
                           size_t stride, double* count) {
  const Eigen::Index n = y.rows();
  const size_t pixels = static_cast<size_t>(y.cols()) / 3;
  stride = std::max<size_t>(stride, 1);
  std::vector<Eigen::Index> cols;
  for (size_t p = 0; p < pixels; p += stride) {
    bool ok = true;
    if (!missing.empty()) {
      for (Eigen::Index i = 0; i < n && ok; ++i) ok = !missing[i * pixels + p];
    }
    if (!ok) continue;
    for (int c = 0; c < 3; ++c) cols.push_back(static_cast<Eigen::Index>(3 * p + c));
  }
  *count = static_cast<double>(cols.size());
  if (stride == 1 && missing.empty()) {
    return (y.cast<double>() * y.cast<double>().transpose());
  }
  // Gather in chunks so that the Gram matrix is a sequence of GEMMs.
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(n, n);
  const size_t chunk = 4096;
  Eigen::MatrixXd block(n, chunk);
  for (size_t s = 0; s < cols.size(); s += chunk) {
    const size_t m = std::min(chunk, cols.size() - s);
    for (size_t j = 0; j < m; ++j) block.col(j) = y.col(cols[s + j]).cast<double>();
    g.noalias() += block.leftCols(m) * block.leftCols(m).transpose();
  }
  return g;
}

Result<std::array<double, 3>> CalibrateLampRadiance(const std::vector<cv::Mat>& radiance,
                                                    const std::array<int, 4>& patch,
                                                    double reflectance) {
  if (radiance.empty()) return MakeError(ErrorCode::kInvalidInput, "reference patch", "no maps");
  const cv::Rect r(patch[0], patch[1], patch[2], patch[3]);
  const cv::Rect image(0, 0, radiance[0].cols, radiance[0].rows);
  if (r.width <= 0 || r.height <= 0 || (r & image) != r) {
    return MakeError(ErrorCode::kInvalidInput, "process.reference_patch_px",
                     "patch [{}, {}, {}, {}] is not inside the {}x{} image", r.x, r.y, r.width,
                     r.height, image.width, image.height);
  }
  std::array<std::vector<double>, 3> per_pose;
  for (const auto& m : radiance) {
    const cv::Scalar mean = cv::mean(m(r));
    for (int c = 0; c < 3; ++c) per_pose[c].push_back(mean[2 - c]);  // BGR -> R, G, B
  }
  std::array<double, 3> e{};
  for (int c = 0; c < 3; ++c) {
    auto& v = per_pose[c];
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    e[c] = v[v.size() / 2] / reflectance;
    if (!(e[c] > 0)) {
      return MakeError(ErrorCode::kInvalidInput, "process.reference_patch_px",
                       "the reference patch is black in channel {}", "RGB"[c]);
    }
  }
  return e;
}

}  // namespace rig
