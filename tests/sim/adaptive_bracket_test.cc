// Adaptive brackets: the plan covers the metered range with the fewest frames; on the
// simulator it takes at most 60% of the fixed bracket's frames at no more than 1.1x its HDR
// error (the bar), every pose measured against the scene's exact radiance.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "capture/plan/adaptive_bracket.h"
#include "capture/plan/bracket.h"
#include "config/config.h"
#include "sim/adaptive_eval.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

TEST(AdaptiveBracket, CoversTheMeteredRangeWithOverlappingWindows) {
  // Radiance from 1 to 1000 (10 stops); the window is 6 stops wide, overlap 0.5: two frames.
  std::vector<float> metered;
  for (int i = 0; i <= 1000; ++i) metered.push_back(float(std::pow(1000.0, i / 1000.0)));
  const auto offered = ThirdStopShutterSpeeds(Seconds(1.0 / 8000), Seconds(30));
  AdaptiveBracketOptions o;
  o.x_lo = 1;
  o.x_hi = 64;
  o.bottom_fraction = 0;
  o.top_fraction = 0;
  auto plan = PlanAdaptiveBracket(metered, offered, o);
  ASSERT_TRUE(plan.ok()) << plan.error().ToString();
  ASSERT_EQ(plan->frames.size(), 2u);
  const double t0 = plan->frames[0].exposure.count(), t1 = plan->frames[1].exposure.count();
  EXPECT_LE(1000 * t0, 64 * 1.0001);         // the brightest is not clipped
  // The longest such speed: the next offered one would clip.
  auto next = std::upper_bound(offered.begin(), offered.end(), plan->frames[0].exposure);
  ASSERT_NE(next, offered.end());
  EXPECT_GT(1000 * next->count(), 64);
  EXPECT_LE(1 / t1, 1.0001);                   // the darkest is recorded
  EXPECT_GE(std::log2((64 / t1) / (1 / t0)), 0.5 - 1e-6);  // windows overlap by >= 0.5 stop
  EXPECT_EQ(plan->below_fraction, 0);
  EXPECT_EQ(plan->above_fraction, 0);
  for (const auto& f : plan->frames) EXPECT_FALSE(f.reason.empty());
}

TEST(AdaptiveBracket, StopsAtTheLongestAllowedAndSaysWhatStaysDark) {
  std::vector<float> metered(1000, 100.f);
  for (int i = 0; i < 100; ++i) metered[i] = 1e-6f;  // 10% far too dark
  const auto offered = ThirdStopShutterSpeeds(Seconds(1.0 / 8000), Seconds(30));
  AdaptiveBracketOptions o;
  o.x_lo = 1;
  o.x_hi = 64;
  o.bottom_fraction = 0;
  o.max_exposure = Seconds(1);
  auto plan = PlanAdaptiveBracket(metered, offered, o);
  ASSERT_TRUE(plan.ok());
  EXPECT_LE(plan->frames.back().exposure.count(), 1.0 + 1e-9);
  EXPECT_NEAR(plan->below_fraction, 0.1, 1e-9);
}

TEST(AdaptiveBracket, RefusesAnEmptyWindowOrMetering) {
  const auto offered = ThirdStopShutterSpeeds(Seconds(1.0 / 8000), Seconds(30));
  AdaptiveBracketOptions o;
  o.x_lo = 10;
  o.x_hi = 5;
  std::vector<float> m(10, 1.f);
  EXPECT_FALSE(PlanAdaptiveBracket(m, offered, o).ok());
  o.x_hi = 100;
  std::vector<float> dark(10, 0.f);
  EXPECT_FALSE(PlanAdaptiveBracket(dark, offered, o).ok());
}

TEST(AdaptiveBracket, OnTheSimulatorTakesAtMostSixtyPercentOfTheFramesAtTheSameError) {
  auto cfg = LoadConfigOrError(testing::SourceDir() + "/config/sim.toml");
  ASSERT_TRUE(cfg.ok()) << cfg.error().ToString();
  cfg->sim.width = 160;
  cfg->sim.height = 120;
  auto r = CompareAdaptiveBracket(*cfg, AdaptiveEvalOptions{});
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  std::printf("fixed %d frames, %.4f RMS, %.1f s; adaptive %d frames, %.4f RMS, %.1f s\n",
              r->fixed_frames, r->fixed_rms, r->fixed_capture_s, r->adaptive_frames,
              r->adaptive_rms, r->adaptive_capture_s);
  EXPECT_LE(r->adaptive_frames, 0.6 * r->fixed_frames);
  EXPECT_LE(r->adaptive_rms, 1.1 * r->fixed_rms);
  EXPECT_LT(r->adaptive_capture_s, r->fixed_capture_s);
  // Pixels the adaptive bracket leaves black in every frame (and the fixed one does not): few.
  EXPECT_LE(r->adaptive_flagged, r->fixed_flagged + r->scored / 3 / 10000);
  for (const auto& p : r->poses) EXPECT_LE(p.adaptive_rms, 1.5 * p.fixed_rms) << p.pose << ": " << p.plan;
}

}  // namespace
}  // namespace rig
