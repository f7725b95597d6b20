// Next-best-light (process/model/light_choice.h): the choice goes where a synthetic highlight
// is, spreads evenly on a scene a linear trend explains, is deterministic, never reads an image
// before choosing it (unchosen files deleted: the same choice), and on the shared icon beats
// an even spread at the lights chosen by neither (skipped when the capture is absent).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <tuple>
#include <utility>

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "process/evaluate/light_subset.h"
#include "process/model/any/rti_fit.h"
#include "process/export/light_choice_files.h"
#include "process/model/light_choice.h"
#include "process/model/lp.h"
#include "tests/support/lp_capture.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

double AngleDeg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a[0] * b[0] + a[1] * b[1] + a[2] * b[2], -1.0, 1.0)) * 180 / M_PI;
}

Vec3 Unit(double x, double y, double z) {
  const double n = std::sqrt(x * x + y * y + z * z);
  return {x / n, y / n, z / n};
}

// 72 lights evenly over the hemisphere above 10 deg of elevation (a Fibonacci spiral).
std::vector<Vec3> DenseLights() {
  std::vector<Vec3> out;
  const int n = 72;
  const double zmin = std::sin(10 * M_PI / 180), golden = M_PI * (3 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1 - (1 - zmin) * (i + 0.5) / n, r = std::sqrt(1 - z * z);
    out.push_back({r * std::cos(golden * i), r * std::sin(golden * i), z});
  }
  return out;
}

// The centre of the highlight's region of light directions: azimuth 20 deg, elevation 35 deg.
const Vec3 kHighlight = Unit(std::cos(20 * M_PI / 180), std::sin(20 * M_PI / 180),
                             std::tan(35 * M_PI / 180));

// A 32x32 scene: a matte surface whose normals tilt up to ~17 deg, and a glossy patch (the
// left third) whose normals lie around the half vector of kHighlight, so its sharp lobe lights
// up only for lights within ~20 deg of kHighlight. `gloss` 0: matte everywhere.
cv::Mat Render(const Vec3& l, double gloss) {
  cv::Mat img(32, 32, CV_8UC3);
  const Vec3 h = Unit(kHighlight[0], kHighlight[1], kHighlight[2] + 1);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      const double u = x / 31.0 - 0.5, v = y / 31.0 - 0.5;
      Vec3 n = Unit(0.6 * u, 0.6 * v, 1);
      double spec = 0;
      if (x < 11) {
        n = Unit(h[0] + 0.15 * u, h[1] + 0.15 * v, h[2]);
        const double ndl = n[0] * l[0] + n[1] * l[1] + n[2] * l[2];
        const Vec3 r = {2 * ndl * n[0] - l[0], 2 * ndl * n[1] - l[1], 2 * ndl * n[2] - l[2]};
        spec = gloss * std::pow(std::max(0.0, r[2]), 80);
      }
      const double diffuse = 0.45 * std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
      for (int c = 0; c < 3; ++c)
        img.at<cv::Vec3b>(y, x)[c] = cv::saturate_cast<uint8_t>(
            255 * std::pow(std::min(1.0, (diffuse + spec) * (1 - 0.1 * c)), 1 / 2.2));
    }
  return img;
}

LightChoice Choose(const std::vector<Vec3>& dirs, double gloss, int count,
                   std::vector<int>* read_order = nullptr) {
  LightChoiceOptions o;
  o.count = count;
  auto reader = [&](int l) -> Result<cv::Mat> {
    if (read_order) read_order->push_back(l);
    return Render(dirs[l], gloss);
  };
  auto c = ChooseLights(dirs, reader, o);
  EXPECT_TRUE(c.ok()) << c.error().ToString();
  return *c;
}

int InRegion(const std::vector<Vec3>& dirs, const std::vector<int>& lights, double deg) {
  int n = 0;
  for (int l : lights) n += AngleDeg(dirs[l], kHighlight) < deg;
  return n;
}

TEST(LightChoice, PutsMoreLightsWhereTheHighlightIsThanAnEvenSpread) {
  const auto dirs = DenseLights();
  const LightChoice c = Choose(dirs, 3.0, 24);
  ASSERT_EQ(c.steps.size(), 24u);
  std::vector<int> after_seed;
  for (const auto& s : c.steps)
    if (!s.seed) after_seed.push_back(s.light);
  ASSERT_EQ(after_seed.size(), 16u);
  const std::vector<int> all = [] { std::vector<int> v(72); for (int i = 0; i < 72; ++i) v[i] = i; return v; }();
  const int region_all = InRegion(dirs, all, 30);
  const int region_adaptive = InRegion(dirs, after_seed, 30);
  const std::vector<int> even = FarthestPointLights(dirs, 24);
  const int region_even = InRegion(dirs, even, 30);
  // The 30-deg cap holds about a tenth of the candidates; an even spread puts a tenth there.
  EXPECT_LT(region_all, 12);
  EXPECT_GE(region_adaptive, 6) << "of 16 after the seed; candidates there: " << region_all;
  const std::vector<int> chosen = c.Chosen();
  const int region_chosen = InRegion(dirs, chosen, 30);
  EXPECT_GE(region_chosen, region_even + 3) << "chosen " << region_chosen << ", even " << region_even;
}

// The largest angle from any candidate to its nearest chosen light.
double CoverageDeg(const std::vector<Vec3>& dirs, const std::vector<int>& chosen) {
  double worst = 0;
  for (const Vec3& d : dirs) {
    double gap = 1e9;
    for (int k : chosen) gap = std::min(gap, AngleDeg(d, dirs[k]));
    worst = std::max(worst, gap);
  }
  return worst;
}

TEST(LightChoice, SpreadsEvenlyWhereALinearTrendExplainsTheScene) {
  // A matte plane: every pixel is albedo · n·l (8-bit), linear in l up to rounding, so the
  // model has (nearly) no error anywhere and the gaps decide: the chosen lights cover the
  // sphere about as well as the farthest-point spread, and far better than with a highlight.
  std::vector<Vec3> dirs = DenseLights();
  LightChoiceOptions o;
  o.count = 20;
  auto reader = [&](int l) -> Result<cv::Mat> {
    cv::Mat img(8, 8, CV_8UC3, cv::Scalar::all(std::round(200 * dirs[l][2])));
    return img;
  };
  auto c = ChooseLights(dirs, reader, o);
  ASSERT_TRUE(c.ok()) << c.error().ToString();
  const double matte = CoverageDeg(dirs, c->Chosen());
  const double even = CoverageDeg(dirs, FarthestPointLights(dirs, 20));
  EXPECT_LT(matte, 1.25 * even) << "matte " << matte << " deg, farthest point " << even;
  EXPECT_LT(InRegion(dirs, c->Chosen(), 30), InRegion(dirs, Choose(dirs, 3.0, 20).Chosen(), 30));
}

TEST(LightChoice, IsDeterministicAndReadsEachImageOnlyOnceAfterChoosingIt) {
  const auto dirs = DenseLights();
  std::vector<int> read_a, read_b;
  const LightChoice a = Choose(dirs, 3.0, 20, &read_a);
  const LightChoice b = Choose(dirs, 3.0, 20, &read_b);
  EXPECT_EQ(a.Chosen(), b.Chosen());
  for (size_t i = 0; i < a.steps.size(); ++i) EXPECT_EQ(a.steps[i].reason, b.steps[i].reason);
  // Read in the order chosen, each once, nothing else.
  EXPECT_EQ(read_a, a.Chosen());
  EXPECT_EQ(a.images_read, a.Chosen());
}

TEST(LightChoice, NeverReadsAnImageItDidNotChoose) {
  // An .lp capture on disk; the choice made once; then every unchosen image deleted and the
  // choice made again: it must succeed with the same lights, reasons and report.
  const std::string dir = testing::FreshTempDir("light_choice_files");
  const std::string lp = testing::WriteLpCapture(dir, 48, 40);
  LightChoiceOptions o;
  o.count = 14;
  auto first = ChooseLightsOfLp(lp, o, dir + "/sub.lp", dir + "/report.md");
  ASSERT_TRUE(first.ok()) << first.error().ToString();
  const std::string report = testing::ReadText(dir + "/report.md");
  auto entries = ReadLp(lp);
  ASSERT_TRUE(entries.ok());
  const std::vector<int> chosen = first->Chosen();
  int removed = 0;
  for (int l = 0; l < static_cast<int>(entries->size()); ++l)
    if (std::find(chosen.begin(), chosen.end(), l) == chosen.end()) {
      fs::remove((*entries)[l].image);
      ++removed;
    }
  EXPECT_EQ(removed, 36 - 14);
  auto again = ChooseLightsOfLp(lp, o, dir + "/sub2.lp", dir + "/report2.md");
  ASSERT_TRUE(again.ok()) << again.error().ToString();
  EXPECT_EQ(again->Chosen(), chosen);
  EXPECT_EQ(testing::ReadText(dir + "/report2.md"), report);
  // SUB.lp: the chosen images in the order chosen, with their directions, readable as a capture.
  auto sub = ReadLp(dir + "/sub.lp");
  ASSERT_TRUE(sub.ok()) << sub.error().ToString();
  ASSERT_EQ(sub->size(), 14u);
  for (size_t i = 0; i < sub->size(); ++i) {
    EXPECT_EQ(fs::canonical((*sub)[i].image), fs::canonical((*entries)[chosen[i]].image));
    EXPECT_LT(AngleDeg((*sub)[i].direction, (*entries)[chosen[i]].direction), 1e-3);
  }
  auto capture = LoadRtiCapture(dir + "/sub.lp");
  EXPECT_TRUE(capture.ok()) << capture.error().ToString();
}

TEST(LightChoice, RefusesMoreLightsThanTheCaptureHasNamingTheOption) {
  const auto dirs = DenseLights();
  LightChoiceOptions o;
  o.count = 73;
  auto c = ChooseLights(dirs, [](int) -> Result<cv::Mat> { return cv::Mat(); }, o);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().ToString().find("--choose"), std::string::npos) << c.error().ToString();
}

// ---- the shared icon (72 lights) ------------------------------------------------------


// The choice one light at a time (the rig's adaptive grid) proposes what ChooseLights chooses.
TEST(LightChooser, ProposingAndTakingOneAtATimeChoosesWhatChooseLightsChooses) {
  const auto dirs = DenseLights();
  const LightChoice whole = Choose(dirs, 3.0, 20);
  LightChoiceOptions o;
  o.count = 20;
  LightChooser chooser(dirs, o);
  for (;;) {
    auto next = chooser.Propose();
    ASSERT_TRUE(next.ok()) << next.error().ToString();
    if (next->stop) {
      EXPECT_NE(next->stop_reason.find("the count"), std::string::npos) << next->stop_reason;
      break;
    }
    ASSERT_TRUE(chooser.Take(next->step.light, Render(dirs[next->step.light], 3.0), next->step).ok());
  }
  EXPECT_EQ(chooser.choice().Chosen(), whole.Chosen());
  for (size_t i = 0; i < whole.steps.size(); ++i)
    EXPECT_EQ(chooser.choice().steps[i].reason, whole.steps[i].reason) << i;
}

TEST(LightChooser, RefusesALightTakenTwiceOrAnImageOfAnotherSize) {
  const auto dirs = DenseLights();
  LightChooser chooser(dirs, LightChoiceOptions{});
  ASSERT_TRUE(chooser.Take(3, Render(dirs[3], 0), {}).ok());
  auto twice = chooser.Take(3, Render(dirs[3], 0), {});
  ASSERT_FALSE(twice.ok());
  EXPECT_NE(twice.error().ToString().find("light 3"), std::string::npos) << twice.error().ToString();
  cv::Mat small;
  cv::resize(Render(dirs[4], 0), small, cv::Size(16, 16));
  EXPECT_FALSE(chooser.Take(4, small, {}).ok());
  EXPECT_FALSE(chooser.Take(999, Render(dirs[4], 0), {}).ok());
  EXPECT_EQ(chooser.taken(), 1);
}

// A cost per light: with the far half of the lights (negative y) ten times dearer, the model's
// choices after the seed go there less often than without the cost; the reason says so.
TEST(LightChooser, ACostPerLightSteersTheChoiceToTheCheapLights) {
  const auto dirs = DenseLights();
  auto run = [&](bool costed) {
    LightChoiceOptions o;
    o.count = 24;
    if (costed) o.cost_s = [&](int, int c) { return dirs[c][1] < 0 ? 10.0 : 1.0; };
    LightChooser chooser(dirs, o);
    int dear = 0;
    std::string reason;
    for (;;) {
      auto next = chooser.Propose();
      EXPECT_TRUE(next.ok());
      if (!next.ok() || next->stop) break;
      if (!next->step.seed) {
        dear += dirs[next->step.light][1] < 0;
        reason = next->step.reason;
      }
      EXPECT_TRUE(chooser.Take(next->step.light, Render(dirs[next->step.light], 3.0), next->step).ok());
    }
    return std::make_pair(dear, reason);
  };
  const auto [free_dear, free_reason] = run(false);
  const auto [costed_dear, costed_reason] = run(true);
  EXPECT_LT(costed_dear, free_dear);
  EXPECT_EQ(free_reason.find("per second"), std::string::npos);
  EXPECT_NE(costed_reason.find("per second of the rig's time"), std::string::npos) << costed_reason;
}

// The target: on a matte scene (a linear trend explains it) the predicted error over a
// region comes within the target of what every light would leave before the count (the stop
// says "the target"), and sooner than on a glossy one; with target 0 only the count stops.
// Names given, the reasons use them.
TEST(LightChooser, StopsAtTheTargetSoonerOnAMatteSceneThanOnAGlossyOneAndNamesTheLights) {
  const auto dirs = DenseLights();
  auto run = [&](double target, double gloss = 0.0) {
    LightChoiceOptions o;
    o.count = 60;
    o.target = target;
    // The region: the hemisphere sampled 4x denser than the lights (without one, the lights
    // not taken are the region, and taking every light would leave no error at them).
    for (int i = 0; i < 288; ++i) {
      const double zmin = std::sin(10 * M_PI / 180), golden = M_PI * (3 - std::sqrt(5.0));
      const double z = 1 - (1 - zmin) * (i + 0.5) / 288, r = std::sqrt(1 - z * z);
      o.region.push_back({r * std::cos(golden * i), r * std::sin(golden * i), z});
    }
    for (size_t i = 0; i < dirs.size(); ++i) o.names.push_back("L" + std::to_string(i));
    LightChooser chooser(dirs, o);
    std::string stop, reason;
    for (;;) {
      auto next = chooser.Propose();
      EXPECT_TRUE(next.ok());
      if (!next.ok()) break;
      if (next->stop) {
        stop = next->stop_reason;
        break;
      }
      if (!next->step.seed) {
        reason = next->step.reason;
        EXPECT_GE(next->step.region_rms + 1e-9, next->step.floor_rms);
      }
      EXPECT_TRUE(chooser.Take(next->step.light, Render(dirs[next->step.light], gloss), next->step).ok());
    }
    return std::make_tuple(chooser.taken(), stop, reason);
  };
  const auto [n_target, stop_target, reason] = run(0.1);
  const auto [n_count, stop_count, reason0] = run(0);
  const auto [n_glossy, stop_glossy, reason_glossy] = run(0.1, 3.0);
  std::printf("target 10%%: matte %d lights, glossy %d (%s)\n", n_target, n_glossy, stop_glossy.c_str());
  EXPECT_LT(n_target, 60);
  EXPECT_LT(n_target, n_glossy);
  EXPECT_NE(stop_target.find("the target"), std::string::npos) << stop_target;
  EXPECT_EQ(n_count, 60);
  EXPECT_NE(stop_count.find("the count"), std::string::npos) << stop_count;
  EXPECT_NE(reason0.find("(to L"), std::string::npos) << reason0;
  EXPECT_EQ(reason0.find("light "), std::string::npos) << reason0;
}

TEST(LightChoiceOnTheIcon, TwentyFourChosenBeatTwentyFourSpreadAtTheLightsInNeither) {
  const fs::path lp = fs::path(testing::SharedDir()) / "data/rti/neuralrti-example/dirs.lp";
  if (!fs::exists(lp)) GTEST_SKIP() << lp << " is not there";
  auto capture = LoadRtiCapture(lp.string());
  ASSERT_TRUE(capture.ok()) << capture.error().ToString();
  LightChoiceOptions o;
  o.count = 24;
  auto adaptive = ChooseLpLights(capture->entries, o);
  ASSERT_TRUE(adaptive.ok()) << adaptive.error().ToString();
  EXPECT_EQ(adaptive->images_read, adaptive->Chosen());
  const std::vector<int> even = FarthestPointLights(capture->samples.directions, 24);
  const std::vector<int> held = LightsInNone(capture->samples.lights(), {adaptive->Chosen(), even});
  ASSERT_GE(held.size(), 24u);
  const std::string tmp = testing::FreshTempDir("light_choice_icon") + "/model";
  auto a = ScoreLightSubset(*capture, adaptive->Chosen(), held, tmp);
  ASSERT_TRUE(a.ok()) << a.error().ToString();
  auto e = ScoreLightSubset(*capture, even, held, tmp);
  ASSERT_TRUE(e.ok()) << e.error().ToString();
  EXPECT_GT(a->psnr_mean_mse_db, e->psnr_mean_mse_db)
      << "adaptive " << a->psnr_mean_mse_db << " dB, even " << e->psnr_mean_mse_db << " dB";
}

}  // namespace
}  // namespace rig
