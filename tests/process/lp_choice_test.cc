// The choice across families per byte: a scene that relight's HSH holds exactly and PCA's
// candidates cannot takes the HSH in 8-bit planes, written as relight's web folder whose
// bytes and renders are what the choice estimated; without the bases it is PCA's own choice.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "process/export/lp_choice.h"
#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/model/any/load_model.h"
#include "process/model/pca/pca.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

std::vector<Vec3> SpreadLights(int rings, int per_ring) {
  std::vector<Vec3> out;
  for (int r = 0; r < rings; ++r) {
    const double e = (15.0 + 60.0 * r / std::max(1, rings - 1)) * M_PI / 180;
    for (int i = 0; i < per_ring; ++i) {
      const double a = (i + 0.37 * r) * 2 * M_PI / per_ring;
      out.push_back({std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)});
    }
  }
  return out;
}

// Every pixel's colour channels an HSH of 9 terms of their own, smooth across the image: 27
// independent functions of the light, which PCA's largest default candidate (18) cannot span.
LightSamples HshScene(int w, int h, const std::vector<Vec3>& lights, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  struct Field { double a, fx, fy, px, py; };
  std::vector<Field> f(27);
  for (auto& q : f) q = {u(rng), 1 + 4 * u(rng), 1 + 4 * u(rng), 6.28 * u(rng), 6.28 * u(rng)};
  LightSamples s;
  s.width = w;
  s.height = h;
  s.directions = lights;
  s.values.resize(static_cast<size_t>(w) * h * lights.size() * 3);
  double weights[kMaxRelightTerms];
  for (size_t l = 0; l < lights.size(); ++l) {
    RelightWeights(RelightType::kHsh, 9, lights[l], weights);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c) {
          double v = 0;
          for (int j = 0; j < 9; ++j) {
            const Field& q = f[j * 3 + c];
            const double field = std::sin(q.fx * x / w + q.px) * std::cos(q.fy * y / h + q.py);
            v += weights[j] * (j == 0 ? 300 + 40 * field : 16 * q.a * field);
          }
          const size_t p = static_cast<size_t>(y) * w + x;
          s.values[(p * lights.size() + l) * 3 + c] =
              static_cast<uint8_t>(std::clamp(std::nearbyint(v), 3.0, 249.0));
        }
  }
  return s;
}

TEST(LpChoice, AnHshSceneTakesTheHshItHoldsWrittenAsEstimated) {
  const auto lights = SpreadLights(4, 10);
  LightSamples s = HshScene(128, 112, lights, 7);
  MaskLdrSamples(&s);
  PcaChoiceOptions o;
  o.max_bytes_per_pixel = 12;
  auto fit = FitLpAuto(s, nullptr, o);
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  const LpChoice& ch = fit->choice;
  ASSERT_EQ(ch.family, "hsh") << ch.reason;
  ASSERT_GE(ch.basis_chosen, 0);
  const BasisCandidate& b = ch.bases[ch.basis_chosen];
  EXPECT_EQ(b.target.terms, 9) << ch.reason;
  double pca_best = 0;
  for (const auto& c : ch.pca.candidates) pca_best = std::max(pca_best, c.psnr_db);
  EXPECT_GT(b.psnr_db, pca_best + 3) << "hsh " << b.psnr_db << " dB, pca's best " << pca_best;
  EXPECT_GT(b.psnr_db, 38) << "the scene is an HSH: only 8-bit rounding and the planes' JPEG remain";
  EXPECT_EQ(ch.pca.chosen, -1);

  // Written as relight's web folder: its bytes are the estimate (the crop is the whole image),
  // and its renders at lights it never saw are the scene's.
  const fs::path dir = fs::path(::testing::TempDir()) / "lp_choice_hsh";
  fs::remove_all(dir);
  ASSERT_TRUE(fit->model->Save(dir.string()).ok());
  EXPECT_EQ(RelightWebType(dir.string()), "hsh");
  const double bpp = static_cast<double>(ModelBytesOnDisk(dir.string())) / s.pixels();
  EXPECT_NEAR(bpp, b.bytes_per_pixel, 0.1 * b.bytes_per_pixel);
  auto back = ReadRelightWeb(dir.string());
  ASSERT_TRUE(back.ok()) << back.error().message;
  const auto unseen = SpreadLights(3, 7);
  const LightSamples truth = HshScene(128, 112, unseen, 7);
  double sse = 0;
  for (size_t l = 0; l < unseen.size(); ++l) {
    const cv::Mat r = RenderRelight(*back, unseen[l]);
    for (size_t p = 0; p < truth.pixels(); ++p)
      for (int c = 0; c < 3; ++c) {
        const double d = std::clamp(r.ptr<float>()[p * 3 + 2 - c], 0.0f, 255.0f) - truth.value(p, l, c);
        sse += d * d;
      }
  }
  const double psnr = 10 * std::log10(255.0 * 255 / (sse / (3.0 * truth.pixels() * unseen.size())));
  EXPECT_GT(psnr, 36) << "the written hsh at 21 unseen lights";
  fs::remove_all(dir);
}

TEST(LpChoice, WithoutTheBasesItIsPcasOwnChoice) {
  const auto lights = SpreadLights(4, 10);
  LightSamples s = HshScene(96, 80, lights, 3);
  MaskLdrSamples(&s);
  PcaChoiceOptions o;
  auto comps = ComputePcaComponents(s, o.base, LargestCandidate(o));
  ASSERT_TRUE(comps.ok());
  auto alone = ChoosePca(s, *comps, o);
  auto lp = ChooseLpModel(PcaChoiceInputOf(s, comps->subset), *comps, o, false);
  ASSERT_TRUE(alone.ok() && lp.ok());
  EXPECT_TRUE(lp->bases.empty());
  EXPECT_EQ(lp->family, "pca-bilinear");
  EXPECT_EQ(lp->pca.chosen, alone->chosen);
  EXPECT_EQ(lp->pca.options.components, alone->options.components);
  EXPECT_EQ(lp->reason, alone->reason);
  // With them, one rule for both families: a PCA pick is the smallest candidate of either
  // family within the tolerance of the best.
  auto both = ChooseLpModel(PcaChoiceInputOf(s, comps->subset), *comps, o, true);
  ASSERT_TRUE(both.ok());
  EXPECT_EQ(both->bases.size(), LpChoiceBases().size() * o.qualities.size());
  double chosen_bpp = both->basis_chosen >= 0 ? both->bases[both->basis_chosen].bytes_per_pixel
                                               : both->pca.candidates[both->pca.chosen].bytes_per_pixel;
  for (const auto& c : both->bases) {
    if (c.within_budget && c.psnr_db >= both->best_psnr_db - o.tolerance_db) {
      EXPECT_GE(c.bytes_per_pixel, chosen_bpp);
    }
  }
  for (const auto& c : both->pca.candidates) {
    if (c.within_budget && c.psnr_db >= both->best_psnr_db - o.tolerance_db) {
      EXPECT_GE(c.bytes_per_pixel, chosen_bpp);
    }
  }
}

}  // namespace
}  // namespace rig
