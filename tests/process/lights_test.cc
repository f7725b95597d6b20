// Light calibration from chrome spheres against the simulator's exact scene: the sphere found,
// every pose's direction within 0.5 deg of truth, the arm's offsets within 0.2 deg, and the
// refusals (no highlight, a saturated blob, spheres that disagree) naming the image.
#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "process/geometry/sphere_lights.h"
#include "sim/scene.h"

namespace rig {
namespace {

using ::testing::HasSubstr;

struct Capture {
  LightStack stack;
  std::vector<Vec3> truth;
  SimScene scene;
};

// The 40 poses of the default grid through `frame`, rendered exactly (radiance, no camera).
Capture Render(const SimConfig& sim, const LightFrameConfig& frame) {
  auto scene = SimScene::Create(sim);
  EXPECT_TRUE(scene.ok());
  Capture c{{}, {}, *scene};
  c.stack.width = sim.width;
  c.stack.height = sim.height;
  for (int v = 0; v <= 30; v += 10)
    for (int h = 0; h <= 90; h += 10) {
      const Vec3 l = LightDirection(h, v, frame);
      c.stack.linear.push_back(c.scene.Radiance(l, {1, 1, 1}));
      c.stack.names.push_back(fmt::format("h{:03d}_v{:02d}", h, v));
      c.stack.h_deg.push_back(h);
      c.stack.v_deg.push_back(v);
      c.stack.directions.push_back(LightDirection(h, v));
      c.truth.push_back(l);
    }
  return c;
}

SimConfig CalibrationScene(int chrome, const std::string& kind = "full") {
  SimConfig sim;
  sim.scene = kind;
  sim.chrome_spheres = chrome;
  sim.matte_sphere = true;
  return sim;
}

TEST(SphereLights, FindsTheChromeSphereAndItsCircleWithinATenthOfAPixel) {
  LightFrameConfig frame;
  Capture c = Render(CalibrationScene(1), frame);
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  ASSERT_EQ(found->size(), 1u);  // not the glossy main sphere, not the matte one
  const auto truth = c.scene.CalibrationSpheres()[0];
  EXPECT_NEAR((*found)[0].cx, truth.cx_px, 0.1);
  EXPECT_NEAR((*found)[0].cy, truth.cy_px, 0.1);
  EXPECT_NEAR((*found)[0].r, truth.r_px, 0.1);
}

TEST(SphereLights, FindsTheCircleWithinATenthOfAPixelThroughABlurAndANoiseFloor) {
  // What a camera does to the limb: a lens's blur (Gaussian, sigma 1 px, on linear radiance)
  // and the noise floor of a merged radiance map, which lifts the sphere's unlit limb (0 in
  // the exact scene) to a level near the background's dark checker cells (~2200 here): in a
  // dry-run session the floor is ~7% of them. With the limb's log contrast down to that of a
  // checker edge 2 px outside it, the steepest edge of a ray is no longer the limb's.
  Capture c = Render(CalibrationScene(1, "matte"), {});
  for (auto& m : c.stack.linear) {
    cv::GaussianBlur(m, m, cv::Size(0, 0), 1.0);
    m += cv::Scalar::all(150);
  }
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  ASSERT_EQ(found->size(), 1u);
  const auto truth = c.scene.CalibrationSpheres()[0];
  std::printf("blurred, with a floor: found (%.3f, %.3f) r %.3f, truth (%.2f, %.2f) r %.2f\n",
              (*found)[0].cx, (*found)[0].cy, (*found)[0].r, truth.cx_px, truth.cy_px, truth.r_px);
  EXPECT_NEAR((*found)[0].cx, truth.cx_px, 0.1);
  EXPECT_NEAR((*found)[0].cy, truth.cy_px, 0.1);
  EXPECT_NEAR((*found)[0].r, truth.r_px, 0.1);
}

TEST(SphereLights, DirectionsWithinHalfADegreeAndArmOffsetsWithinAFifth) {
  LightFrameConfig frame;
  frame.h_offset_deg = 2.5;
  frame.v_offset_deg = -1.5;
  Capture c = Render(CalibrationScene(1), frame);
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  for (const auto& f : *found) std::printf("found sphere (%.2f, %.2f) r %.2f\n", f.cx, f.cy, f.r);
  ASSERT_EQ(found->size(), 1u);
  auto cal = CalibrateFromSpheres(c.stack, *found, CameraModel{});
  ASSERT_TRUE(cal.ok()) << cal.error().ToString();
  double sum = 0, worst = 0;
  for (size_t k = 0; k < c.truth.size(); ++k) {
    const double e = AngleDeg(cal->directions[k], c.truth[k]);
    sum += e;
    worst = std::max(worst, e);
  }
  const double mean = sum / c.truth.size();
  std::printf("sphere directions vs truth over %zu poses: mean %.3f deg, max %.3f deg\n",
              c.truth.size(), mean, worst);
  EXPECT_LT(mean, 0.5);
  EXPECT_LT(worst, 0.5);
  auto fit = FitLightFrame(c.stack.h_deg, c.stack.v_deg, cal->directions);
  ASSERT_TRUE(fit.ok());
  std::printf("fitted light frame: h_offset %.3f (truth 2.5), v_offset %.3f (truth -1.5), rms "
              "%.3f deg, tilt %.3f deg\n", fit->frame.h_offset_deg, fit->frame.v_offset_deg,
              fit->rms_deg, fit->tilt_deg);
  EXPECT_EQ(fit->frame.h_sign, 1);
  EXPECT_EQ(fit->frame.v_sign, 1);
  EXPECT_NEAR(fit->frame.h_offset_deg, 2.5, 0.2);
  EXPECT_NEAR(fit->frame.v_offset_deg, -1.5, 0.2);
  EXPECT_EQ(fit->residual_deg.size(), 40u);
}

TEST(SphereLights, FitsAFlippedAxisAndATilt) {
  std::vector<double> h, v;
  std::vector<Vec3> m;
  LightFrameConfig truth;
  truth.h_sign = -1;
  truth.h_offset_deg = 88;
  truth.v_offset_deg = 1;
  const double tilt = 2.0 * std::numbers::pi / 180;
  for (int vv = 0; vv <= 30; vv += 10)
    for (int hh = 0; hh <= 90; hh += 10) {
      h.push_back(hh);
      v.push_back(vv);
      Vec3 d = LightDirection(hh, vv, truth);
      m.push_back({std::cos(tilt) * d[0] - std::sin(tilt) * d[1],
                   std::sin(tilt) * d[0] + std::cos(tilt) * d[1], d[2]});
    }
  auto fit = FitLightFrame(h, v, m);
  ASSERT_TRUE(fit.ok());
  EXPECT_EQ(fit->frame.h_sign, -1);
  EXPECT_NEAR(fit->tilt_deg, 2.0, 0.05);
  EXPECT_LT(fit->rms_with_tilt_deg, 0.01);
  EXPECT_GT(fit->rms_deg, 0.5);  // the tilt the config cannot hold shows in the residual
}

TEST(SphereLights, PerspectiveModelRecoversTheSameDirectionsWithALongLens) {
  // The simulator's camera is orthographic; a perspective model with a very long lens must
  // agree with it, and a short one must not.
  Capture c = Render(CalibrationScene(1), {});
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok());
  CameraModel tele{1e6}, wide{200};
  auto a = CalibrateFromSpheres(c.stack, *found, tele);
  auto b = CalibrateFromSpheres(c.stack, *found, wide);
  ASSERT_TRUE(a.ok() && b.ok());
  double ea = 0, eb = 0;
  for (size_t k = 0; k < c.truth.size(); ++k) {
    ea = std::max(ea, AngleDeg(a->directions[k], c.truth[k]));
    eb = std::max(eb, AngleDeg(b->directions[k], c.truth[k]));
  }
  EXPECT_LT(ea, 0.5);
  EXPECT_GT(eb, 2.0);
}

TEST(SphereLights, RefusesAMatteSphereAndASaturatedBlobNamingTheImage) {
  Capture c = Render(CalibrationScene(1), {});
  const auto spheres = c.scene.CalibrationSpheres();
  SphereCircle matte{spheres[1].cx_px, spheres[1].cy_px, spheres[1].r_px};
  auto r = LocateHighlight(c.stack, 3, matte, CameraModel{});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidInput);
  EXPECT_THAT(r.error().ToString(), HasSubstr("h030_v00"));
  EXPECT_THAT(r.error().ToString(), HasSubstr("no highlight"));
  // An overexposed 8-bit image: the chrome highlight clipped over a wide blob.
  LightStack ldr = c.stack;
  SphereCircle chrome{spheres[0].cx_px, spheres[0].cy_px, spheres[0].r_px};
  ldr.clipped.assign(ldr.size(), cv::Mat());
  for (size_t k = 0; k < ldr.size(); ++k) {
    // The sphere's diffuse near the top of the range: the lobe clips over ~5 px around its
    // peak (2% of the disc).
    cv::Mat sat = ldr.linear[k] * 2.8e-3;
    cv::Mat clip;
    cv::min(sat, 1.0, sat);
    ldr.linear[k] = sat;
    cv::Mat grey = LinearGrey(sat);
    clip = grey >= 0.999;
    clip /= 255;
    ldr.clipped[k] = clip;
  }
  HighlightOptions strict;
  strict.max_blob_fraction = 0.01;
  auto s = LocateHighlight(ldr, 0, chrome, CameraModel{}, strict);
  ASSERT_FALSE(s.ok());
  EXPECT_THAT(s.error().ToString(), HasSubstr("h000_v00"));
  EXPECT_THAT(s.error().ToString(), HasSubstr("saturated"));
}

TEST(SphereLights, TwoSpheresAgreeUnderAFarLampAndDisagreementIsRefused) {
  Capture c = Render(CalibrationScene(2), {});
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  for (const auto& f : *found) std::printf("found sphere (%.2f, %.2f) r %.2f\n", f.cx, f.cy, f.r);
  for (const auto& t : c.scene.CalibrationSpheres()) std::printf("truth (%.2f, %.2f) r %.2f\n", t.cx_px, t.cy_px, t.r_px);
  ASSERT_EQ(found->size(), 2u);
  auto cal = CalibrateFromSpheres(c.stack, *found, CameraModel{});
  ASSERT_TRUE(cal.ok()) << cal.error().ToString();
  for (double d : cal->sphere_disagreement_deg) EXPECT_LT(d, 0.6);
  // A sphere's circle given a few pixels off: its normals, so its directions, are wrong.
  auto moved = *found;
  moved[1].cx += 4;
  auto bad = CalibrateFromSpheres(c.stack, moved, CameraModel{}, {}, 1.0);
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(bad.error().ToString(), HasSubstr("disagree"));
  EXPECT_THAT(bad.error().ToString(), HasSubstr("_v"));  // names the image
}

TEST(SphereLights, NoSphereInTheSceneIsAClearError) {
  SimConfig sim;
  sim.scene = "matte";
  Capture c = Render(sim, {});
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_FALSE(found.ok());
  EXPECT_THAT(found.error().ToString(), HasSubstr("no chrome sphere found"));
}

}  // namespace
}  // namespace rig
