// Leave-one-out by refitting, scored in 8 bits.
#include "process/model/holdout.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>

namespace rig {

LightSamples SamplesFromImages(const std::vector<cv::Mat>& bgr8, const std::vector<Vec3>& lights) {
  LightSamples s;
  if (bgr8.empty()) return s;
  s.width = bgr8[0].cols;
  s.height = bgr8[0].rows;
  s.directions = lights;
  const size_t pixels = s.pixels();
  const size_t n = bgr8.size();
  s.values.resize(pixels * n * 3);
  for (size_t l = 0; l < n; ++l) {
    const cv::Mat img = bgr8[l].isContinuous() ? bgr8[l] : bgr8[l].clone();
    const uint8_t* src = img.ptr<uint8_t>();
    for (size_t p = 0; p < pixels; ++p) {
      uint8_t* dst = s.values.data() + (p * n + l) * 3;
      dst[0] = src[p * 3 + 2];
      dst[1] = src[p * 3 + 1];
      dst[2] = src[p * 3 + 0];
    }
  }
  return s;
}

double EightBitMse(const LightSamples& all, int light, const cv::Mat& predicted) {
  const size_t pixels = all.pixels();
  const float* pr = predicted.ptr<float>();
  double sum = 0;
  for (size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c) {
      const float v = std::clamp(std::nearbyint(pr[p * 3 + (2 - c)] * 255.0f), 0.0f, 255.0f);
      const double d = v - all.value(p, light, c);
      sum += d * d;
    }
  }
  return sum / static_cast<double>(pixels * 3);
}

double PsnrFromMse(double mse) { return 10.0 * std::log10(255.0 * 255.0 / std::max(mse, 1e-12)); }

Result<HoldoutScore> LeaveOneOut(const LightSamples& all, const std::vector<int>& held_out,
                                 const FitAndPredict& fit) {
  HoldoutScore score;
  score.held_out = held_out;
  if (score.held_out.empty()) {
    for (int l = 0; l < all.lights(); ++l) score.held_out.push_back(l);
  }
  double bytes = 0, seconds = 0;
  std::vector<double> psnr;
  for (int l : score.held_out) {
    const auto t0 = std::chrono::steady_clock::now();
    const LightSamples fold = WithoutLight(all, l);
    auto r = fit(fold, l, all.directions[l]);
    if (!r.ok()) {
      Error e = r.error();
      e.message = fmt::format("fold without image {}: {}", l + 1, e.message);
      return e;
    }
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (r->predicted.rows != all.height || r->predicted.cols != all.width ||
        r->predicted.type() != CV_32FC3) {
      return MakeError(ErrorCode::kInternal, "leave-one-out", "fold {} predicted a {}x{} image",
                       l + 1, r->predicted.cols, r->predicted.rows);
    }
    const double mse = EightBitMse(all, l, r->predicted);
    score.mse.push_back(mse);
    psnr.push_back(PsnrFromMse(mse));
    bytes += static_cast<double>(r->bytes);
  }
  double mean_mse = 0;
  for (double m : score.mse) mean_mse += m;
  mean_mse /= static_cast<double>(score.mse.size());
  score.psnr_mean_mse_db = PsnrFromMse(mean_mse);
  std::sort(psnr.begin(), psnr.end());
  const size_t n = psnr.size();
  score.psnr_median_db = n % 2 ? psnr[n / 2] : 0.5 * (psnr[n / 2 - 1] + psnr[n / 2]);
  score.bytes_per_pixel = bytes / static_cast<double>(n) / static_cast<double>(all.pixels());
  score.fold_time_s = seconds / static_cast<double>(n);
  return score;
}

}  // namespace rig
