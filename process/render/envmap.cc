// Environment-map relighting: basis projection for linear harmonic models, importance
// sampling for the others.
#include "process/render/envmap.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include <opencv2/imgproc.hpp>

#include "process/render/radiance_file.h"

namespace rig {
namespace {

constexpr double kWeightB = 0.0722, kWeightG = 0.7152, kWeightR = 0.2126;

// One texel of the working map: direction, R, G, B radiance × solid angle, luminance × solid
// angle, and whether the model answers there.
struct Texel {
  Vec3 dir;
  std::array<double, 3> rgb_sa;
  double lum_sa;
  bool inside;
};

std::vector<Texel> Texels(const ReflectanceModel& model, const cv::Mat& map,
                          const EnvmapOptions& o) {
  const int w = map.cols, h = map.rows;
  std::vector<Texel> texels;
  texels.reserve(static_cast<size_t>(w) * h);
  for (int r = 0; r < h; ++r) {
    const double v = (r + 0.5) / h;
    const double pi = std::numbers::pi;
    const double solid_angle = (2 * pi / w) * (pi / h) * std::cos(pi * (0.5 - v));
    const cv::Vec3f* row = map.ptr<cv::Vec3f>(r);
    for (int c = 0; c < w; ++c) {
      Texel t;
      t.dir = EnvmapDirection((c + 0.5) / w, v, o.rotate_deg);
      const double s = solid_angle * o.intensity;
      t.rgb_sa = {row[c][2] * s, row[c][1] * s, row[c][0] * s};
      t.lum_sa = kWeightR * t.rgb_sa[0] + kWeightG * t.rgb_sa[1] + kWeightB * t.rgb_sa[2];
      t.inside = t.lum_sa <= 0 || o.extrapolate || model.CheckRegion(t.dir).inside;
      texels.push_back(t);
    }
  }
  return texels;
}

// Σ_k c_k · p_k per pixel and channel, times the capture lamp: one pass over the coefficients.
cv::Mat DotWithProjection(const Model& m, const std::vector<std::array<double, 3>>& p) {
  const int terms = m.basis().size();
  const auto& e = m.info().lamp_radiance_rgb;
  std::vector<std::array<float, 3>> wk(terms);  // B, G, R
  for (int k = 0; k < terms; ++k)
    wk[k] = {static_cast<float>(p[k][2] * e[2]), static_cast<float>(p[k][1] * e[1]),
             static_cast<float>(p[k][0] * e[0])};
  cv::Mat out(m.height(), m.width(), CV_32FC3);
  const cv::Mat& valid = m.valid();
  cv::parallel_for_(cv::Range(0, m.height()), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      float* o = out.ptr<float>(y);
      const float* c0 = m.coefficients()[0].ptr<float>(y);
      for (int x = 0; x < m.width(); ++x)
        for (int c = 0; c < 3; ++c) o[3 * x + c] = wk[0][c] * c0[3 * x + c];
      for (int k = 1; k < terms; ++k) {
        const float* ck = m.coefficients()[k].ptr<float>(y);
        const float b = wk[k][0], g = wk[k][1], r = wk[k][2];
        for (int x = 0; x < m.width(); ++x) {
          o[3 * x] += b * ck[3 * x];
          o[3 * x + 1] += g * ck[3 * x + 1];
          o[3 * x + 2] += r * ck[3 * x + 2];
        }
      }
      if (!valid.empty()) {
        const uint8_t* v = valid.ptr<uint8_t>(y);
        for (int x = 0; x < m.width(); ++x)
          if (!v[x]) o[3 * x] = o[3 * x + 1] = o[3 * x + 2] = 0;
      }
    }
  });
  return out;
}

}  // namespace

Vec3 EnvmapDirection(double u, double v, double rotate_deg) {
  const double phi = 2 * std::numbers::pi * (u - 0.5) + rotate_deg * std::numbers::pi / 180;
  const double theta = std::numbers::pi * (0.5 - v);
  return {std::cos(theta) * std::sin(phi), std::sin(theta), std::cos(theta) * std::cos(phi)};
}

Status CheckEnvironmentMap(const cv::Mat& map, const std::string& name) {
  if (map.empty() || map.type() != CV_32FC3) {
    return MakeError(ErrorCode::kInvalidInput, name, "an environment map must be RGB radiance");
  }
  if (map.cols != 2 * map.rows) {
    return MakeError(ErrorCode::kInvalidInput, name,
                     "is {}x{}: a latitude-longitude environment map is twice as wide as high "
                     "(2:1)",
                     map.cols, map.rows);
  }
  for (int r = 0; r < map.rows; ++r) {
    const float* p = map.ptr<float>(r);
    for (int i = 0; i < map.cols * 3; ++i) {
      if (!std::isfinite(p[i])) {
        return MakeError(ErrorCode::kInvalidInput, name,
                         "pixel ({}, {}) is not finite (NaN or Inf): not a usable radiance map",
                         i / 3, r);
      }
      if (p[i] < 0) {
        return MakeError(ErrorCode::kInvalidInput, name,
                         "pixel ({}, {}) is negative ({}): radiance cannot be", i / 3, r, p[i]);
      }
    }
  }
  return Ok();
}

Result<cv::Mat> LoadEnvironmentMap(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(cv::Mat map, ReadRadianceFile(path));
  RIG_TRY(CheckEnvironmentMap(map, path));
  return map;
}

Result<EnvmapRender> RenderEnvironment(const ReflectanceModel& model, const Model* harmonic,
                                       const cv::Mat& full_map, const EnvmapOptions& o) {
  RIG_TRY(CheckEnvironmentMap(full_map, "environment map"));
  if (!(o.intensity >= 0 && std::isfinite(o.intensity)) || o.samples < 1 || o.max_width < 4) {
    return MakeError(ErrorCode::kInvalidInput, "environment map",
                     "intensity must be >= 0, samples >= 1 and max_width >= 4");
  }
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  auto seconds = [](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
  };
  cv::Mat map = full_map;
  if (map.cols > o.max_width) {
    const int w = o.max_width - o.max_width % 2;
    cv::resize(full_map, map, cv::Size(w, w / 2), 0, 0, cv::INTER_AREA);
  }
  EnvmapRender out;
  out.map_width = map.cols;
  out.map_height = map.rows;
  const std::vector<Texel> texels = Texels(model, map, o);
  double total = 0, outside = 0;
  for (const auto& t : texels) {
    total += t.lum_sa;
    if (!t.inside) outside += t.lum_sa;
  }
  out.outside_energy_fraction = total > 0 ? outside / total : 0;

  const bool project = harmonic && !o.force_sampling &&
                       harmonic->info().transform.space == FitSpace::kLinear;
  if (project) {
    const Basis& basis = harmonic->basis();
    std::vector<std::array<double, 3>> p(basis.size(), {0, 0, 0});
    std::vector<double> b(basis.size());
    for (const auto& t : texels) {
      if (!t.inside || t.lum_sa <= 0) continue;
      basis.Eval(t.dir, b.data());
      for (int k = 0; k < basis.size(); ++k)
        for (int c = 0; c < 3; ++c) p[k][c] += b[k] * t.rgb_sa[c];
    }
    const auto t1 = Clock::now();
    out.radiance = DotWithProjection(*harmonic, p);
    out.prepare_s = seconds(t0, t1);
    out.pixels_s = seconds(t1, Clock::now());
    out.projected = true;
    out.terms = basis.size();
    return out;
  }

  // Importance sampling over luminance × solid angle, inside the region.
  std::vector<double> cdf;
  std::vector<size_t> index;
  double sum = 0;
  for (size_t i = 0; i < texels.size(); ++i) {
    if (!texels[i].inside || texels[i].lum_sa <= 0) continue;
    sum += texels[i].lum_sa;
    cdf.push_back(sum);
    index.push_back(i);
  }
  out.samples = o.samples;
  if (cdf.empty()) {
    out.radiance = cv::Mat::zeros(model.height(), model.width(), CV_32FC3);
    return out;
  }
  std::mt19937_64 gen(o.seed);
  std::map<size_t, int> drawn;
  for (int s = 0; s < o.samples; ++s) {
    const double u = static_cast<double>(gen() >> 11) * 0x1.0p-53 * sum;
    const size_t k = std::min(cdf.size() - 1, static_cast<size_t>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin()));
    ++drawn[index[k]];
  }
  const auto t1 = Clock::now();
  cv::Mat radiance;
  for (const auto& [i, count] : drawn) {
    const Texel& t = texels[i];
    // Each draw stands for sum / N of luminance × solid angle, in this texel's colour.
    const double f = sum / t.lum_sa * count / o.samples;
    model.AddLamp(t.dir, {t.rgb_sa[0] * f, t.rgb_sa[1] * f, t.rgb_sa[2] * f}, &radiance);
  }
  out.radiance = radiance;
  out.prepare_s = seconds(t0, t1);
  out.pixels_s = seconds(t1, Clock::now());
  out.distinct_lamps = static_cast<int>(drawn.size());
  return out;
}

}  // namespace rig
