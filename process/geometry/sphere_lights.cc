// Chrome-sphere light calibration: circles, highlights, directions, the light frame.
#include "process/geometry/sphere_lights.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDegPerRadian = 180.0 / kPi;

Vec3 Normalize(const Vec3& v) {
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  return n > 0 ? Vec3{v[0] / n, v[1] / n, v[2] / n} : Vec3{0, 0, 0};
}
double Dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

double Median(std::vector<float> v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + v.size() / 2;
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Bilinear sample of a CV_32FC1 image at continuous coordinates (u, v) (pixel centres at
// i + 0.5); clamps at the border.
double SampleBilinear(const cv::Mat& img, double u, double v) {
  double x = u - 0.5, y = v - 0.5;
  x = std::clamp(x, 0.0, img.cols - 1.001);
  y = std::clamp(y, 0.0, img.rows - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double tx = x - x0, ty = y - y0;
  const float* r0 = img.ptr<float>(y0);
  const float* r1 = img.ptr<float>(std::min(y0 + 1, img.rows - 1));
  const int x1 = std::min(x0 + 1, img.cols - 1);
  return (r0[x0] * (1 - tx) + r0[x1] * tx) * (1 - ty) + (r1[x0] * (1 - tx) + r1[x1] * tx) * ty;
}

// The view geometry of one sphere: normal and view direction at an image point.
struct SphereView {
  SphereCircle c;
  CameraModel cam;
  double width = 0, height = 0;
  Vec3 center{};  // perspective: the sphere's centre, radius 1, camera at the origin

  void Init() {
    if (!cam.perspective()) return;
    const Vec3 d = Ray(c.cx, c.cy);
    const double alpha = std::atan(c.r / cam.focal_px);
    const double dist = 1.0 / std::sin(alpha);
    center = {d[0] * dist, d[1] * dist, d[2] * dist};
  }
  // Unit ray from the camera through image point (u, v) (object frame: camera looks down -z).
  Vec3 Ray(double u, double v) const {
    return Normalize({(u - width / 2) / cam.focal_px, -(v - height / 2) / cam.focal_px, -1.0});
  }
  // false when the point does not see the sphere.
  bool At(double u, double v, Vec3* n, Vec3* view) const {
    if (!cam.perspective()) {
      const double dx = (u - c.cx) / c.r, dy = -(v - c.cy) / c.r;
      const double rr = 1 - dx * dx - dy * dy;
      if (rr <= 0) return false;
      *n = {dx, dy, std::sqrt(rr)};
      *view = {0, 0, 1};
      return true;
    }
    const Vec3 d = Ray(u, v);
    const double b = Dot(d, center);
    const double disc = b * b - Dot(center, center) + 1.0;
    if (disc <= 0) return false;
    const double t = b - std::sqrt(disc);
    *n = Normalize({t * d[0] - center[0], t * d[1] - center[1], t * d[2] - center[2]});
    *view = {-d[0], -d[1], -d[2]};
    return true;
  }
};

Vec3 Reflect(const Vec3& n, const Vec3& v) {
  const double nv = Dot(n, v);
  return Normalize({2 * nv * n[0] - v[0], 2 * nv * n[1] - v[1], 2 * nv * n[2] - v[2]});
}

// Algebraic (Kasa) circle fit, then refits without points beyond 3 robust sigmas.
bool FitCircle(const std::vector<cv::Point2d>& pts, SphereCircle* out) {
  std::vector<cv::Point2d> use = pts;
  for (int iter = 0; iter < 3; ++iter) {
    if (use.size() < 12) return false;
    Eigen::MatrixXd a(use.size(), 3);
    Eigen::VectorXd b(use.size());
    for (size_t i = 0; i < use.size(); ++i) {
      a(i, 0) = use[i].x;
      a(i, 1) = use[i].y;
      a(i, 2) = 1;
      b(i) = use[i].x * use[i].x + use[i].y * use[i].y;
    }
    Eigen::Vector3d s = a.colPivHouseholderQr().solve(b);
    const double cx = s(0) / 2, cy = s(1) / 2;
    const double r2 = s(2) + cx * cx + cy * cy;
    if (r2 <= 0) return false;
    *out = {cx, cy, std::sqrt(r2)};
    std::vector<float> res;
    for (const auto& p : pts) res.push_back(static_cast<float>(std::abs(std::hypot(p.x - cx, p.y - cy) - out->r)));
    const double sigma = std::max(0.05, 1.4826 * Median(res));
    std::vector<cv::Point2d> next;
    for (size_t i = 0; i < pts.size(); ++i)
      if (res[i] <= 3 * sigma) next.push_back(pts[i]);
    if (next.size() == use.size()) break;
    use = std::move(next);
  }
  return true;
}

}  // namespace

std::string CameraModel::Describe() const {
  const std::string what =
      perspective() ? fmt::format("perspective, focal length {:.1f} px, principal point at the "
                                  "image centre", focal_px)
                    : "orthographic (view direction +z at every pixel)";
  return source.empty() ? what : what + "; " + source;
}

double AngleDeg(const Vec3& a, const Vec3& b) {
  const Vec3 x = Normalize(a), y = Normalize(b);
  const Vec3 c = {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
  return std::atan2(std::sqrt(Dot(c, c)), Dot(x, y)) * kDegPerRadian;
}

cv::Mat MedianGrey(const LightStack& stack) {
  std::vector<cv::Mat> greys;
  for (const auto& m : stack.linear) greys.push_back(LinearGrey(m));
  cv::Mat out(stack.height, stack.width, CV_32FC1);
  std::vector<float> v(greys.size());
  for (int y = 0; y < stack.height; ++y)
    for (int x = 0; x < stack.width; ++x) {
      for (size_t k = 0; k < greys.size(); ++k) v[k] = greys[k].at<float>(y, x);
      auto mid = v.begin() + v.size() / 2;
      std::nth_element(v.begin(), mid, v.end());
      out.at<float>(y, x) = *mid;
    }
  return out;
}

namespace {
cv::Mat LogImage(const cv::Mat& grey) {
  cv::Mat sorted = grey.reshape(1, 1).clone();
  cv::sort(sorted, sorted, cv::SORT_ASCENDING);
  const float hi = sorted.at<float>(0, static_cast<int>(sorted.cols * 0.99));
  const float eps = std::max(1e-6f, hi * 1e-3f);
  cv::Mat lg;
  cv::max(grey, 0.0, lg);
  lg += eps;
  cv::log(lg, lg);
  return lg;
}
}  // namespace

namespace {
SphereCircle RefineOnce(const cv::Mat& lg, const cv::Mat& lin, const SphereCircle& rough) {
  std::vector<cv::Point2d> pts;
  std::vector<float> strengths;
  const int rays = 360;
  const double step = 0.25;
  for (int a = 0; a < rays; ++a) {
    const double th = 2 * kPi * a / rays, ca = std::cos(th), sa = std::sin(th);
    std::vector<double> prof;
    const double r0 = rough.r * 0.75, r1 = rough.r * 1.25 + 2;
    for (double r = r0; r <= r1; r += step)
      prof.push_back(SampleBilinear(lg, rough.cx + r * ca, rough.cy + r * sa));
    std::vector<double> d(prof.size(), 0);
    for (size_t i = 1; i + 1 < prof.size(); ++i) d[i] = std::abs(prof[i + 1] - prof[i - 1]);
    // The sphere's edge is the innermost strong edge of the ray (at least half its steepest):
    // the background's own edges (a checker, a shadow's border) lie outside it, and one of
    // them can be the steeper in the log when the limb's dark level sits on a noise floor
    // (a merged radiance map's darkest pixels are lifted by the noise; the median keeps that).
    double dmax = 0;
    for (size_t i = 1; i + 1 < d.size(); ++i) dmax = std::max(dmax, d[i]);
    if (dmax <= 0) continue;
    size_t bi = 0;
    for (size_t i = 1; i + 1 < d.size(); ++i)
      if (d[i] >= 0.5 * dmax && d[i] >= d[i - 1] && d[i] >= d[i + 1]) {
        bi = i;
        break;
      }
    if (bi == 0) continue;
    const double best = d[bi];
    const double coarse = r0 + bi * step;
    // The edge's position: where the linear profile crosses halfway between its levels on
    // either side of this edge (the steepest point of the log profile is only the coarse
    // guess: in a log image a blurred step's steepest point moves towards the dark side).
    // The levels are read where the linear profile's slope, walking away from the edge's
    // steepest point, has fallen to a fifth of it: just outside the edge's own transition and
    // before the next edge (a background edge 2 px further must not set the outer level). A
    // symmetric blur gives symmetric walks, so the halfway crossing is the edge's position.
    auto at = [&](double r) { return SampleBilinear(lin, rough.cx + r * ca, rough.cy + r * sa); };
    const double fine = 0.125;
    auto slope = [&](double r) { return std::abs(at(r + 2 * fine) - at(r - 2 * fine)); };
    double peak_r = coarse, peak = -1;
    for (double r = coarse - 1; r <= coarse + 1 + 1e-9; r += fine) {
      const double s = slope(r);
      if (s > peak) peak = s, peak_r = r;
    }
    if (!(peak > 0)) continue;
    // The halfway crossing is the edge's position only for an isolated step between two
    // flat levels. A ray where another edge follows within the blur of this one (the slope
    // rises again before it has fallen, or within as far again after) is left out: there the
    // crossing is pulled towards the other edge, by up to a pixel when it is 10x stronger.
    const double max_walk = 4;
    auto walk = [&](double dir, double* end) {
      double r = peak_r, lowest = peak;
      while (std::abs(r - peak_r) < max_walk) {
        const double s = slope(r);
        if (s > lowest + 0.1 * peak) return false;
        lowest = std::min(lowest, s);
        if (s <= 0.2 * peak) break;
        r += dir * fine;
      }
      if (std::abs(r - peak_r) >= max_walk) return false;
      *end = r;
      const double margin = std::max(0.5, std::abs(r - peak_r));
      for (double q = r; std::abs(q - r) <= margin; q += dir * fine)
        if (slope(q) > 0.3 * peak) return false;
      return true;
    };
    double r_in = peak_r, r_out = peak_r;
    if (!walk(-1, &r_in) || !walk(+1, &r_out)) continue;
    const double mid = 0.5 * (at(r_in) + at(r_out));
    double found = -1, prev = at(r_in);
    for (double r = r_in + fine; r <= r_out + 1e-9; r += fine) {
      const double cur = at(r);
      if ((prev - mid) * (cur - mid) <= 0 && prev != cur) {
        const double cand = r - fine + (mid - prev) / (cur - prev) * fine;
        if (found < 0 || std::abs(cand - peak_r) < std::abs(found - peak_r)) found = cand;
      }
      prev = cur;
    }
    if (found <= 0) continue;
    pts.push_back({rough.cx + found * ca, rough.cy + found * sa});
    strengths.push_back(static_cast<float>(best));
  }
  // Only the clear edge points: where the sphere meets a background of another brightness.
  const double med = Median(strengths);
  std::vector<cv::Point2d> strong;
  for (size_t i = 0; i < pts.size(); ++i)
    if (strengths[i] >= 0.7 * med && strengths[i] > 0.05) strong.push_back(pts[i]);
  SphereCircle out;
  if (!FitCircle(strong, &out)) return rough;
  if (std::hypot(out.cx - rough.cx, out.cy - rough.cy) > 0.3 * rough.r ||
      std::abs(out.r - rough.r) > 0.3 * rough.r)
    return rough;
  return out;
}
}  // namespace

SphereCircle RefineCircle(const cv::Mat& median_grey, const SphereCircle& rough) {
  // A few passes: the rays of each start from the centre found by the last. The edge is
  // found in the linear image, normalised: the steepest point of a blurred step lies at its
  // middle there (in a log image it moves towards the dark side, by the contrast's side).
  const cv::Mat lg = LogImage(median_grey);
  cv::Mat lin;
  cv::max(median_grey, 0.0, lin);
  SphereCircle c = rough;
  for (int pass = 0; pass < 4; ++pass) {
    const SphereCircle next = RefineOnce(lg, lin, c);
    const double moved = std::hypot(next.cx - c.cx, next.cy - c.cy) + std::abs(next.r - c.r);
    c = next;
    if (moved < 0.01) break;
  }
  return c;
}

namespace {

// The pixels inside 97% of the sphere's radius: their mask, grey values and the brightest.
struct DiscSamples {
  cv::Mat inside;  // CV_8UC1
  std::vector<float> values;
  float peak = -1;
  int px = -1, py = -1;
};

DiscSamples SampleDisc(const cv::Mat& grey, const SphereCircle& sphere) {
  DiscSamples d;
  const int x0 = std::max(0, static_cast<int>(sphere.cx - sphere.r));
  const int x1 = std::min(grey.cols - 1, static_cast<int>(sphere.cx + sphere.r));
  const int y0 = std::max(0, static_cast<int>(sphere.cy - sphere.r));
  const int y1 = std::min(grey.rows - 1, static_cast<int>(sphere.cy + sphere.r));
  const double rin = 0.97 * sphere.r;
  d.inside = cv::Mat(grey.rows, grey.cols, CV_8UC1, cv::Scalar(0));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) {
      if (std::hypot(x + 0.5 - sphere.cx, y + 0.5 - sphere.cy) > rin) continue;
      d.inside.at<uint8_t>(y, x) = 1;
      const float g = grey.at<float>(y, x);
      d.values.push_back(g);
      if (g > d.peak) d.peak = g, d.px = x, d.py = y;
    }
  return d;
}

// The blob at or above `half` around the peak (8-connected, inside the disc): its size in
// pixels, and whether any of it is clipped.
std::pair<int, bool> HalfMaximumBlob(const cv::Mat& grey, const DiscSamples& d, const cv::Mat* clip,
                                     double half) {
  std::vector<cv::Point> todo = {{d.px, d.py}};
  cv::Mat seen(grey.rows, grey.cols, CV_8UC1, cv::Scalar(0));
  seen.at<uint8_t>(d.py, d.px) = 1;
  int blob = 0;
  bool saturated = false;
  while (!todo.empty()) {
    cv::Point p = todo.back();
    todo.pop_back();
    ++blob;
    if (clip && clip->at<uint8_t>(p.y, p.x)) saturated = true;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int x = p.x + dx, y = p.y + dy;
        if (x < 0 || y < 0 || x >= grey.cols || y >= grey.rows) continue;
        if (seen.at<uint8_t>(y, x) || !d.inside.at<uint8_t>(y, x)) continue;
        if (grey.at<float>(y, x) < half) continue;
        seen.at<uint8_t>(y, x) = 1;
        todo.push_back({x, y});
      }
  }
  return {blob, saturated};
}

// Weighted mean normal over the lobe, three times from the peak's reflection `l`. Per pixel the
// weight is the lobe's value above the sphere's median `bg`, divided by N.L (the lobe is
// symmetric about the half vector only before the cosine) and by N.V (pixels to solid angle);
// cut at 5% of the peak. Sets h's position and normal; returns the light direction.
Vec3 LobeDirection(const cv::Mat& grey, const DiscSamples& d, const SphereView& view, double bg,
                   double rw, Vec3 l, Highlight* h) {
  const int px = d.px, py = d.py;
  for (int iter = 0; iter < 3; ++iter) {
    struct Px { Vec3 n, v; double g; double u, w; };
    std::vector<Px> pxs;
    double gmax = 0;
    for (int y = std::max(0, static_cast<int>(py - rw)); y <= std::min(grey.rows - 1, static_cast<int>(py + rw)); ++y)
      for (int x = std::max(0, static_cast<int>(px - rw)); x <= std::min(grey.cols - 1, static_cast<int>(px + rw)); ++x) {
        if (!d.inside.at<uint8_t>(y, x)) continue;
        if (std::hypot(x - px, y - py) > rw) continue;
        Vec3 n, v;
        if (!view.At(x + 0.5, y + 0.5, &n, &v)) continue;
        const double nl = std::max(Dot(n, l), 0.05), nv = std::max(Dot(n, v), 0.05);
        const double g = (grey.at<float>(y, x) - bg) / nl;
        pxs.push_back({n, v, g / nv, x + 0.5, static_cast<double>(y) + 0.5});
        gmax = std::max(gmax, g);
      }
    const double cut = 0.05 * gmax;
    Vec3 sn = {0, 0, 0}, sv = {0, 0, 0};
    double su = 0, sw = 0, wsum = 0;
    for (const auto& p : pxs) {
      const double w = p.g - cut / 1.0;
      if (w <= 0) continue;
      for (int c = 0; c < 3; ++c) sn[c] += w * p.n[c], sv[c] += w * p.v[c];
      su += w * p.u;
      sw += w * p.w;
      wsum += w;
    }
    if (wsum <= 0) break;
    const Vec3 n = Normalize(sn), v = Normalize(sv);
    l = Reflect(n, v);
    h->x = su / wsum;
    h->y = sw / wsum;
    h->normal = n;
  }
  return l;
}

}  // namespace

Result<Highlight> LocateHighlight(const LightStack& stack, size_t k, const SphereCircle& sphere,
                                  const CameraModel& camera, const HighlightOptions& options) {
  const std::string& name = stack.names[k];
  const cv::Mat grey = LinearGrey(stack.linear[k]);
  const cv::Mat* clip = stack.clipped.empty() ? nullptr : &stack.clipped[k];
  SphereView view{sphere, camera, static_cast<double>(stack.width),
                  static_cast<double>(stack.height)};
  view.Init();
  const DiscSamples disc = SampleDisc(grey, sphere);
  const std::vector<float>& vals = disc.values;
  const float peak = disc.peak;
  const int px = disc.px, py = disc.py;
  if (vals.size() < 20)
    return MakeError(ErrorCode::kInvalidInput, name,
                     "the sphere at ({:.1f}, {:.1f}) r {:.1f} px is outside the {}x{} image or "
                     "too small", sphere.cx, sphere.cy, sphere.r, stack.width, stack.height);
  const double bg = Median(vals);
  const bool peak_clipped = clip && clip->at<uint8_t>(py, px);
  std::vector<float> sorted_vals = vals;
  auto p90 = sorted_vals.begin() + static_cast<long>(0.9 * (sorted_vals.size() - 1));
  std::nth_element(sorted_vals.begin(), p90, sorted_vals.end());
  const double q90 = std::max(static_cast<double>(*p90), 1e-12);
  if (!peak_clipped && peak - bg <= options.min_contrast * std::max(bg, 1e-9))
    return MakeError(ErrorCode::kInvalidInput, name,
                     "no highlight on the sphere at ({:.1f}, {:.1f}) r {:.1f} px: its brightest "
                     "pixel is only {:.1f}x its median (a highlight needs {:.0f}x)", sphere.cx,
                     sphere.cy, sphere.r, bg > 0 ? peak / bg : 0.0, options.min_contrast + 1);
  // The half-maximum blob around the peak; a clipped peak: the clipped area (its half maximum
  // is unknown).
  const double half = peak_clipped ? peak * 0.999 : bg + 0.5 * (peak - bg);
  const auto [blob, saturated] = HalfMaximumBlob(grey, disc, clip, half);
  const double disc_area = kPi * sphere.r * sphere.r;
  if (blob > options.max_blob_fraction * disc_area)
    return MakeError(ErrorCode::kInvalidInput, name,
                     "the highlight on the sphere at ({:.1f}, {:.1f}) is {} a blob of {} px, {:.1f}% "
                     "of the sphere (at most {:.1f}%): not a point lamp's highlight (a matte "
                     "sphere, an overexposed image or a lamp too large)",
                     sphere.cx, sphere.cy, saturated ? "saturated over" : "spread over", blob,
                     100.0 * blob / disc_area, 100 * options.max_blob_fraction);
  const double rw = std::max(3.0, 3.0 * std::sqrt(blob / kPi));
  Vec3 n_peak, v_peak;
  if (!view.At(px + 0.5, py + 0.5, &n_peak, &v_peak))
    return MakeError(ErrorCode::kInvalidInput, name, "the highlight lies off the sphere");
  Highlight h;
  h.direction = LobeDirection(grey, disc, view, bg, rw, Reflect(n_peak, v_peak), &h);
  h.blob_px = blob;
  h.blob_fraction = blob / disc_area;
  h.contrast90 = (peak - bg) / q90;
  h.saturated = saturated;
  return h;
}

Result<std::vector<SphereCircle>> DetectChromeSpheres(const LightStack& stack,
                                                      const HighlightOptions& options) {
  const cv::Mat med = MedianGrey(stack);
  cv::Mat lg = LogImage(med), img8;
  cv::normalize(lg, img8, 0, 255, cv::NORM_MINMAX);
  img8.convertTo(img8, CV_8U);
  cv::GaussianBlur(img8, img8, cv::Size(5, 5), 1.2);
  std::vector<cv::Vec3f> circles;
  const int min_r = 8, max_r = std::min(stack.width, stack.height) / 2;
  cv::HoughCircles(img8, circles, cv::HOUGH_GRADIENT_ALT, 1.5, 10, 300, 0.8, min_r, max_r);
  std::vector<cv::Vec3f> more;
  cv::HoughCircles(img8, more, cv::HOUGH_GRADIENT, 1, 10, 120, 30, min_r, max_r);
  circles.insert(circles.end(), more.begin(), more.end());
  std::vector<SphereCircle> found;
  std::vector<double> scores;
  for (const auto& c : circles) {
    SphereCircle s = RefineCircle(med, {c[0], c[1], c[2]});
    bool dup = false;
    for (const auto& f : found)
      if (std::hypot(f.cx - s.cx, f.cy - s.cy) < 0.5 * std::max(f.r, s.r)) dup = true;
    if (dup) continue;
    // A chrome sphere shows a sharp, small highlight in most images.
    int ok = 0;
    for (size_t k = 0; k < stack.size(); ++k) {
      auto h = LocateHighlight(stack, k, s, CameraModel{}, options);
      if (h.ok() && h->contrast90 >= options.detect_contrast &&
          h->blob_fraction <= options.detect_blob_fraction)
        ++ok;
    }
    if (ok >= 0.6 * static_cast<double>(stack.size())) found.push_back(s);
  }
  if (found.empty())
    return MakeError(ErrorCode::kInvalidInput, stack.names.empty() ? "(capture)" : stack.names[0],
                     "no chrome sphere found in the capture ({} circles tried, none with a sharp "
                     "highlight in 60% of the {} images); give one with --sphere CX,CY,R",
                     circles.size(), stack.size());
  std::sort(found.begin(), found.end(), [](const SphereCircle& a, const SphereCircle& b) {
    return a.cx + a.cy * 1e4 < b.cx + b.cy * 1e4;
  });
  return found;
}

namespace {

// Every image's rays, the spheres placed by the field's scale at centre depths `depths` (mm).
std::vector<std::vector<LampRay>> SphereRays(const SphereCalibration& cal, int width, int height,
                                             const SphereField& field,
                                             const std::vector<double>& depths) {
  const double mm_per_px = field.field_height_mm / height;
  std::vector<std::vector<LampRay>> rays(cal.highlights.size());
  for (size_t k = 0; k < cal.highlights.size(); ++k)
    for (size_t j = 0; j < cal.spheres.size(); ++j) {
      const Highlight& h = cal.highlights[k][j];
      const SphereCircle& c = cal.spheres[j];
      const double r_mm = c.r * mm_per_px;
      const Vec3 centre = {(c.cx - width / 2.0) * mm_per_px, (height / 2.0 - c.cy) * mm_per_px,
                           depths[j]};
      rays[k].push_back({{centre[0] + r_mm * h.normal[0], centre[1] + r_mm * h.normal[1],
                          centre[2] + r_mm * h.normal[2]},
                         h.direction,
                         2 * field.edge_px / c.r});
    }
  return rays;
}

double MedianOfValues(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t m = v.size() / 2;
  return v.size() % 2 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

Vec3 StartDirection(const LampFix& fix, const std::vector<LampRay>& rays) {
  if (fix.determined) return fix.position_mm;
  Vec3 start = {0, 0, 0};
  for (const auto& r : rays)
    for (int c = 0; c < 3; ++c) start[c] += r.direction[c];
  return start;
}

LampEstimate EstimateAtDepths(const SphereCalibration& cal, int width, int height,
                              const SphereField& field, const std::vector<double>& depths) {
  LampEstimate est;
  est.depth_mm = depths;
  const auto rays = SphereRays(cal, width, height, field, depths);
  std::vector<double> distances, misses, resolvable;
  for (const auto& image_rays : rays) {
    LampFix fix = TriangulateRays(image_rays, field.lamp);
    resolvable.push_back(fix.resolvable_mm);
    if (fix.determined) {
      ++est.determined;
      distances.push_back(fix.distance_mm);
      misses.push_back(fix.miss_mm);
    }
    est.fixes.push_back(std::move(fix));
  }
  est.resolvable_mm = MedianOfValues(resolvable);
  est.near = !rays.empty() && 2 * est.determined >= static_cast<int>(rays.size());
  if (!est.near) return est;
  est.distance_mm = MedianOfValues(distances);
  est.median_miss_mm = MedianOfValues(misses);
  for (size_t k = 0; k < rays.size(); ++k) {
    std::vector<double> res;
    est.directions.push_back(LampDirectionAtDistance(rays[k], est.distance_mm,
                                                     StartDirection(est.fixes[k], rays[k]), &res));
    est.residual_deg.push_back(*std::max_element(res.begin(), res.end()));
  }
  return est;
}

struct DepthFit {
  std::vector<double> depth_mm, depth_sigma_mm;
  double distance_mm = 0, distance_sigma_mm = 0, rms = 0;
};

// The spheres' depths and the lamp's one distance from the arm's centre, fitted to every image
// at once (Levenberg-Marquardt, numeric Jacobian; each image's direction solved inside, for
// the parameters at hand): the lamp moves on a sphere about the arm's centre, so its distance
// may not change from image to image, and a depth error of a sphere shifts its rays along z,
// which grazing lamps see. Residuals: each ray's miss over its sigma times its range.
Result<DepthFit> FitDepths(const SphereCalibration& cal, int width, int height,
                           const SphereField& field, const std::vector<double>& start_depths,
                           const LampEstimate& start) {
  const size_t m = start_depths.size();
  Eigen::VectorXd p(m + 1);
  for (size_t j = 0; j < m; ++j) p(j) = start_depths[j];
  p(m) = start.distance_mm;
  std::vector<Vec3> dirs = start.directions;
  auto residuals = [&](const Eigen::VectorXd& q, std::vector<Vec3>* u) {
    const std::vector<double> depths(q.data(), q.data() + m);
    const auto rays = SphereRays(cal, width, height, field, depths);
    Eigen::VectorXd r(3 * m * rays.size());
    for (size_t k = 0; k < rays.size(); ++k) {
      (*u)[k] = LampDirectionAtDistance(rays[k], q(m), (*u)[k]);
      for (size_t j = 0; j < m; ++j) {
        const LampRay& ray = rays[k][j];
        const Eigen::Vector3d d(ray.direction[0], ray.direction[1], ray.direction[2]);
        const Eigen::Vector3d to(q(m) * (*u)[k][0] - ray.origin_mm[0],
                                 q(m) * (*u)[k][1] - ray.origin_mm[1],
                                 q(m) * (*u)[k][2] - ray.origin_mm[2]);
        const Eigen::Vector3d perp = to - d * d.dot(to);
        r.segment<3>(3 * (k * m + j)) = perp / (ray.sigma_rad * std::max(to.norm(), 1e-9));
      }
    }
    return r;
  };
  Eigen::VectorXd r = residuals(p, &dirs);
  Eigen::MatrixXd jac(r.size(), m + 1);
  double lambda = 1e-3;
  for (int iter = 0; iter < 40; ++iter) {
    for (size_t c = 0; c <= m; ++c) {
      Eigen::VectorXd q = p;
      q(c) += 0.01;  // mm
      std::vector<Vec3> u = dirs;
      jac.col(c) = (residuals(q, &u) - r) / 0.01;
    }
    Eigen::MatrixXd a = jac.transpose() * jac;
    a.diagonal() *= 1 + lambda;
    const Eigen::VectorXd step = a.ldlt().solve(-jac.transpose() * r);
    Eigen::VectorXd q = p + step;
    if (q(m) <= 0) {
      lambda *= 10;
      continue;
    }
    std::vector<Vec3> u = dirs;
    const Eigen::VectorXd rq = residuals(q, &u);
    if (rq.squaredNorm() < r.squaredNorm()) {
      p = q;
      r = rq;
      dirs = u;
      lambda *= 0.3;
      if (step.norm() < 1e-4) break;
    } else {
      lambda *= 10;
      if (lambda > 1e8) break;
    }
  }
  DepthFit fit;
  const double dof = std::max<double>(1.0, static_cast<double>(r.size()) - (m + 1));
  // The residuals are in units of the directions' assumed sigma. The covariance is scaled up
  // when they are larger, never down when smaller: a circle's error (a few hundredths of a
  // pixel) is the same in every image and does not average out over them, so small residuals
  // do not make the depths better known than the assumed sigma says.
  const double chi2 = r.squaredNorm() / dof;
  fit.rms = std::sqrt(chi2);
  Eigen::MatrixXd jtj = jac.transpose() * jac;
  Eigen::FullPivLU<Eigen::MatrixXd> lu(jtj);
  if (!lu.isInvertible())
    return MakeError(ErrorCode::kInvalidInput, "(spheres)",
                     "the spheres' depths cannot be told apart from the lamp's distance with "
                     "these images (the lamp must reach grazing angles)");
  const Eigen::MatrixXd cov = lu.inverse() * std::max(1.0, chi2);
  for (size_t j = 0; j < m; ++j) {
    fit.depth_mm.push_back(p(j));
    fit.depth_sigma_mm.push_back(std::sqrt(std::max(0.0, cov(j, j))));
  }
  fit.distance_mm = p(m);
  fit.distance_sigma_mm = std::sqrt(std::max(0.0, cov(m, m)));
  return fit;
}

}  // namespace

Result<LampEstimate> EstimateLamp(const SphereCalibration& cal, int width, int height,
                                  const CameraModel& camera, const SphereField& field) {
  const auto& spheres = cal.spheres;
  if (spheres.size() < 2)
    return MakeError(ErrorCode::kInvalidInput, "(spheres)",
                     "the lamp's position needs two or more chrome spheres at different places in "
                     "the field ({} given): one sphere sees the lamp's direction, not its distance",
                     spheres.size());
  if (field.field_height_mm <= 0)
    return MakeError(ErrorCode::kInvalidInput, "(field)",
                     "the lamp's position needs the field's height at the object (mm) to place "
                     "the spheres");
  if (camera.perspective())
    return MakeError(ErrorCode::kInvalidInput, "(camera)",
                     "the lamp's position places the spheres with the orthographic model only "
                     "(a perspective camera would need every sphere's size in mm)");
  if (field.depth_mm.size() > 1 && field.depth_mm.size() != spheres.size())
    return MakeError(ErrorCode::kInvalidInput, "(spheres)",
                     "{} sphere depths given for {} spheres (give one for all, or one per sphere)",
                     field.depth_mm.size(), spheres.size());
  for (size_t a = 0; a < spheres.size(); ++a)
    for (size_t b = a + 1; b < spheres.size(); ++b)
      if (std::hypot(spheres[a].cx - spheres[b].cx, spheres[a].cy - spheres[b].cy) <
          spheres[a].r + spheres[b].r)
        return MakeError(ErrorCode::kInvalidInput, "(spheres)",
                         "spheres {} and {} overlap in the image ({:.1f}, {:.1f} and {:.1f}, "
                         "{:.1f} px): the same sphere twice, or a circle wrong", a + 1, b + 1,
                         spheres[a].cx, spheres[a].cy, spheres[b].cx, spheres[b].cy);
  const double mm_per_px = field.field_height_mm / height;
  std::vector<double> depths;
  for (size_t j = 0; j < spheres.size(); ++j)
    depths.push_back(field.depth_mm.empty()
                         ? spheres[j].r * mm_per_px
                         : field.depth_mm[field.depth_mm.size() == 1 ? 0 : j]);
  LampEstimate est = EstimateAtDepths(cal, width, height, field, depths);
  est.depth_assumed = field.depth_mm.empty();
  if (!field.fit_depths) return est;
  if (!est.near)
    return MakeError(ErrorCode::kInvalidInput, "(spheres)",
                     "the spheres' depths are fitted from a near lamp's parallax; this lamp is "
                     "far ({} of {} images give a distance): its rays are parallel whatever "
                     "the depths", est.determined, cal.highlights.size());
  RIG_ASSIGN_OR_RETURN(DepthFit fit, FitDepths(cal, width, height, field, depths, est));
  LampEstimate fitted = EstimateAtDepths(cal, width, height, field, fit.depth_mm);
  fitted.depth_assumed = false;
  fitted.depth_fitted = true;
  fitted.depth_sigma_mm = fit.depth_sigma_mm;
  fitted.fit_distance_mm = fit.distance_mm;
  fitted.fit_distance_sigma_mm = fit.distance_sigma_mm;
  fitted.fit_rms = fit.rms;
  fitted.depth_start_mm = depths;
  return fitted;
}

std::vector<double> SurfaceUnderSpheres(const LampEstimate& lamp,
                                        const std::vector<SphereCircle>& spheres,
                                        double field_height_mm, int height) {
  std::vector<double> out;
  if (height <= 0 || field_height_mm <= 0) return out;
  const double mm_per_px = field_height_mm / height;
  for (size_t j = 0; j < spheres.size() && j < lamp.depth_mm.size(); ++j)
    out.push_back(lamp.depth_mm[j] - spheres[j].r * mm_per_px);
  return out;
}

Result<SphereCalibration> CalibrateFromSpheres(const LightStack& stack,
                                               const std::vector<SphereCircle>& spheres,
                                               const CameraModel& camera,
                                               const HighlightOptions& options,
                                               double max_disagreement_deg,
                                               const SphereField& field) {
  SphereCalibration cal;
  cal.spheres = spheres;
  for (size_t k = 0; k < stack.size(); ++k) {
    std::vector<Highlight> hs;
    Vec3 sum = {0, 0, 0};
    for (const auto& s : spheres) {
      RIG_ASSIGN_OR_RETURN(Highlight h, LocateHighlight(stack, k, s, camera, options));
      for (int c = 0; c < 3; ++c) sum[c] += h.direction[c];
      hs.push_back(h);
    }
    double worst = 0;
    for (size_t a = 0; a < hs.size(); ++a)
      for (size_t b = a + 1; b < hs.size(); ++b)
        worst = std::max(worst, AngleDeg(hs[a].direction, hs[b].direction));
    cal.directions.push_back(Normalize(sum));
    cal.highlights.push_back(std::move(hs));
    cal.sphere_disagreement_deg.push_back(worst);
  }
  if (field.field_height_mm > 0) {
    RIG_ASSIGN_OR_RETURN(LampEstimate lamp,
                         EstimateLamp(cal, stack.width, stack.height, camera, field));
    cal.lamp = std::move(lamp);
  }
  if (cal.lamp && cal.lamp->near) {
    // Each sphere sees a near lamp from its own place: what must agree is every sphere's ray
    // with the lamp the rays triangulate, and the direction is the one from the arm's centre.
    for (size_t k = 0; k < stack.size(); ++k)
      if (cal.lamp->residual_deg[k] > max_disagreement_deg)
        return MakeError(ErrorCode::kInvalidInput, stack.names[k],
                         "a sphere's ray misses the lamp the spheres triangulate ({:.0f} mm from "
                         "the arm's centre) by {:.2f} deg (at most {:.2f}): a sphere misplaced, "
                         "or its depth wrong", cal.lamp->distance_mm, cal.lamp->residual_deg[k],
                         max_disagreement_deg);
    cal.directions = cal.lamp->directions;
    return cal;
  }
  for (size_t k = 0; k < stack.size(); ++k)
    if (cal.sphere_disagreement_deg[k] > max_disagreement_deg)
      return MakeError(ErrorCode::kInvalidInput, stack.names[k],
                       "the spheres disagree on the light direction by {:.2f} deg (at most {:.2f}; "
                       "a sphere misplaced, or a lamp so near that it shows parallax: give the "
                       "field's height to triangulate it, or a --max-disagreement that allows it)",
                       cal.sphere_disagreement_deg[k], max_disagreement_deg);
  return cal;
}

namespace {

Vec3 Tilted(const Vec3& d, double tilt_deg) {
  const double t = tilt_deg / kDegPerRadian, c = std::cos(t), s = std::sin(t);
  return {c * d[0] - s * d[1], s * d[0] + c * d[1], d[2]};
}

// Gauss-Newton with a numeric Jacobian on p = (h_offset, v_offset[, tilt]) (degrees).
double FitOffsets(const std::vector<double>& h, const std::vector<double>& v,
                  const std::vector<Vec3>& m, LightFrameConfig* f, double* tilt, bool with_tilt) {
  const int np = with_tilt ? 3 : 2;
  const size_t n = h.size();
  auto residual = [&](const Eigen::Vector3d& p, Eigen::VectorXd* r) {
    LightFrameConfig g = *f;
    g.h_offset_deg = p(0);
    g.v_offset_deg = p(1);
    r->resize(3 * n);
    for (size_t i = 0; i < n; ++i) {
      const Vec3 d = Tilted(LightDirection(h[i], v[i], g), p(2));
      for (int c = 0; c < 3; ++c) (*r)(3 * i + c) = d[c] - m[i][c];
    }
  };
  Eigen::Vector3d p(f->h_offset_deg, f->v_offset_deg, 0);
  Eigen::VectorXd r, r2;
  residual(p, &r);
  double lambda = 1e-3;
  for (int iter = 0; iter < 50; ++iter) {
    Eigen::MatrixXd j(3 * n, np);
    for (int k = 0; k < np; ++k) {
      Eigen::Vector3d q = p;
      q(k) += 1e-4;
      residual(q, &r2);
      j.col(k) = (r2 - r) / 1e-4;
    }
    Eigen::MatrixXd a = j.transpose() * j;
    a.diagonal() *= 1 + lambda;
    Eigen::VectorXd step = a.ldlt().solve(-j.transpose() * r);
    Eigen::Vector3d q = p;
    for (int k = 0; k < np; ++k) q(k) += step(k);
    residual(q, &r2);
    if (r2.squaredNorm() < r.squaredNorm()) {
      p = q;
      r = r2;
      lambda *= 0.3;
      if (step.norm() < 1e-7) break;
    } else {
      lambda *= 10;
    }
  }
  f->h_offset_deg = p(0);
  f->v_offset_deg = p(1);
  *tilt = p(2);
  return r.squaredNorm();
}

}  // namespace

Result<LightFrameFit> FitLightFrame(const std::vector<double>& h_deg,
                                    const std::vector<double>& v_deg,
                                    const std::vector<Vec3>& measured,
                                    const LightFrameConfig& start) {
  if (h_deg.size() != measured.size() || v_deg.size() != measured.size() || measured.size() < 3)
    return MakeError(ErrorCode::kInvalidInput, "(light frame)",
                     "fitting the light frame needs at least 3 poses with angles ({} given)",
                     measured.size());
  LightFrameFit best;
  double best_cost = 1e300;
  for (int hs : {1, -1})
    for (int vs : {1, -1}) {
      LightFrameConfig f = start;
      f.h_sign = hs;
      f.v_sign = vs;
      // Start from the mean angle difference (h as a circular mean).
      double sh = 0, ch = 0, sv = 0;
      for (size_t i = 0; i < measured.size(); ++i) {
        double mh, mv;
        DirectionToAngles(measured[i], &mh, &mv);
        const double dh = (mh - hs * h_deg[i]) / kDegPerRadian;
        sh += std::sin(dh);
        ch += std::cos(dh);
        sv += mv - vs * v_deg[i];
      }
      f.h_offset_deg = std::atan2(sh, ch) * kDegPerRadian;
      f.v_offset_deg = sv / measured.size();
      double tilt = 0;
      const double cost = FitOffsets(h_deg, v_deg, measured, &f, &tilt, false);
      if (cost < best_cost) {
        best_cost = cost;
        best.frame = f;
      }
    }
  double sum2 = 0;
  best.residual_deg.clear();
  for (size_t i = 0; i < measured.size(); ++i) {
    const double e = AngleDeg(LightDirection(h_deg[i], v_deg[i], best.frame), measured[i]);
    best.residual_deg.push_back(e);
    sum2 += e * e;
    best.max_deg = std::max(best.max_deg, e);
  }
  best.rms_deg = std::sqrt(sum2 / measured.size());
  LightFrameConfig t = best.frame;
  double tilt = 0;
  FitOffsets(h_deg, v_deg, measured, &t, &tilt, true);
  double sum2t = 0;
  for (size_t i = 0; i < measured.size(); ++i) {
    const double e = AngleDeg(Tilted(LightDirection(h_deg[i], v_deg[i], t), tilt), measured[i]);
    sum2t += e * e;
  }
  best.tilt_deg = tilt;
  best.rms_with_tilt_deg = std::sqrt(sum2t / measured.size());
  return best;
}

}  // namespace rig
