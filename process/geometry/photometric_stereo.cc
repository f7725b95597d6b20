// Photometric stereo: plain and robust per-pixel solves, light refinement, integration, files.
#include "process/geometry/photometric_stereo.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>

#include <Eigen/Dense>
#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"
#include "process/io/image_io.h"
#include "process/model/harmonic/fit.h"

namespace rig {
namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;

struct Sample {
  double i;       // grey
  Eigen::Vector3d s;  // falloff * direction
  int k;
};

// The weighted normal equations of I = g.s over the samples of positive weight: A = Σ w s sᵀ,
// b = Σ w I s; returns how many samples took part.
int NormalEquations(const std::vector<Sample>& smp, const std::vector<double>& w,
                    Eigen::Matrix3d* a, Eigen::Vector3d* b) {
  *a = Eigen::Matrix3d::Zero();
  *b = Eigen::Vector3d::Zero();
  int n = 0;
  for (size_t k = 0; k < smp.size(); ++k) {
    if (w[k] <= 0) continue;
    *a += w[k] * smp[k].s * smp[k].s.transpose();
    *b += w[k] * smp[k].i * smp[k].s;
    ++n;
  }
  return n;
}

// Weighted LS for g in I = g.s; false if singular.
bool Solve(const std::vector<Sample>& smp, const std::vector<double>& w, Eigen::Vector3d* g) {
  Eigen::Matrix3d a;
  Eigen::Vector3d b;
  if (NormalEquations(smp, w, &a, &b) < 3) return false;
  Eigen::LDLT<Eigen::Matrix3d> ldlt(a);
  if (ldlt.info() != Eigen::Success) return false;
  // A nearly rank-deficient set (all lights in one plane) gives no normal.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(a);
  if (es.eigenvalues()(0) <= 1e-6 * es.eigenvalues()(2)) return false;
  *g = ldlt.solve(b);
  return g->allFinite() && g->norm() > 0;
}

double MedianOf(std::vector<double> v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Tukey's biweight IRLS from g; returns the final weights.
void Irls(const std::vector<Sample>& smp, int iterations, Eigen::Vector3d* g,
          std::vector<double>* w) {
  for (int it = 0; it < iterations; ++it) {
    std::vector<double> r(smp.size()), absr;
    for (size_t k = 0; k < smp.size(); ++k) {
      const double p = g->dot(smp[k].s);
      r[k] = smp[k].i - p;
      if (p > 0) absr.push_back(std::abs(r[k]));
    }
    const double sigma = std::max(1.4826 * MedianOf(absr), 1e-3 * g->norm() + 1e-12);
    const double c = 4.685 * sigma;
    std::vector<double> nw(smp.size(), 0);
    for (size_t k = 0; k < smp.size(); ++k) {
      if (g->dot(smp[k].s) <= 0) continue;  // attached shadow once the normal is known
      const double u = r[k] / c;
      if (std::abs(u) < 1) nw[k] = (1 - u * u) * (1 - u * u);
    }
    Eigen::Vector3d next;
    if (!Solve(smp, nw, &next)) break;
    *g = next;
    *w = std::move(nw);
  }
}

}  // namespace

Result<PsResult> PhotometricStereo(const LightStack& stack, const std::vector<Vec3>& directions,
                                   const PsOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const int n = static_cast<int>(stack.size());
  if (n < 3 || static_cast<int>(directions.size()) != n)
    return MakeError(ErrorCode::kInvalidInput, "(photometric stereo)",
                     "needs at least 3 images with one direction each ({} images, {} directions)",
                     n, directions.size());
  std::vector<cv::Mat> grey;
  for (const auto& m : stack.linear) grey.push_back(LinearGrey(m));
  const int w = stack.width, h = stack.height;
  PsResult out;
  out.normals = cv::Mat(h, w, CV_32FC3, cv::Scalar(0, 0, 0));
  out.albedo = cv::Mat(h, w, CV_32FC3, cv::Scalar(0, 0, 0));
  out.valid = cv::Mat(h, w, CV_8UC1, cv::Scalar(0));
  out.inliers = cv::Mat(h, w, CV_16UC1, cv::Scalar(0));
  ParallelFor(h, o.threads, [&](int r0, int r1) {
    std::vector<Sample> smp;
    smp.reserve(n);
    for (int y = r0; y < r1; ++y)
      for (int x = 0; x < w; ++x) {
        smp.clear();
        double imax = 0;
        for (int k = 0; k < n; ++k) imax = std::max(imax, static_cast<double>(grey[k].at<float>(y, x)));
        if (imax <= 0) continue;
        for (int k = 0; k < n; ++k) {
          if (!stack.clipped.empty() && stack.clipped[k].at<uint8_t>(y, x)) continue;
          const double v = grey[k].at<float>(y, x);
          if (v < o.dark_fraction * imax) continue;  // shadow (cast or attached)
          double f = 1;
          const Vec3 l = o.lamp.At(x, y, w, h, directions[k], &f);
          smp.push_back({v, Eigen::Vector3d(l[0] * f, l[1] * f, l[2] * f), k});
        }
        if (smp.size() < 3) continue;
        Eigen::Vector3d g;
        std::vector<double> wt(smp.size(), 1.0);
        if (o.robust) {
          // Start from the middle of the sorted samples: neither the highlight nor the
          // shadows.
          std::vector<double> sorted;
          for (const auto& s : smp) sorted.push_back(s.i);
          std::sort(sorted.begin(), sorted.end());
          const size_t m = sorted.size();
          size_t lo = static_cast<size_t>(o.trim_low * m), hi = m - static_cast<size_t>(o.trim_high * m);
          if (hi <= lo + 3) lo = 0, hi = m;
          const double vlo = sorted[lo], vhi = sorted[hi - 1];
          std::vector<double> w0(m);
          for (size_t k = 0; k < m; ++k) w0[k] = (smp[k].i >= vlo && smp[k].i <= vhi) ? 1 : 0;
          if (!Solve(smp, w0, &g) && !Solve(smp, wt, &g)) continue;
          Irls(smp, o.iterations, &g, &wt);
        } else if (!Solve(smp, wt, &g)) {
          continue;
        }
        const Eigen::Vector3d nn = g.normalized();
        // Albedo per channel over the samples kept.
        double num[3] = {0, 0, 0}, den = 0;
        int used = 0;
        for (size_t k = 0; k < smp.size(); ++k) {
          const double sn = nn.dot(smp[k].s);
          if (wt[k] <= 0 || sn <= 0) continue;
          const float* px = stack.linear[smp[k].k].ptr<float>(y) + 3 * x;
          for (int c = 0; c < 3; ++c) num[c] += wt[k] * px[c] * sn;
          den += wt[k] * sn * sn;
          ++used;
        }
        if (den <= 0) continue;
        float* np = out.normals.ptr<float>(y) + 3 * x;
        float* ap = out.albedo.ptr<float>(y) + 3 * x;
        for (int c = 0; c < 3; ++c) {
          np[c] = static_cast<float>(nn(c));
          ap[c] = static_cast<float>(num[c] / den);
        }
        out.valid.at<uint8_t>(y, x) = 1;
        out.inliers.at<uint16_t>(y, x) = static_cast<uint16_t>(used);
      }
  });
  out.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

Vec3 EstimateLight(const cv::Mat& linear_bgr, const cv::Mat& clipped, const PsResult& ps,
                   const Vec3& start) {
  const cv::Mat grey = LinearGrey(linear_bgr);
  // Samples: pixels with a normal, not clipped, lit (N.L > 0.2 at the start) and not dark.
  std::vector<Sample> smp;
  double gmax = 0;
  for (int y = 0; y < grey.rows; ++y)
    for (int x = 0; x < grey.cols; ++x) gmax = std::max(gmax, static_cast<double>(grey.at<float>(y, x)));
  const Eigen::Vector3d l0(start[0], start[1], start[2]);
  for (int y = 0; y < grey.rows; y += 2)
    for (int x = 0; x < grey.cols; x += 2) {
      if (!ps.valid.at<uint8_t>(y, x)) continue;
      if (!clipped.empty() && clipped.at<uint8_t>(y, x)) continue;
      const float* n = ps.normals.ptr<float>(y) + 3 * x;
      const float* a = ps.albedo.ptr<float>(y) + 3 * x;
      const double rho = 0.0722 * a[0] + 0.7152 * a[1] + 0.2126 * a[2];
      const Eigen::Vector3d nv(n[0], n[1], n[2]);
      if (rho <= 0 || nv.dot(l0) < 0.2) continue;
      const double v = grey.at<float>(y, x);
      if (v < 0.02 * gmax) continue;
      smp.push_back({v, rho * nv, 0});
    }
  // A flat object's normals all point one way: the light's components across them are not
  // determined by the data. Damped least squares keeps those at the start direction (scaled
  // by the intensity along it) and moves only what the normals' spread determines.
  std::vector<double> w(smp.size(), 1.0);
  Eigen::Vector3d g = l0;
  for (int it = 0; it < 5; ++it) {
    Eigen::Matrix3d a;
    Eigen::Vector3d b;
    if (NormalEquations(smp, w, &a, &b) < 10) return start;
    const double c = l0.dot(b) / std::max(l0.dot(a * l0), 1e-30);
    const double mu = 0.05 * a.trace() / 3;
    g = (a + mu * Eigen::Matrix3d::Identity()).ldlt().solve(b + mu * c * l0);
    if (!g.allFinite() || g.norm() <= 0) return start;
    // Tukey weights on the residuals for the next pass.
    std::vector<double> absr;
    for (const auto& sm : smp) absr.push_back(std::abs(sm.i - g.dot(sm.s)));
    const double sigma = std::max(1.4826 * MedianOf(absr), 1e-12);
    for (size_t k = 0; k < smp.size(); ++k) {
      const double u = (smp[k].i - g.dot(smp[k].s)) / (4.685 * sigma);
      w[k] = std::abs(u) < 1 ? (1 - u * u) * (1 - u * u) : 0;
    }
  }
  const Eigen::Vector3d d = g.normalized();
  return {d(0), d(1), d(2)};
}

std::vector<Vec3> RefineLightsFromImages(const LightStack& stack, const std::vector<Vec3>& start,
                                         int rounds, const PsOptions& options) {
  std::vector<Vec3> dirs = start;
  for (int r = 0; r < rounds; ++r) {
    auto ps = PhotometricStereo(stack, dirs, options);
    if (!ps.ok()) break;
    std::vector<Vec3> next(dirs.size());
    ParallelFor(static_cast<int>(dirs.size()), options.threads, [&](int b, int e) {
      for (int k = b; k < e; ++k)
        next[k] = EstimateLight(stack.linear[k], stack.clipped.empty() ? cv::Mat() : stack.clipped[k],
                                *ps, dirs[k]);
    });
    dirs = std::move(next);
  }
  return dirs;
}

cv::Mat IntegrateNormals(const cv::Mat& normals) {
  const int h = normals.rows, w = normals.cols;
  cv::Mat p(h, w, CV_32FC1), q(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float* n = normals.ptr<float>(y) + 3 * x;
      const float nz = std::max(n[2], 0.05f);
      p.at<float>(y, x) = n[2] > 0 ? -n[0] / nz : 0;  // dz/dx (x to the right)
      q.at<float>(y, x) = n[2] > 0 ? n[1] / nz : 0;   // dz/d(row): rows run down, y up
    }
  cv::Mat pf, qf;
  cv::dft(p, pf, cv::DFT_COMPLEX_OUTPUT);
  cv::dft(q, qf, cv::DFT_COMPLEX_OUTPUT);
  cv::Mat zf(h, w, CV_32FC2);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const double wx = 2 * std::numbers::pi * (u < w / 2 ? u : u - w) / w;
      const double wy = 2 * std::numbers::pi * (v < h / 2 ? v : v - h) / h;
      const double d = wx * wx + wy * wy;
      const cv::Vec2f a = pf.at<cv::Vec2f>(v, u), b = qf.at<cv::Vec2f>(v, u);
      if (d == 0) {
        zf.at<cv::Vec2f>(v, u) = {0, 0};
        continue;
      }
      // Z = (-i wx P - i wy Q) / d; -i (re + i im) = im - i re.
      const double re = (wx * a[1] + wy * b[1]) / d, im = -(wx * a[0] + wy * b[0]) / d;
      zf.at<cv::Vec2f>(v, u) = {static_cast<float>(re), static_cast<float>(im)};
    }
  cv::Mat z;
  cv::dft(zf, z, cv::DFT_INVERSE | cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  z -= cv::mean(z)[0];
  return z;
}

namespace {
cv::Mat NormalsPng(const PsResult& ps) {
  cv::Mat out(ps.normals.rows, ps.normals.cols, CV_8UC3);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      const float* n = ps.normals.ptr<float>(y) + 3 * x;
      uint8_t* o = out.ptr<uint8_t>(y) + 3 * x;
      const bool ok = ps.valid.at<uint8_t>(y, x) != 0;
      for (int c = 0; c < 3; ++c)  // B = z, G = y, R = x
        o[c] = ok ? static_cast<uint8_t>(std::lround(255 * std::clamp(n[2 - c] * 0.5f + 0.5f, 0.f, 1.f))) : 0;
    }
  return out;
}
cv::Mat AlbedoPng(const PsResult& ps) {
  std::vector<float> v;
  for (int y = 0; y < ps.albedo.rows; ++y)
    for (int x = 0; x < ps.albedo.cols; ++x)
      if (ps.valid.at<uint8_t>(y, x)) {
        const float* a = ps.albedo.ptr<float>(y) + 3 * x;
        v.push_back(std::max({a[0], a[1], a[2]}));
      }
  float scale = 1;
  if (!v.empty()) {
    auto it = v.begin() + static_cast<long>(0.995 * (v.size() - 1));
    std::nth_element(v.begin(), it, v.end());
    if (*it > 0) scale = 1 / *it;
  }
  cv::Mat out(ps.albedo.rows, ps.albedo.cols, CV_8UC3);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      const float* a = ps.albedo.ptr<float>(y) + 3 * x;
      uint8_t* o = out.ptr<uint8_t>(y) + 3 * x;
      for (int c = 0; c < 3; ++c)
        o[c] = static_cast<uint8_t>(std::lround(255 * SrgbEncode(std::clamp(a[c] * scale, 0.f, 1.f))));
    }
  return out;
}
Status WritePng(const std::string& path, const cv::Mat& img) {
  try {
    RIG_TRY(WriteImageFile(path, img));
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kIo, path, "cannot write the PNG: {}", e.what());
  }
  return {};
}
std::string Stem(const std::string& path) {
  const auto dot = path.rfind('.');
  const auto slash = path.rfind('/');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return path;
  return path.substr(0, dot);
}
}  // namespace

Status WriteNormalPictures(const PsResult& ps, const std::string& normals_png,
                           const std::string& albedo_png) {
  RIG_TRY(WritePng(normals_png, NormalsPng(ps)));
  return WritePng(albedo_png, AlbedoPng(ps));
}

Result<std::vector<std::string>> WriteNormalsAndAlbedo(const PsResult& ps,
                                                       const std::string& normals_exr) {
  const std::string stem = Stem(normals_exr);
  ExrImage img;
  img.width = ps.normals.cols;
  img.height = ps.normals.rows;
  img.channel_names = {"R", "G", "B"};
  std::vector<cv::Mat> planes;
  cv::split(ps.normals, planes);
  img.channels = {planes[0], planes[1], planes[2]};  // R = x, G = y, B = z
  img.attributes = {{"content", "surface normals by photometric stereo"},
                    {"axes", "R = x right, G = y up, B = z towards the camera; (0,0,0): none"}};
  RIG_TRY(WriteExr(normals_exr, img, ExrPixelType::kFloat));
  std::vector<std::string> paths = {normals_exr, stem + ".png", stem + "-albedo.exr",
                                    stem + "-albedo.png"};
  RIG_TRY(WritePng(paths[1], NormalsPng(ps)));
  RIG_TRY(WriteRgbExr(paths[2], ps.albedo,
                      {{"content", "albedo by photometric stereo: I / (N.L), linear"}}));
  RIG_TRY(WritePng(paths[3], AlbedoPng(ps)));
  return paths;
}

AngularError NormalError(const cv::Mat& normals, const cv::Mat& truth, const cv::Mat& mask) {
  std::vector<double> e;
  for (int y = 0; y < normals.rows; ++y)
    for (int x = 0; x < normals.cols; ++x) {
      if (!mask.at<uint8_t>(y, x)) continue;
      const float* a = normals.ptr<float>(y) + 3 * x;
      const float* b = truth.ptr<float>(y) + 3 * x;
      const double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
      const double na = std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
      e.push_back(na > 0 ? std::acos(std::clamp(d / na, -1.0, 1.0)) * kDeg : 180.0);
    }
  AngularError r;
  r.pixels = e.size();
  if (e.empty()) return r;
  double s = 0;
  for (double v : e) s += v;
  r.mean_deg = s / e.size();
  std::sort(e.begin(), e.end());
  r.median_deg = e[e.size() / 2];
  r.p95_deg = e[static_cast<size_t>(0.95 * (e.size() - 1))];
  return r;
}

Status WriteHeightMap(const cv::Mat& normals, const std::string& exr) {
  cv::Mat z = IntegrateNormals(normals);
  ExrImage img;
  img.width = z.cols;
  img.height = z.rows;
  img.channel_names = {"Y"};
  img.channels = {z};
  img.attributes = {{"content", "height from normals (Frankot-Chellappa), pixels, mean 0"}};
  return WriteExr(exr, img);
}

Result<NearLamp> PlaceLamp(const LampPlacement& placement, const LightFrameConfig* session,
                           int image_height) {
  LampPlacement p = placement;
  if (session && !p.far && p.lamp_distance_mm < 0) {
    p.lamp_distance_mm = session->lamp_distance_mm;
    if (p.field_height_mm <= 0) p.field_height_mm = session->field_height_mm;
    if (std::isnan(p.surface_depth_mm)) p.surface_depth_mm = session->surface_depth_mm;
  }
  NearLamp lamp;
  if (p.lamp_distance_mm <= 0 || p.far) return lamp;
  if (p.field_height_mm <= 0)
    return MakeError(ErrorCode::kInvalidInput, "--field-height-mm", "a near lamp needs the field's height");
  lamp.distance_mm = p.lamp_distance_mm;
  lamp.mm_per_px = p.field_height_mm / image_height;
  lamp.plane_z_mm = std::isnan(p.surface_depth_mm) ? 0.0 : p.surface_depth_mm;
  if (!std::isfinite(lamp.plane_z_mm) ||
      (lamp.plane_z_mm != 0 && std::abs(lamp.plane_z_mm) + p.field_height_mm >= p.lamp_distance_mm)) {
    return MakeError(ErrorCode::kInvalidInput, fmt::format("--surface-depth-mm {:g}", lamp.plane_z_mm),
                     "|surface depth| + the field's height must stay below the lamp's distance "
                     "({:g} mm)", p.lamp_distance_mm);
  }
  return lamp;
}

}  // namespace rig
