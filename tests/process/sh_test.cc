// Real spherical harmonics (paper eq. 2-5) and the HSH/PTM bases against independent truth.
#include "process/model/harmonic/sh.h"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "process/model/harmonic/basis.h"

namespace rig {
namespace {

constexpr double kPi = std::numbers::pi;

// Gauss-Legendre nodes/weights on [-1, 1], by Newton on the plain Legendre recurrence
// (independent of the code under test).
void GaussLegendre(int n, std::vector<double>* x, std::vector<double>* w) {
  x->resize(n);
  w->resize(n);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(kPi * (i + 0.75) / (n + 0.5)), pp = 0;
    for (int it = 0; it < 100; ++it) {
      double p1 = 1, p2 = 0;
      for (int j = 1; j <= n; ++j) {
        const double p3 = p2;
        p2 = p1;
        p1 = ((2.0 * j - 1) * z * p2 - (j - 1.0) * p3) / j;
      }
      pp = n * (z * p1 - p2) / (z * z - 1);
      const double dz = p1 / pp;
      z -= dz;
      if (std::fabs(dz) < 1e-15) break;
    }
    (*x)[i] = z;
    (*w)[i] = 2 / ((1 - z * z) * pp * pp);
  }
}

// Gram matrix of a basis over the sphere (or the hemisphere z >= 0), exact for polynomial
// degree < 2*nodes in cos θ and trigonometric degree < phis in φ.
Eigen::MatrixXd BasisGram(const Basis& b, bool hemisphere) {
  std::vector<double> x, w;
  GaussLegendre(32, &x, &w);
  const int phis = 64;
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(b.size(), b.size());
  for (size_t i = 0; i < x.size(); ++i) {
    // Hemisphere: cos θ = (x+1)/2 in [0, 1], dcosθ = dx/2.
    const double c = hemisphere ? 0.5 * (x[i] + 1) : x[i];
    const double wc = hemisphere ? 0.5 * w[i] : w[i];
    const double s = std::sqrt(1 - c * c);
    for (int j = 0; j < phis; ++j) {
      const double phi = 2 * kPi * j / phis;
      auto v = b.Eval({s * std::cos(phi), s * std::sin(phi), c});
      Eigen::Map<Eigen::VectorXd> e(v.data(), b.size());
      g += wc * (2 * kPi / phis) * e * e.transpose();
    }
  }
  return g;
}

TEST(SphericalHarmonics, OrthonormalOverTheSphereToOrderEight) {
  const Eigen::MatrixXd g = BasisGram(Basis(BasisKind::kSh, 8), false);
  EXPECT_LT((g - Eigen::MatrixXd::Identity(81, 81)).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(SphericalHarmonics, NormalisationUsesTwoPiAndRootTwoForMZero) {
  // N_l0 / √2 = sqrt((2l+1)/(4π)).
  for (int l = 0; l <= 6; ++l) {
    EXPECT_NEAR(ShNormalization(l, 0) / std::sqrt(2.0), std::sqrt((2 * l + 1) / (4 * kPi)), 1e-15);
  }
  EXPECT_NEAR(ShNormalization(2, 1), std::sqrt(5 / (2 * kPi) / 6.0), 1e-15);
  EXPECT_NEAR(ShNormalization(2, -2), std::sqrt(5 / (2 * kPi) / 24.0), 1e-15);
}

TEST(SphericalHarmonics, LegendreMatchesClosedForms) {
  for (double x : {-0.9, -0.3, 0.0, 0.4, 0.95}) {
    const double s = std::sqrt(1 - x * x);
    EXPECT_NEAR(AssocLegendre(0, 0, x), 1, 1e-15);
    EXPECT_NEAR(AssocLegendre(1, 0, x), x, 1e-15);
    EXPECT_NEAR(AssocLegendre(1, 1, x), -s, 1e-15);
    EXPECT_NEAR(AssocLegendre(2, 0, x), 0.5 * (3 * x * x - 1), 1e-14);
    EXPECT_NEAR(AssocLegendre(2, 1, x), -3 * x * s, 1e-14);
    EXPECT_NEAR(AssocLegendre(2, 2, x), 3 * s * s, 1e-14);
    EXPECT_NEAR(AssocLegendre(3, 0, x), 0.5 * (5 * x * x * x - 3 * x), 1e-14);
    EXPECT_NEAR(AssocLegendre(3, 3, x), -15 * s * s * s, 1e-13);
    EXPECT_NEAR(AssocLegendre(4, 0, x), (35 * std::pow(x, 4) - 30 * x * x + 3) / 8, 1e-13);
  }
}

TEST(SphericalHarmonics, LowOrdersMatchCartesianClosedForms) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  for (int t = 0; t < 50; ++t) {
    double x = n01(rng), y = n01(rng), z = n01(rng);
    const double r = std::sqrt(x * x + y * y + z * z);
    x /= r, y /= r, z /= r;
    double th = 0, ph = 0;
    DirectionToSpherical({x, y, z}, &th, &ph);
    const double c1 = std::sqrt(3 / (4 * kPi)), c2 = 0.5 * std::sqrt(15 / kPi);
    EXPECT_NEAR(ShY(0, 0, th, ph), 0.5 / std::sqrt(kPi), 1e-14);
    EXPECT_NEAR(ShY(1, -1, th, ph), -c1 * y, 1e-14);
    EXPECT_NEAR(ShY(1, 0, th, ph), c1 * z, 1e-14);
    EXPECT_NEAR(ShY(1, 1, th, ph), -c1 * x, 1e-14);
    EXPECT_NEAR(ShY(2, -2, th, ph), c2 * x * y, 1e-14);
    EXPECT_NEAR(ShY(2, -1, th, ph), -c2 * y * z, 1e-14);
    EXPECT_NEAR(ShY(2, 0, th, ph), 0.25 * std::sqrt(5 / kPi) * (3 * z * z - 1), 1e-14);
    EXPECT_NEAR(ShY(2, 1, th, ph), -c2 * x * z, 1e-14);
    EXPECT_NEAR(ShY(2, 2, th, ph), 0.5 * c2 * (x * x - y * y), 1e-14);
    // The all-terms evaluator agrees with the one-term one.
    double all[81];
    ShEvalAll(8, {x, y, z}, all);
    for (int l = 0; l <= 8; ++l)
      for (int m = -l; m <= l; ++m) EXPECT_NEAR(all[ShIndex(l, m)], ShY(l, m, th, ph), 1e-12);
  }
}

TEST(HemisphericalHarmonics, OrthonormalOverTheHemisphereToOrderSix) {
  const Eigen::MatrixXd g = BasisGram(Basis(BasisKind::kHsh, 6), true);
  EXPECT_LT((g - Eigen::MatrixXd::Identity(49, 49)).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(HemisphericalHarmonics, LowOrderClosedForms) {
  // H_00 = 1/√(2π); H_10 = √(3/2π)(2cosθ-1).
  Basis b(BasisKind::kHsh, 1);
  auto v = b.Eval({0.6, 0.0, 0.8});
  EXPECT_NEAR(v[0], 1 / std::sqrt(2 * kPi), 1e-14);
  EXPECT_NEAR(v[ShIndex(1, 0)], std::sqrt(3 / (2 * kPi)) * (2 * 0.8 - 1), 1e-14);
}

TEST(PtmBasis, BiquadraticHasSixTermsInLuLv) {
  Basis b(BasisKind::kPtm, 2);
  ASSERT_EQ(b.size(), 6);
  auto v = b.Eval({0.3, -0.4, std::sqrt(1 - 0.25)});
  const double expect[6] = {1, 0.3, -0.4, 0.09, -0.12, 0.16};
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(v[k], expect[k], 1e-14) << b.TermName(k);
}

TEST(BasisFactory, RefusesUnknownNamesAndOrdersOutOfRange) {
  EXPECT_FALSE(Basis::Create("wavelet", 2).ok());
  EXPECT_FALSE(Basis::Create("sh", 13).ok());
  EXPECT_FALSE(Basis::Create("ptm", 0).ok());
  ASSERT_TRUE(Basis::Create("hsh", 3).ok());
  EXPECT_EQ(Basis::Create("hsh", 3)->size(), 16);
}

}  // namespace
}  // namespace rig
