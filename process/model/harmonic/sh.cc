// Real spherical harmonics (paper eq. 2-5 with the typos fixed), evaluated by recurrence.
#include "process/model/harmonic/sh.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace rig {

double AssocLegendre(int l, int m, double x) {
  RIG_CHECK(m >= 0 && l >= m, "AssocLegendre needs 0 <= m <= l");
  // P_mm = (1-2m) sqrt(1-x²) P_(m-1)(m-1), from P_00 = 1.
  const double s = std::sqrt(std::max(0.0, 1.0 - x * x));
  double pmm = 1.0;
  for (int k = 1; k <= m; ++k) pmm *= (1.0 - 2.0 * k) * s;
  if (l == m) return pmm;
  // P_(m+1)m = x (2m+1) P_mm.
  double pm1 = x * (2.0 * m + 1.0) * pmm;
  if (l == m + 1) return pm1;
  // P_lm = x (2l-1)/(l-m) P_(l-1)m - (l+m-1)/(l-m) P_(l-2)m.
  double p2 = pmm, p1 = pm1, p = 0;
  for (int ll = m + 2; ll <= l; ++ll) {
    p = (x * (2.0 * ll - 1.0) * p1 - (ll + m - 1.0) * p2) / (ll - m);
    p2 = p1;
    p1 = p;
  }
  return p;
}

double ShNormalization(int l, int m) {
  const int am = std::abs(m);
  // (l-|m|)!/(l+|m|)! as a product, no overflow for the orders used here.
  double ratio = 1.0;
  for (int k = l - am + 1; k <= l + am; ++k) ratio /= k;
  return std::sqrt((2.0 * l + 1.0) / (2.0 * std::numbers::pi) * ratio);
}

double ShY(int l, int m, double theta_rad, double phi_rad) {
  const double p = AssocLegendre(l, std::abs(m), std::cos(theta_rad));
  const double n = ShNormalization(l, m);
  if (m > 0) return n * p * std::cos(m * phi_rad);
  if (m < 0) return n * p * std::sin(-m * phi_rad);
  return n * p / std::numbers::sqrt2;
}

void DirectionToSpherical(const Vec3& d, double* theta_rad, double* phi_rad) {
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  *theta_rad = std::acos(std::clamp(d[2] / n, -1.0, 1.0));
  *phi_rad = std::atan2(d[1], d[0]);
}

void ShEvalAll(int order, const Vec3& d, double* out) {
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  RIG_CHECK(n > 0, "ShEvalAll needs a non-zero direction");
  const double x = d[2] / n;  // cos θ
  const double phi = std::atan2(d[1], d[0]);
  const double s = std::sqrt(std::max(0.0, 1.0 - x * x));
  double pmm = 1.0;
  for (int m = 0; m <= order; ++m) {
    if (m > 0) pmm *= (1.0 - 2.0 * m) * s;
    const double cm = std::cos(m * phi), sm = std::sin(m * phi);
    double p2 = 0, p1 = 0;
    for (int l = m; l <= order; ++l) {
      double p;
      if (l == m) {
        p = pmm;
      } else if (l == m + 1) {
        p = x * (2.0 * m + 1.0) * pmm;
      } else {
        p = (x * (2.0 * l - 1.0) * p1 - (l + m - 1.0) * p2) / (l - m);
      }
      p2 = p1;
      p1 = p;
      if (m == 0) {
        out[ShIndex(l, 0)] = ShNormalization(l, 0) * p / std::numbers::sqrt2;
      } else {
        const double nlm = ShNormalization(l, m);
        out[ShIndex(l, m)] = nlm * p * cm;
        out[ShIndex(l, -m)] = nlm * p * sm;
      }
    }
  }
}

}  // namespace rig
