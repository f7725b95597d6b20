// Synthetic brackets with known truth: radiance images, a filmic per-channel camera response,
// and brackets rendered through it from any radiance map (e.g. a real HDR image) with seeded
// noise; error measures against the truth. Header-only: used by bench/hdr_bench.cc, the
// tests and `rig evaluate`.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "process/io/image_io.h"

namespace rig::synth {

// A filmic S-curve per channel (Hable's "Uncharted 2" operator on linear exposure, with a
// per-channel exposure scale and output power): toe and shoulder, no plain gamma.
// X is the sensor exposure E * t; f(X) in [0, 1]; f reaches 1 (saturation) at X_sat(c).
class FilmicResponse {
 public:
  FilmicResponse(std::array<double, 3> scale = {0.9, 1.0, 1.15},
                 std::array<double, 3> power = {0.92, 1.0, 1.08})
      : scale_(scale), power_(power) {
    for (int c = 0; c < 3; ++c) {
      // Tabulate f on a fine grid of ln X for fast rendering and exact inversion.
      table_[c].resize(kTable);
      for (int i = 0; i < kTable; ++i) table_[c][i] = Eval(c, std::exp(LnX(i)));
    }
  }
  // The exact curve.
  double Eval(int c, double x) const {
    if (x <= 0) return 0;
    const double v = Hable(kWhite * scale_[c] * x) / Hable(kWhite);
    return std::pow(std::min(1.0, v), power_[c]);
  }
  // The curve through the table (linear interpolation in ln X), for rendering.
  double Fast(int c, double x) const {
    if (x <= 0) return 0;
    const double pos = (std::log(x) - kLnMin) / (kLnMax - kLnMin) * (kTable - 1);
    if (pos <= 0) return table_[c][0];
    if (pos >= kTable - 1) return table_[c][kTable - 1];
    const int i = int(pos);
    const double f = pos - i;
    return table_[c][i] * (1 - f) + table_[c][i + 1] * f;
  }
  // Truth of Debevec-Malik's g for level z of `levels`: ln X with f(X) = z / (levels - 1).
  double TrueG(int c, double z, int levels = 256) const {
    const double target = z / (levels - 1);
    double lo = kLnMin, hi = kLnMax;
    for (int it = 0; it < 100; ++it) {
      const double mid = 0.5 * (lo + hi);
      (Eval(c, std::exp(mid)) < target ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
  }

 private:
  static constexpr int kTable = 1 << 15;
  static constexpr double kLnMin = -16, kLnMax = 3, kWhite = 11.2;
  static double LnX(int i) { return kLnMin + (kLnMax - kLnMin) * i / (kTable - 1); }
  static double Hable(double x) {
    constexpr double a = 0.15, b = 0.50, c = 0.10, d = 0.20, e = 0.02, f = 0.30;
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f;
  }
  std::array<double, 3> scale_, power_;
  std::array<std::vector<double>, 3> table_;
};

// A radiance image (CV_32FC3 BGR) spanning about 4.5 decades: a smooth log-radiance ramp with
// slow colour variation, flat patches at 16 levels, one blazing spot (saturated in every
// exposure of ExposuresFor's bracket) and one zero-radiance spot (black in every exposure).
// `spots` rectangles (optional) receive where the two spots are.
inline cv::Mat SyntheticRadiance(int w, int h, cv::Rect* hot_spot = nullptr,
                                 cv::Rect* black_spot = nullptr) {
  cv::Mat e(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y) {
    auto* row = e.ptr<cv::Vec3f>(y);
    const double v = double(y) / h;
    for (int x = 0; x < w; ++x) {
      const double u = double(x) / w;
      const double log10e = -2.0 + 4.5 * u + 0.25 * std::sin(6.0 * v + 3.0 * u);
      const double base = std::pow(10.0, log10e);
      row[x] = cv::Vec3f(float(base * (0.8 + 0.3 * v)), float(base),
                         float(base * (1.2 - 0.4 * v * u)));
    }
  }
  // Flat patches: a 4 x 4 grid in the lower half, log10 radiance -2 .. 2.5.
  const int pw = w / 10, ph = h / 12;
  for (int i = 0; i < 16; ++i) {
    const int px = w / 20 + (i % 4) * (w / 4), py = h / 2 + (i / 4) * (h / 9);
    const double level = std::pow(10.0, -2.0 + 4.5 * i / 15.0);
    cv::Rect r(px, py, pw, ph);
    r &= cv::Rect(0, 0, w, h);
    e(r).setTo(cv::Scalar(level * 0.7, level, level * 1.3));
  }
  cv::Rect hot(w - w / 8, h / 16, w / 16 + 1, h / 16 + 1), black(w / 16, h / 16, w / 16 + 1, h / 16 + 1);
  hot &= cv::Rect(0, 0, w, h);
  black &= cv::Rect(0, 0, w, h);
  e(hot).setTo(cv::Scalar(1e6, 1e6, 1e6));
  e(black).setTo(cv::Scalar(0, 0, 0));
  if (hot_spot) *hot_spot = hot;
  if (black_spot) *black_spot = black;
  return e;
}

// n exposure times, evenly spaced in log, covering radiance from `e_low` (recorded near the
// middle of the range by the longest exposure) to `e_high` (below saturation in the shortest).
inline std::vector<double> ExposuresFor(double e_low, double e_high, int n) {
  const double t_short = 0.3 / e_high, t_long = 0.3 / e_low;
  std::vector<double> t(n);
  for (int j = 0; j < n; ++j) {
    t[j] = t_short * std::pow(t_long / t_short, n == 1 ? 0.0 : double(j) / (n - 1));
  }
  return t;
}

// Renders a bracket: X = E t + noise (shot and read noise, relative to the saturation
// exposure, seeded), through the response, quantised to 8 or 16 bits.
inline Bracket RenderBracket(const cv::Mat& radiance, const std::vector<double>& times,
                             const FilmicResponse& f, uint64_t seed, double shot = 5e-5,
                             double read = 2.5e-4, int depth = CV_8U, int threads = 2) {
  Bracket frames(times.size());
  const double full = depth == CV_16U ? 65535.0 : 255.0;
  ParallelFor(int(times.size()), threads, [&](int b, int e) {
    for (int j = b; j < e; ++j) {
      cv::Mat x = radiance * times[j];
      cv::Mat noise(x.size(), CV_32FC3);
      cv::RNG rng(seed * 7919 + j);
      rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
      cv::Mat out(x.size(), depth == CV_16U ? CV_16UC3 : CV_8UC3);
      for (int y = 0; y < x.rows; ++y) {
        const float* xr = x.ptr<float>(y);
        const float* nr = noise.ptr<float>(y);
        for (int k = 0; k < x.cols * 3; ++k) {
          const double xv = xr[k];
          const double xn = xv + nr[k] * std::sqrt(shot * std::max(xv, 0.0) + read * read);
          const double v = std::clamp(f.Fast(k % 3, xn) * full + 0.5, 0.0, full);
          if (depth == CV_16U) {
            out.ptr<uint16_t>(y)[k] = uint16_t(v);
          } else {
            out.ptr<uint8_t>(y)[k] = uint8_t(v);
          }
        }
      }
      frames[j].image = out;
      frames[j].exposure = Seconds(times[j]);
      frames[j].source = "synthetic_" + std::to_string(j) + ".png";
    }
  });
  return frames;
}

// Radiance percentiles of a CV_32FC3 image over all channels (p in [0, 1]), ignoring zeros.
inline double Percentile(const cv::Mat& radiance, double p) {
  std::vector<float> v;
  v.reserve(radiance.total() * 3);
  for (int y = 0; y < radiance.rows; ++y) {
    const float* r = radiance.ptr<float>(y);
    for (int k = 0; k < radiance.cols * 3; ++k) {
      if (r[k] > 0 && std::isfinite(r[k])) v.push_back(r[k]);
    }
  }
  if (v.empty()) return 0;
  const size_t i = std::min(v.size() - 1, size_t(p * (v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + i, v.end());
  return v[i];
}

// Per channel, log-radiance RMS error of `estimate` against `truth` over pixel-channels that
// some frame records well (a level in [5%, 95%] of the range) and whose truth is positive,
// after removing the mean log offset per channel (radiance is relative: the response is known
// up to one constant per channel). Returns the RMS over all three channels; `count` receives
// the number of pixel-channels used.
inline double LogRmsError(const cv::Mat& estimate, const cv::Mat& truth, const Bracket& frames,
                          size_t* count = nullptr) {
  const double full = frames[0].image.depth() == CV_16U ? 65535.0 : 255.0;
  const double lo = 0.05 * full, hi = 0.95 * full;
  std::array<std::vector<double>, 3> d;
  for (int y = 0; y < truth.rows; ++y) {
    const float* t = truth.ptr<float>(y);
    const float* e = estimate.ptr<float>(y);
    for (int k = 0; k < truth.cols * 3; ++k) {
      if (!(t[k] > 0)) continue;
      bool well = false;
      for (const auto& f : frames) {
        const double z = f.image.depth() == CV_16U ? f.image.ptr<uint16_t>(y)[k]
                                                   : f.image.ptr<uint8_t>(y)[k];
        if (z >= lo && z <= hi) {
          well = true;
          break;
        }
      }
      if (!well) continue;
      // An estimate of 0 or below is an error as large as the data allow: cap at 1e-30.
      d[k % 3].push_back(std::log(std::max<double>(e[k], 1e-30)) - std::log(double(t[k])));
    }
  }
  double sum = 0;
  size_t n = 0;
  for (auto& ch : d) {
    if (ch.empty()) continue;
    double mean = 0;
    for (double v : ch) mean += v;
    mean /= ch.size();
    for (double v : ch) sum += (v - mean) * (v - mean);
    n += ch.size();
  }
  if (count) *count = n;
  return n ? std::sqrt(sum / n) : 0.0;
}

// The largest deviation of a recovered g from the truth over levels [z_lo, z_hi], per channel
// after removing the mean offset over that range; returns the maximum over channels.
template <typename Curve>
double MaxResponseError(const Curve& g, const FilmicResponse& f, int z_lo, int z_hi,
                        int levels = 256) {
  double worst = 0;
  for (int c = 0; c < 3; ++c) {
    double mean = 0;
    for (int z = z_lo; z <= z_hi; ++z) mean += g(c, z) - f.TrueG(c, z, levels);
    mean /= (z_hi - z_lo + 1);
    for (int z = z_lo; z <= z_hi; ++z) {
      worst = std::max(worst, std::abs(g(c, z) - f.TrueG(c, z, levels) - mean));
    }
  }
  return worst;
}

}  // namespace rig::synth
