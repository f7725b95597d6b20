// The lamp's position from reflected rays: the weighted point nearest them, its uncertainty,
// and the lamp's direction from the arm's centre once its distance is known.
#include "process/geometry/lamp_position.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "config/result.h"

namespace rig {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

Eigen::Vector3d E(const Vec3& v) { return {v[0], v[1], v[2]}; }
Vec3 V(const Eigen::Vector3d& v) { return {v(0), v(1), v(2)}; }

// The projection onto the plane perpendicular to the unit direction d.
Eigen::Matrix3d Perp(const Eigen::Vector3d& d) {
  return Eigen::Matrix3d::Identity() - d * d.transpose();
}

double AngleBetweenDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kDegPerRad;
}

}  // namespace

LampFix TriangulateRays(const std::vector<LampRay>& rays, const LampOptions& options) {
  RIG_CHECK(rays.size() >= 2, "a lamp's position needs two rays");
  const size_t n = rays.size();
  std::vector<Eigen::Vector3d> o(n), d(n);
  for (size_t i = 0; i < n; ++i) {
    RIG_CHECK(rays[i].sigma_rad > 0, "a ray's direction noise must be positive");
    o[i] = E(rays[i].origin_mm);
    d[i] = E(rays[i].direction).normalized();
  }
  LampFix fix;
  // Parallax, and what the widest pair can resolve: for a lamp at D seen over a baseline B
  // (across the rays) the parallax is ~B / D, and its noise sigma_g = hypot(sigma_a, sigma_b)
  // makes the distance's relative error sigma_g / parallax = sigma_g D / B.
  for (size_t a = 0; a < n; ++a)
    for (size_t b = a + 1; b < n; ++b) {
      fix.parallax_deg = std::max(fix.parallax_deg, AngleBetweenDeg(d[a], d[b]));
      const Eigen::Vector3d mean = (d[a] + d[b]).normalized();
      const double across = (Perp(mean) * (o[a] - o[b])).norm();
      const double sigma_g = std::hypot(rays[a].sigma_rad, rays[b].sigma_rad);
      fix.resolvable_mm =
          std::max(fix.resolvable_mm, options.max_relative_sigma * across / sigma_g);
    }
  std::vector<double> w(n);
  for (size_t i = 0; i < n; ++i) w[i] = 1.0 / (rays[i].sigma_rad * rays[i].sigma_rad);
  Eigen::Matrix3d a;
  Eigen::Vector3d s;
  for (int iter = 0; iter < 4; ++iter) {
    a.setZero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Matrix3d p = Perp(d[i]);
      a += w[i] * p;
      b += w[i] * p * o[i];
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(a);
    if (eig.eigenvalues()(0) <= 1e-12 * eig.eigenvalues()(2)) {
      fix.note = "the rays are parallel: no point is nearer them than another (a far lamp)";
      return fix;
    }
    s = a.ldlt().solve(b);
    for (size_t i = 0; i < n; ++i) {
      const double range = d[i].dot(s - o[i]);
      if (range <= 0) {
        fix.note = fmt::format("the rays diverge (parallax {:.2f} deg): the lamp is beyond what "
                               "the spheres resolve, or a sphere is misplaced", fix.parallax_deg);
        return fix;
      }
      w[i] = 1.0 / std::pow(rays[i].sigma_rad * range, 2);
    }
  }
  fix.position_mm = V(s);
  fix.distance_mm = s.norm();
  double miss2 = 0;
  for (size_t i = 0; i < n; ++i) miss2 += (Perp(d[i]) * (s - o[i])).squaredNorm();
  fix.miss_mm = std::sqrt(miss2 / n);
  // Gauss-Newton's covariance: the residuals are in units of each ray's sigma.
  const Eigen::Matrix3d cov = a.inverse();
  const Eigen::Vector3d u = s / std::max(fix.distance_mm, 1e-12);
  fix.sigma_mm = std::sqrt(std::max(0.0, u.dot(cov * u)));
  fix.determined = fix.sigma_mm <= options.max_relative_sigma * fix.distance_mm;
  if (!fix.determined)
    fix.note = fmt::format("uncertain, {:.0f} +- {:.0f} mm (parallax {:.2f} deg)",
                           fix.distance_mm, fix.sigma_mm, fix.parallax_deg);
  return fix;
}

Vec3 LampDirectionAtDistance(const std::vector<LampRay>& rays, double distance_mm,
                             const Vec3& start, std::vector<double>* residual_deg) {
  RIG_CHECK(!rays.empty() && distance_mm > 0, "a lamp's direction needs rays and a distance");
  Eigen::Vector3d u = E(start).normalized();
  for (int iter = 0; iter < 30; ++iter) {
    // A basis of the tangent plane at u.
    const Eigen::Vector3d any =
        std::abs(u(0)) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    const Eigen::Vector3d e1 = u.cross(any).normalized(), e2 = u.cross(e1);
    Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
    Eigen::Vector2d g = Eigen::Vector2d::Zero();
    for (const auto& r : rays) {
      const Eigen::Vector3d d = E(r.direction).normalized();
      const Eigen::Vector3d to = distance_mm * u - E(r.origin_mm);
      const double w = 1.0 / std::pow(r.sigma_rad * std::max(to.norm(), 1e-9), 2);
      const Eigen::Matrix3d p = Perp(d);
      Eigen::Matrix<double, 3, 2> j;
      j.col(0) = distance_mm * p * e1;
      j.col(1) = distance_mm * p * e2;
      h += w * j.transpose() * j;
      g += w * j.transpose() * (p * to);
    }
    const Eigen::Vector2d step = -h.ldlt().solve(g);
    u = (u + step(0) * e1 + step(1) * e2).normalized();
    if (step.norm() < 1e-12) break;
  }
  if (residual_deg) {
    residual_deg->clear();
    for (const auto& r : rays)
      residual_deg->push_back(
          AngleBetweenDeg(E(r.direction), distance_mm * u - E(r.origin_mm)));
  }
  return V(u);
}

}  // namespace rig
