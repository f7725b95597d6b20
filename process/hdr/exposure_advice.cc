// Exposure statistics of one frame and the bracket rule.
#include "process/hdr/exposure_advice.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

constexpr double kGamma = 2.2;
constexpr double kClipped = 250, kDark = 5;
constexpr double kHighTarget = 200, kLowTarget = 128;
constexpr double kGuessStops = 3;

double Linear(double v) { return std::pow(std::max(v, 0.5) / 255.0, kGamma); }

}  // namespace

Result<ExposureStats> AnalyzeExposure(const cv::Mat& image, double exposure_s) {
  if (image.empty() || image.channels() != 3 || exposure_s <= 0)
    return MakeError(ErrorCode::kInvalidInput, "frame", "expected a 3-channel image and an exposure > 0");
  cv::Mat img8;
  if (image.depth() == CV_8U) img8 = image;
  else if (image.depth() == CV_16U) image.convertTo(img8, CV_8U, 1.0 / 257.0);
  else return MakeError(ErrorCode::kInvalidInput, "frame", "8- or 16-bit images only");
  ExposureStats s;
  s.exposure_s = exposure_s;
  s.pixels = img8.rows * img8.cols;
  std::array<int64_t, 256> hist{};
  int64_t clipped = 0;
  for (int y = 0; y < img8.rows; ++y) {
    const uint8_t* p = img8.ptr<uint8_t>(y);
    for (int x = 0; x < img8.cols; ++x, p += 3) {
      const uint8_t m = std::max({p[0], p[1], p[2]});
      ++hist[m];
      if (m >= kClipped) ++clipped;
    }
  }
  auto percentile = [&](double q) {
    const int64_t target = static_cast<int64_t>(std::ceil(q * static_cast<double>(s.pixels)));
    int64_t acc = 0;
    for (int v = 0; v < 256; ++v) {
      acc += hist[v];
      if (acc >= std::max<int64_t>(1, target)) return static_cast<double>(v);
    }
    return 255.0;
  };
  s.p01 = percentile(0.01);
  s.p50 = percentile(0.5);
  s.p99 = percentile(0.99);
  s.p999 = percentile(0.999);
  int64_t dark = 0;
  for (int v = 0; v <= kDark; ++v) dark += hist[v];
  s.clipped_fraction = static_cast<double>(clipped) / s.pixels;
  s.dark_fraction = static_cast<double>(dark) / s.pixels;
  for (int v = 0; v < 256; ++v) s.histogram[v / 32] += static_cast<double>(hist[v]) / s.pixels;
  return s;
}

BracketAdvice SuggestBracket(const ExposureStats& s, double ev_step) {
  BracketAdvice a;
  a.ev_step = ev_step;
  const double t = s.exposure_s;
  if (s.p999 >= kClipped) {
    a.highlights_guessed = true;
    a.shortest_s = t / std::pow(2.0, kGuessStops);
  } else {
    a.shortest_s = t * Linear(kHighTarget) / Linear(s.p999);
  }
  if (s.p01 <= kDark) {
    a.shadows_guessed = true;
    a.longest_s = t * std::pow(2.0, kGuessStops);
  } else {
    a.longest_s = t * Linear(kLowTarget) / Linear(s.p01);
  }
  a.longest_s = std::max(a.longest_s, a.shortest_s);
  const double stops = std::log2(a.longest_s / a.shortest_s);
  a.count = static_cast<int>(std::ceil(stops / ev_step - 1e-9)) + 1;
  a.center_s = std::sqrt(a.shortest_s * a.longest_s);
  if (a.highlights_guessed)
    a.note += fmt::format("highlights clipped at {:.4g} s: the short end is a guess {} stops down; "
                          "shoot again at {:.4g} s. ",
                          t, kGuessStops, a.shortest_s);
  if (a.shadows_guessed)
    a.note += fmt::format("shadows in the noise at {:.4g} s: the long end is a guess {} stops up; "
                          "shoot again at {:.4g} s. ",
                          t, kGuessStops, a.longest_s);
  return a;
}

}  // namespace rig
