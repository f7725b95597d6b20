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

// The sphere centres' depths (mm) of the simulator's truth, in the spheres' image order.
std::vector<double> TrueDepthsMm(const SimScene& scene, const std::vector<SphereCircle>& found) {
  std::vector<double> out;
  for (const auto& f : found)
    for (const auto& t : scene.CalibrationSpheres())
      if (t.material == SimMaterialId::kChrome && std::hypot(t.cx_px - f.cx, t.cy_px - f.cy) < 2)
        out.push_back(t.center[2] * scene.mm_per_unit());
  return out;
}

TEST(LampPosition, TwoSpheresPlaceANearLampWithinTheirResolution) {
  // The simulator's exact near lamp, 300 mm from the arm's centre over a 100 mm field, the arm
  // off by h +2.5, v -1.5 deg; two chrome spheres (33.6 and 26.4 px, 14 and 11 mm), their
  // depths given from the truth.
  SimConfig sim = CalibrationScene(2, "matte");
  sim.lamp_distance_mm = 300;
  LightFrameConfig frame;
  frame.h_offset_deg = 2.5;
  frame.v_offset_deg = -1.5;
  Capture c = Render(sim, frame);
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  ASSERT_EQ(found->size(), 2u);
  // As a far lamp, the spheres see it from two places up to 19 deg apart: refused.
  auto far = CalibrateFromSpheres(c.stack, *found, CameraModel{});
  ASSERT_FALSE(far.ok());
  EXPECT_THAT(far.error().ToString(), HasSubstr("disagree"));
  SphereField field;
  field.field_height_mm = sim.field_height_mm;
  field.depth_mm = TrueDepthsMm(c.scene, *found);
  ASSERT_EQ(field.depth_mm.size(), 2u);
  auto cal = CalibrateFromSpheres(c.stack, *found, CameraModel{}, {}, 3.0, field);
  ASSERT_TRUE(cal.ok()) << cal.error().ToString();
  ASSERT_TRUE(cal->lamp.has_value());
  const LampEstimate& lamp = *cal->lamp;
  ASSERT_TRUE(lamp.near);
  // Per image: the fix against the lamp's true place, and its own 1-sigma.
  std::vector<double> pos_err, sigma;
  double worst_residual = 0;
  for (size_t k = 0; k < c.truth.size(); ++k) {
    worst_residual = std::max(worst_residual, lamp.residual_deg[k]);
    const LampFix& f = lamp.fixes[k];
    if (!f.determined) continue;
    double e2 = 0;
    for (int i = 0; i < 3; ++i) e2 += std::pow(f.position_mm[i] - 300 * c.truth[k][i], 2);
    pos_err.push_back(std::sqrt(e2));
    sigma.push_back(f.sigma_mm);
  }
  std::sort(pos_err.begin(), pos_err.end());
  std::sort(sigma.begin(), sigma.end());
  const double median_sigma = sigma[sigma.size() / 2];
  double sum = 0, worst = 0, sum_mean = 0;
  for (size_t k = 0; k < c.truth.size(); ++k) {
    const double e = AngleDeg(cal->directions[k], c.truth[k]);
    sum += e;
    worst = std::max(worst, e);
    Vec3 m = {0, 0, 0};
    for (const auto& h : cal->highlights[k])
      for (int i = 0; i < 3; ++i) m[i] += h.direction[i];
    sum_mean += AngleDeg(m, c.truth[k]);
  }
  const size_t n = c.truth.size();
  std::printf("near lamp 300 mm, depths given: %d of %zu images determined, median distance "
              "%.2f mm, median ray miss %.3f mm, median position error %.2f mm (max %.2f), "
              "median 1-sigma %.2f mm, resolvable to %.0f mm\n", lamp.determined, n,
              lamp.distance_mm, lamp.median_miss_mm, pos_err[pos_err.size() / 2], pos_err.back(),
              median_sigma, lamp.resolvable_mm);
  std::printf("directions from the arm's centre vs truth: mean %.3f deg, max %.3f deg (the "
              "spheres' mean direction: mean %.3f deg); largest ray residual %.3f deg\n",
              sum / n, worst, sum_mean / n, worst_residual);
  // The tolerance is the spheres' own resolution: a tenth of a pixel of highlight on the
  // smaller sphere (26.4 px) is 0.43 deg of direction; over the two spheres' ~100 mm baseline
  // that is the 1-sigma the fixes report (median_sigma, ~2-3 % of 300 mm).
  EXPECT_GE(2 * lamp.determined, static_cast<int>(n));
  EXPECT_NEAR(lamp.distance_mm, 300, median_sigma);
  EXPECT_LT(median_sigma, 0.05 * 300);
  EXPECT_LT(sum / n, 0.5);
  EXPECT_LT(worst, 0.5);
  EXPECT_LT(worst_residual, 1.0);
  auto fit = FitLightFrame(c.stack.h_deg, c.stack.v_deg, cal->directions);
  ASSERT_TRUE(fit.ok());
  std::printf("fitted light frame: h_offset %.3f (truth 2.5), v_offset %.3f (truth -1.5)\n",
              fit->frame.h_offset_deg, fit->frame.v_offset_deg);
  EXPECT_NEAR(fit->frame.h_offset_deg, 2.5, 0.2);
  EXPECT_NEAR(fit->frame.v_offset_deg, -1.5, 0.2);

  // The default assumption (every sphere resting on the plane through the arm's centre) where
  // the simulator's spheres float 15 and 35 mm behind it: the distance it gives, printed.
  SphereField resting;
  resting.field_height_mm = sim.field_height_mm;
  auto assumed = CalibrateFromSpheres(c.stack, *found, CameraModel{}, {}, 3.0, resting);
  ASSERT_TRUE(assumed.ok()) << assumed.error().ToString();
  std::printf("depths assumed (resting on the plane, z = r: %.1f, %.1f mm; truth %.1f, %.1f): "
              "near %d, median distance %.2f mm, median ray miss %.3f mm\n",
              assumed->lamp->depth_mm[0], assumed->lamp->depth_mm[1], field.depth_mm[0],
              field.depth_mm[1], assumed->lamp->near, assumed->lamp->distance_mm,
              assumed->lamp->median_miss_mm);
}

TEST(LampPosition, TheSpheresDepthsFittedFromTheArmKeepingTheLampsDistance) {
  // The depths not known: fitted with the lamp's one distance over all 40 images, from the
  // resting default (11 and 14 mm; truth -35 and -15 mm).
  SimConfig sim = CalibrationScene(2, "matte");
  sim.lamp_distance_mm = 300;
  LightFrameConfig frame;
  frame.h_offset_deg = 2.5;
  frame.v_offset_deg = -1.5;
  Capture c = Render(sim, frame);
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  ASSERT_EQ(found->size(), 2u);
  const auto truth = TrueDepthsMm(c.scene, *found);
  SphereField field;
  field.field_height_mm = sim.field_height_mm;
  field.fit_depths = true;
  auto cal = CalibrateFromSpheres(c.stack, *found, CameraModel{}, {}, 3.0, field);
  ASSERT_TRUE(cal.ok()) << cal.error().ToString();
  const LampEstimate& lamp = *cal->lamp;
  ASSERT_TRUE(lamp.depth_fitted);
  double sum = 0, worst = 0;
  for (size_t k = 0; k < c.truth.size(); ++k) {
    const double e = AngleDeg(cal->directions[k], c.truth[k]);
    sum += e;
    worst = std::max(worst, e);
  }
  std::printf("depths fitted: %.2f +- %.2f, %.2f +- %.2f mm (truth %.1f, %.1f; start %.1f, %.1f); "
              "fit's distance %.2f +- %.2f mm, rms %.2f; median distance %.2f mm, median miss "
              "%.3f mm; directions mean %.3f, max %.3f deg\n", lamp.depth_mm[0],
              lamp.depth_sigma_mm[0], lamp.depth_mm[1], lamp.depth_sigma_mm[1], truth[0], truth[1],
              lamp.depth_start_mm[0], lamp.depth_start_mm[1], lamp.fit_distance_mm,
              lamp.fit_distance_sigma_mm, lamp.fit_rms, lamp.distance_mm, lamp.median_miss_mm,
              sum / c.truth.size(), worst);
  // Within the fit's 1-sigma (a tenth of a pixel of highlight on every ray, not averaged down
  // over the images: ~10 mm here), and a fifth of the start's error at most (46 and 29 mm). The
  // depths matter at the scale of a few mm: a depth error d shifts a grazing lamp by d, ~0.2 deg
  // per mm at 300 mm.
  for (int j = 0; j < 2; ++j) {
    EXPECT_NEAR(lamp.depth_mm[j], truth[j], lamp.depth_sigma_mm[j]) << j;
    EXPECT_LT(std::abs(lamp.depth_mm[j] - truth[j]),
              0.2 * std::abs(lamp.depth_start_mm[j] - truth[j])) << j;
  }
  EXPECT_NEAR(lamp.fit_distance_mm, 300, lamp.fit_distance_sigma_mm);
  // The directions: half a degree on average, a degree at worst (0.2 deg with the true depths).
  EXPECT_LT(sum / c.truth.size(), 0.5);
  EXPECT_LT(worst, 1.0);
  // A far lamp has no parallax to fit depths from: said so.
  Capture f = Render(CalibrationScene(2, "matte"), {});
  auto far = CalibrateFromSpheres(f.stack, *found, CameraModel{}, {}, 3.0, field);
  ASSERT_FALSE(far.ok());
  EXPECT_THAT(far.error().ToString(), HasSubstr("far"));
}

TEST(LampPosition, TheDepthFitIsExactOnExactHighlights) {
  // Highlights computed from the geometry (the point whose mirror sends +z to the lamp), no
  // image: the fit itself must return the depths and the distance, from 25 mm away.
  const int width = 320, height = 240;
  const double mm_per_px = 100.0 / height;
  SphereCalibration cal;
  cal.spheres = {{46.0, 38.4, 33.6}, {289.6, 28.8, 26.4}};
  const std::vector<double> depth = {-15, -35};
  for (int h = 0; h <= 90; h += 10)
    for (int v = 0; v <= 30; v += 10) {
      const Vec3 l = LightDirection(h, v);
      const Vec3 lamp = {300 * l[0], 300 * l[1], 300 * l[2]};
      std::vector<Highlight> hs;
      for (size_t j = 0; j < 2; ++j) {
        const SphereCircle& c = cal.spheres[j];
        const Vec3 centre = {(c.cx - width / 2.0) * mm_per_px, (height / 2.0 - c.cy) * mm_per_px,
                             depth[j]};
        const double r = c.r * mm_per_px;
        Vec3 n = {0, 0, 1}, d{};
        for (int it = 0; it < 200; ++it) {
          const Vec3 p = {centre[0] + r * n[0], centre[1] + r * n[1], centre[2] + r * n[2]};
          Vec3 to = {lamp[0] - p[0], lamp[1] - p[1], lamp[2] - p[2]};
          const double tn = std::sqrt(to[0] * to[0] + to[1] * to[1] + to[2] * to[2]);
          d = {to[0] / tn, to[1] / tn, to[2] / tn};
          Vec3 b = {d[0], d[1], d[2] + 1};
          const double bn = std::sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
          n = {b[0] / bn, b[1] / bn, b[2] / bn};
        }
        Highlight hl;
        hl.normal = n;
        hl.direction = d;
        hs.push_back(hl);
      }
      cal.highlights.push_back(hs);
    }
  SphereField field;
  field.field_height_mm = 100;
  field.depth_mm = {10, -10};
  field.fit_depths = true;
  auto est = EstimateLamp(cal, width, height, CameraModel{}, field);
  ASSERT_TRUE(est.ok()) << est.error().ToString();
  EXPECT_NEAR(est->depth_mm[0], -15, 1e-3);
  EXPECT_NEAR(est->depth_mm[1], -35, 1e-3);
  EXPECT_NEAR(est->fit_distance_mm, 300, 1e-3);
  EXPECT_NEAR(est->distance_mm, 300, 1e-3);
}

TEST(LampPosition, AFarLampIsReportedFarNeverAsADistance) {
  Capture c = Render(CalibrationScene(2, "matte"), {});
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  ASSERT_EQ(found->size(), 2u);
  SphereField field;
  field.field_height_mm = 100;
  field.depth_mm = TrueDepthsMm(c.scene, *found);
  auto cal = CalibrateFromSpheres(c.stack, *found, CameraModel{}, {}, 3.0, field);
  ASSERT_TRUE(cal.ok()) << cal.error().ToString();
  ASSERT_TRUE(cal->lamp.has_value());
  std::printf("far lamp: %d of %zu images determined; resolvable to %.0f mm; first note: %s\n",
              cal->lamp->determined, c.truth.size(), cal->lamp->resolvable_mm,
              cal->lamp->fixes[0].note.c_str());
  EXPECT_FALSE(cal->lamp->near);
  EXPECT_EQ(cal->lamp->determined, 0);
  EXPECT_EQ(cal->lamp->distance_mm, 0);
  EXPECT_GT(cal->lamp->resolvable_mm, 300);  // a 300 mm lamp is within what they resolve
  // The directions stay the spheres' mean, as without the field.
  auto plain = CalibrateFromSpheres(c.stack, *found, CameraModel{});
  ASSERT_TRUE(plain.ok());
  for (size_t k = 0; k < c.truth.size(); ++k)
    EXPECT_LT(AngleDeg(cal->directions[k], plain->directions[k]), 1e-9);
}

TEST(LampPosition, OneSphereAndOverlappingSpheresAreClearErrors) {
  SimConfig sim = CalibrationScene(1, "matte");
  sim.lamp_distance_mm = 300;
  Capture c = Render(sim, {});
  auto found = DetectChromeSpheres(c.stack);
  ASSERT_TRUE(found.ok()) << found.error().ToString();
  ASSERT_EQ(found->size(), 1u);
  SphereField field;
  field.field_height_mm = 100;
  auto one = CalibrateFromSpheres(c.stack, *found, CameraModel{}, {}, 3.0, field);
  ASSERT_FALSE(one.ok());
  EXPECT_EQ(one.error().code, ErrorCode::kInvalidInput);
  EXPECT_THAT(one.error().ToString(), HasSubstr("two or more chrome spheres"));
  auto twice = *found;
  twice.push_back(twice[0]);
  twice[1].cx += 1;
  auto overlap = CalibrateFromSpheres(c.stack, twice, CameraModel{}, {}, 30.0, field);
  ASSERT_FALSE(overlap.ok());
  EXPECT_THAT(overlap.error().ToString(), HasSubstr("overlap"));
}

TEST(LampPosition, RaysCrossingParallelAndDiverging) {
  // Two rays through (10, 20, 300) from (-50, 0, 0) and (50, 5, -10): the point, exactly.
  const Vec3 lamp = {10, 20, 300};
  auto ray = [&](const Vec3& o) {
    Vec3 d = {lamp[0] - o[0], lamp[1] - o[1], lamp[2] - o[2]};
    const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    return LampRay{o, {d[0] / n, d[1] / n, d[2] / n}, 0.005};
  };
  LampFix x = TriangulateRays({ray({-50, 0, 0}), ray({50, 5, -10})});
  ASSERT_TRUE(x.determined) << x.note;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(x.position_mm[i], lamp[i], 1e-6);
  EXPECT_LT(x.miss_mm, 1e-6);
  EXPECT_GT(x.sigma_mm, 0);
  // Its distance known, the direction from the arm's centre comes back from the rays alone.
  std::vector<double> res;
  const double d = std::sqrt(10 * 10 + 20 * 20 + 300 * 300);
  const Vec3 u = LampDirectionAtDistance({ray({-50, 0, 0}), ray({50, 5, -10})}, d, {0, 0, 1}, &res);
  EXPECT_LT(AngleDeg(u, lamp), 1e-6);
  EXPECT_LT(res[0], 1e-6);
  // Parallel rays: no point.
  LampFix p = TriangulateRays({{{-50, 0, 0}, {0, 0, 1}, 0.005}, {{50, 0, 0}, {0, 0, 1}, 0.005}});
  EXPECT_FALSE(p.determined);
  EXPECT_THAT(p.note, HasSubstr("parallel"));
  // Diverging rays: the nearest point lies behind the spheres.
  const double a = 0.01;
  LampFix v = TriangulateRays({{{-50, 0, 0}, {-a, 0, 1}, 0.005}, {{50, 0, 0}, {a, 0, 1}, 0.005}});
  EXPECT_FALSE(v.determined);
  EXPECT_THAT(v.note, HasSubstr("diverge"));
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
