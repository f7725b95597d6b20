// Fitting on the rig's 40-pose grid with known truth: identifiability, conditioning, RLS vs
// the paper's quadrature, order selection, refusals, missing samples, extrapolation.
#include "process/model/harmonic/fit.h"

#include <limits>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "process/model/harmonic/model.h"
#include "process/model/harmonic/sh.h"

namespace rig {
namespace {

struct Grid {
  std::vector<Vec3> dirs;
  std::vector<double> h, v, weights;
};

Grid RigGrid() {
  Grid g;
  for (int v = 0; v <= 30; v += 10)
    for (int h = 0; h <= 90; h += 10) {
      g.dirs.push_back(LightDirection(h, v));
      g.h.push_back(h);
      g.v.push_back(v);
    }
  g.weights = GridQuadratureWeights(g.h, g.v);
  return g;
}

// Off-grid poses inside the sampled region (cell centres).
std::vector<Vec3> OffGrid() {
  std::vector<Vec3> d;
  for (int v = 5; v <= 25; v += 10)
    for (int h = 5; h <= 85; h += 10) d.push_back(LightDirection(h, v));
  return d;
}

// A synthetic scene: per pixel a Lambertian albedo times cos to its normal, plus a Phong-like
// gloss lobe around the mirror direction of the camera (+z) about the normal.
struct Scene {
  int w = 16, h = 8;
  std::vector<Vec3> normal;
  std::vector<double> albedo, gloss, exponent;
  double Rho(int p, const Vec3& l) const {
    const Vec3& n = normal[p];
    const double nl = std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
    const Vec3 r{2 * n[2] * n[0], 2 * n[2] * n[1], 2 * n[2] * n[2] - 1};
    const double rl = std::max(0.0, r[0] * l[0] + r[1] * l[1] + r[2] * l[2]);
    return albedo[p] * nl + gloss[p] * std::pow(rl, exponent[p]);
  }
};

Scene MakeScene(int seed, double gloss_scale = 1.0) {
  Scene s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  for (int p = 0; p < s.w * s.h; ++p) {
    const double a = 0.5 * u(rng), b = 0.35 * u(rng);
    Vec3 n{std::sin(a) * std::cos(6 * b), std::sin(a) * std::sin(6 * b), std::cos(a)};
    s.normal.push_back(n);
    s.albedo.push_back(0.2 + 0.6 * u(rng));
    s.gloss.push_back(0.4 * gloss_scale * u(rng));
    s.exponent.push_back(4 + 12 * u(rng));
  }
  return s;
}

std::vector<cv::Mat> Render(const Scene& s, const std::vector<Vec3>& dirs, double noise = 0,
                            int seed = 1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  std::vector<cv::Mat> out;
  for (const auto& d : dirs) {
    cv::Mat m(s.h, s.w, CV_32FC3);
    for (int p = 0; p < s.w * s.h; ++p) {
      const double r = s.Rho(p, d);
      for (int c = 0; c < 3; ++c)
        m.at<cv::Vec3f>(p / s.w, p % s.w)[c] =
            static_cast<float>(r * (0.8 + 0.1 * c) + noise * n01(rng));
    }
    out.push_back(m);
  }
  return out;
}

// RMS error of a model's ρ against the scene's truth at some directions.
double HeldOutRms(const Model& m, const Scene& s, const std::vector<Vec3>& dirs) {
  double sum = 0;
  size_t n = 0;
  for (const auto& d : dirs) {
    cv::Mat rho = m.EvaluateRho(d);
    for (int p = 0; p < s.w * s.h; ++p)
      for (int c = 0; c < 3; ++c) {
        const double e = rho.at<cv::Vec3f>(p / s.w, p % s.w)[c] - s.Rho(p, d) * (0.8 + 0.1 * c);
        sum += e * e;
        ++n;
      }
  }
  return std::sqrt(sum / n);
}

Result<FitOutput> Fit(const Grid& g, const std::vector<cv::Mat>& maps, FitMethod method,
                      int order, BasisKind basis = BasisKind::kSh, int max_order = 6) {
  FitInput in;
  in.radiance = maps;
  in.directions = g.dirs;
  in.weights = g.weights;
  FitOptions o;
  o.basis = basis;
  o.method = method;
  o.order = order;
  o.max_order = max_order;
  return FitModel(in, o);
}

TEST(FitConditioning, ConditionNumberOfTheGridGrowsSteeplyWithOrderThenTheGridIsRankDeficient) {
  const Grid g = RigGrid();
  std::vector<double> cond;
  for (int order = 0; order <= 5; ++order) {
    auto pr = BuildProjector(Basis(BasisKind::kSh, order), g.dirs, g.weights, FitMethod::kQuadrature,
                             0, 1e300);
    ASSERT_TRUE(pr.ok());
    cond.push_back(pr->condition);
    std::printf("sh order %d terms %d cond(B) %.3g\n", order, (order + 1) * (order + 1),
                pr->condition);
  }
  EXPECT_NEAR(cond[0], 1.0, 1e-12);
  for (size_t i = 1; i <= 3; ++i) EXPECT_GT(cond[i], 3 * cond[i - 1]);
  // The grid's 40 directions lie on 4 circles of constant y = sin v. The degree-4 polynomial
  // (y - sin 0)(y - sin 10)(y - sin 20)(y - sin 30) vanishes on every one of them, so from
  // order 4 on the SH design matrix has a null space: no amount of data on this grid tells
  // those harmonics apart, and an unregularised fit must refuse (see FitRefusals).
  EXPECT_GT(cond[4], 1e12);
  EXPECT_GT(cond[5], 1e12);
}

TEST(FitIdentifiability, LowOrderShCombinationIsRecoveredExactlyByLeastSquares) {
  const Grid g = RigGrid();
  // ρ(dir) = Σ c_k Y_k for SH order 2 with known c.
  const double c[9] = {0.9, -0.2, 0.4, 0.1, 0.05, -0.07, 0.12, 0.03, -0.06};
  std::vector<cv::Mat> maps;
  for (const auto& d : g.dirs) {
    double y[9];
    ShEvalAll(2, d, y);
    double r = 0;
    for (int k = 0; k < 9; ++k) r += c[k] * y[k];
    maps.push_back(cv::Mat(2, 2, CV_32FC3, cv::Scalar::all(r)));
  }
  auto fit = Fit(g, maps, FitMethod::kLs, 2);
  ASSERT_TRUE(fit.ok()) << fit.error().ToString();
  for (int k = 0; k < 9; ++k) {
    // Float samples through a condition number of ~1e2..1e3: a few 1e-5 of error.
    EXPECT_NEAR(fit->model.coefficients()[k].at<cv::Vec3f>(0, 0)[0], c[k], 2e-3) << k;
  }
  EXPECT_LT(fit->model.info().loo_rmse, 1e-5);
}

TEST(FitMethods, RegularisedLeastSquaresBeatsThePapersQuadratureByAWideMargin) {
  const Grid g = RigGrid();
  const Scene s = MakeScene(3);
  const auto maps = Render(s, g.dirs, 0.002);
  const auto off = OffGrid();
  std::printf("| method | order | terms | LOO RMSE | off-grid RMSE vs truth |\n");
  double quad_best = 1e9, rls_best = 1e9;
  for (FitMethod m : {FitMethod::kQuadrature, FitMethod::kLs, FitMethod::kRls}) {
    for (int order = 1; order <= 4; ++order) {
      auto fit = Fit(g, maps, m, order);
      if (!fit.ok()) {
        std::printf("| %s | %d | %d | refused: %s |\n", FitMethodName(m), order,
                    (order + 1) * (order + 1), fit.error().message.c_str());
        continue;
      }
      const double err = HeldOutRms(fit->model, s, off);
      std::printf("| %s | %d | %d | %.5f | %.5f |\n", FitMethodName(m), order,
                  (order + 1) * (order + 1), fit->model.info().loo_rmse, err);
      if (m == FitMethod::kQuadrature) quad_best = std::min(quad_best, err);
      if (m == FitMethod::kRls) rls_best = std::min(rls_best, err);
    }
  }
  EXPECT_LT(rls_best * 10, quad_best);
}

int ExpectedSmallestWithinTolerance(const FitOutput& fit, double tolerance) {
  double best = 1e9;
  for (const auto& r : fit.selection.orders)
    if (r.supported) best = std::min(best, r.loo_rmse);
  for (const auto& r : fit.selection.orders)
    if (r.supported && r.loo_rmse <= best * (1 + tolerance)) return r.order;
  return -1;
}

TEST(FitOrderSelection, ChoosesTheSmallestOrderWithinToleranceOfTheBest) {
  const Grid g = RigGrid();
  const auto maps = Render(MakeScene(5), g.dirs, 0.002);
  auto fit = Fit(g, maps, FitMethod::kRls, -1);
  ASSERT_TRUE(fit.ok()) << fit.error().ToString();
  EXPECT_EQ(fit->selection.order, ExpectedSmallestWithinTolerance(*fit, 0.02));
}

TEST(FitOrderSelection, AMatteSceneGetsOrderOneAndAGlossyOneMore) {
  // A Lambertian patch lit from its front hemisphere: rho = albedo * N.L is linear in L, so
  // order 1 holds all of it; anything more fits the noise. Gloss needs more.
  const Grid g = RigGrid();
  auto matte = Fit(g, Render(MakeScene(5, 0.0), g.dirs, 0.002), FitMethod::kRls, -1);
  auto glossy = Fit(g, Render(MakeScene(5, 1.0), g.dirs, 0.002), FitMethod::kRls, -1);
  ASSERT_TRUE(matte.ok() && glossy.ok());
  std::printf("chosen order: matte %d, glossy %d\n", matte->selection.order,
              glossy->selection.order);
  EXPECT_EQ(matte->selection.order, 1);
  EXPECT_GT(glossy->selection.order, matte->selection.order);
}

TEST(FitRefusals, UnsupportedOrdersAreRefusedNotFittedToGarbage) {
  const Grid g = RigGrid();
  const auto maps = Render(MakeScene(1), g.dirs);
  // 49 terms from 40 poses: least squares refuses.
  auto too_many = Fit(g, maps, FitMethod::kLs, 6);
  ASSERT_FALSE(too_many.ok());
  EXPECT_NE(too_many.error().message.find("fewer terms than poses"), std::string::npos);
  // 25 terms on a 90°x30° patch: ill-conditioned, least squares refuses with the number.
  auto ill = Fit(g, maps, FitMethod::kLs, 4);
  ASSERT_FALSE(ill.ok());
  EXPECT_NE(ill.error().message.find("condition number"), std::string::npos);
  // Regularised least squares gives a stable fit at the same order: bounded values.
  auto rls = Fit(g, maps, FitMethod::kRls, 6);
  ASSERT_TRUE(rls.ok()) << rls.error().ToString();
  double mx = 0;
  for (const auto& d : OffGrid()) {
    double lo, hi;
    cv::minMaxLoc(rls->model.EvaluateRho(d).reshape(1), &lo, &hi);
    mx = std::max({mx, std::fabs(lo), std::fabs(hi)});
  }
  EXPECT_LT(mx, 2.0);
}

TEST(FitMissingSamples, PixelsAreFittedFromTheirValidSamplesOrFlagged) {
  const Grid g = RigGrid();
  const Scene s = MakeScene(9);
  auto maps = Render(s, g.dirs);
  std::vector<cv::Mat> valid;
  for (size_t i = 0; i < maps.size(); ++i) valid.push_back(cv::Mat(s.h, s.w, CV_8U, cv::Scalar(1)));
  // Pixel (0,0): 8 poses saturated (invented garbage, flagged). Pixel (0,1): only 5 valid.
  for (int i = 0; i < 8; ++i) {
    maps[i * 5].at<cv::Vec3f>(0, 0) = cv::Vec3f(1e4, 1e4, 1e4);
    valid[i * 5].at<uint8_t>(0, 0) = 0;
  }
  for (size_t i = 5; i < maps.size(); ++i) valid[i].at<uint8_t>(0, 1) = 0;
  FitInput in;
  in.radiance = maps;
  in.directions = g.dirs;
  in.weights = g.weights;
  in.valid = valid;
  FitOptions o;
  o.order = 2;
  auto fit = FitModel(in, o);
  ASSERT_TRUE(fit.ok());
  EXPECT_EQ(fit->missing.pixels_with_missing, 2u);
  EXPECT_EQ(fit->missing.flagged, 1u);
  ASSERT_FALSE(fit->model.valid().empty());
  EXPECT_EQ(fit->model.valid().at<uint8_t>(0, 1), 0);
  EXPECT_EQ(fit->model.valid().at<uint8_t>(0, 0), 1);
  // The garbage never reaches the fit: pixel (0,0) predicts like a clean fit of its pixel.
  auto clean = Fit(g, Render(s, g.dirs), FitMethod::kRls, 2);
  ASSERT_TRUE(clean.ok());
  for (const auto& d : OffGrid()) {
    const float a = fit->model.EvaluateRho(d).at<cv::Vec3f>(0, 0)[1];
    const float b = clean->model.EvaluateRho(d).at<cv::Vec3f>(0, 0)[1];
    EXPECT_NEAR(a, b, 0.05);
    EXPECT_LT(std::fabs(a), 2.0f);
  }
  // Flagged pixels render black.
  EXPECT_EQ(fit->model.EvaluateRho(g.dirs[0]).at<cv::Vec3f>(0, 1)[0], 0.0f);
}

TEST(FitNoise, LeaveOneOutErrorTracksTheNoiseLevel) {
  const Grid g = RigGrid();
  // A scene that is exactly SH order 1 plus noise σ: LOO RMSE ≈ σ·sqrt(1 + leverage).
  std::vector<cv::Mat> maps;
  std::mt19937 rng(4);
  std::normal_distribution<double> n01;
  const double sigma = 0.01;
  for (const auto& d : g.dirs) {
    cv::Mat m(16, 16, CV_32FC3);
    for (auto it = m.begin<cv::Vec3f>(); it != m.end<cv::Vec3f>(); ++it)
      for (int c = 0; c < 3; ++c)
        (*it)[c] = static_cast<float>(0.5 + 0.3 * d[2] + 0.1 * d[0] + sigma * n01(rng));
    maps.push_back(m);
  }
  auto fit = Fit(g, maps, FitMethod::kLs, 1);
  ASSERT_TRUE(fit.ok());
  EXPECT_GT(fit->model.info().loo_rmse, sigma);
  EXPECT_LT(fit->model.info().loo_rmse, sigma * 1.15);
}

TEST(FitRegion, ExtrapolationOutsideTheSampledLampsIsDetected) {
  const Grid g = RigGrid();
  auto fit = Fit(g, Render(MakeScene(2), g.dirs), FitMethod::kRls, 2);
  ASSERT_TRUE(fit.ok());
  const Model& m = fit->model;
  EXPECT_NEAR(m.info().sample_spacing_deg, 10.0, 0.5);
  EXPECT_TRUE(m.CheckRegion(LightDirection(45, 15)).inside);
  EXPECT_TRUE(m.CheckRegion(LightDirection(90, 30)).inside);
  const RegionCheck far = m.CheckRegion(LightDirection(-40, 0));
  EXPECT_FALSE(far.inside);
  EXPECT_NEAR(far.nearest_deg, 40, 0.5);
  EXPECT_FALSE(m.CheckRegion(LightDirection(45, 60)).inside);
}

TEST(FitSpaceTransform, ForwardAndInverseAreConsistent) {
  for (FitSpace sp : {FitSpace::kLinear, FitSpace::kSrgb, FitSpace::kLog}) {
    FitTransform t;
    t.space = sp;
    std::vector<float> v = {0.0f, 0.001f, 0.02f, 0.18f, 0.5f, 1.0f, 3.0f};
    std::vector<float> w = v;
    t.ForwardInPlace(w.data(), w.size());
    for (size_t i = 0; i < v.size(); ++i) EXPECT_NEAR(w[i], t.Forward(v[i]), 1e-5);
    t.InverseInPlace(w.data(), w.size());
    for (size_t i = 0; i < v.size(); ++i) EXPECT_NEAR(w[i], v[i], 1e-5 + 1e-5 * v[i]);
  }
}

TEST(LampRadiance, CalibratedFromAReferencePatch) {
  std::vector<cv::Mat> maps;
  for (int i = 0; i < 5; ++i) {
    cv::Mat m(10, 10, CV_32FC3, cv::Scalar(0.1, 0.2, 0.3 + 0.01 * i));  // B G R
    maps.push_back(m);
  }
  auto e = CalibrateLampRadiance(maps, {2, 2, 4, 4}, 0.5);
  ASSERT_TRUE(e.ok());
  EXPECT_NEAR((*e)[0], 0.32 / 0.5, 1e-5);  // R: median of 0.30..0.34
  EXPECT_NEAR((*e)[2], 0.1 / 0.5, 1e-5);   // B
  EXPECT_FALSE(CalibrateLampRadiance(maps, {8, 8, 4, 4}, 0.5).ok());
}

TEST(SelectionTable, SaysIllConditionedAndGivesTheErrorRelativeToTheSamples) {
  Selection sel;
  sel.data_rms = 0.5;
  OrderReport fine;
  fine.order = 1, fine.terms = 4, fine.supported = true, fine.loo_rmse = 0.05, fine.condition = 3.2;
  OrderReport deficient = fine;
  deficient.order = 4, deficient.terms = 25, deficient.loo_rmse = 0.01;
  deficient.condition = std::numeric_limits<double>::infinity(), deficient.lambda_relative = 1e-3;
  OrderReport refused;
  refused.order = 5, refused.terms = 36, refused.refusal = "more terms than poses";
  sel.orders = {fine, deficient, refused};
  const std::string md = SelectionTable(sel, "linear");
  EXPECT_NE(md.find("| 1 | 4 | yes | 0.05 | 10.00% | 3.2 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 4 | 25 | yes | 0.01 | 2.00% | ill-conditioned"), std::string::npos) << md;
  EXPECT_EQ(md.find("inf"), std::string::npos) << md;
  EXPECT_NE(md.find("no: more terms than poses"), std::string::npos) << md;
  EXPECT_EQ(LooRelativeCell(0.1, 0), "");
}

TEST(FitReportMarkdown, ARankDeficientOrderIsCalledIllConditionedNotInf) {
  FitOutput out;
  OrderReport fine;
  fine.order = 1, fine.terms = 4, fine.supported = true, fine.loo_rmse = 0.05, fine.condition = 3.2;
  fine.solved_condition = 3.2;
  OrderReport deficient = fine;
  deficient.order = 4, deficient.terms = 25, deficient.loo_rmse = 0.01;
  deficient.condition = std::numeric_limits<double>::infinity(), deficient.lambda_relative = 1e-3;
  deficient.solved_condition = 40;
  out.selection.orders = {fine, deficient};
  out.selection.order = 4;
  const std::string md = FitReportMarkdown(out, FitOptions{});
  EXPECT_NE(md.find("| 1 | 4 | 0.05 | 3.2 | 3.2 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 4 | 25 | 0.01 | ill-conditioned (rank deficient; regularised by λ) | 40 |"),
            std::string::npos)
      << md;
  EXPECT_EQ(md.find("| inf"), std::string::npos) << md;
}

}  // namespace
}  // namespace rig
