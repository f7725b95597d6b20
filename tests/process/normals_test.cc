// Photometric stereo against the simulator's exact normals: plain and robust least squares on
// unshadowed surfaces, where each fails (cast shadows, gloss), and a near lamp with and without
// its per-pixel correction. Prints the figures of docs/lights.md.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "process/geometry/photometric_stereo.h"
#include "process/geometry/sphere_lights.h"
#include "sim/scene.h"

namespace rig {
namespace {

struct Capture {
  LightStack stack;
  cv::Mat unshadowed;   // lit (rho > 0) in every image
  cv::Mat cast_shadow;  // facing every lamp (N.L > 0) but dark in at least one image
};

std::vector<Vec3> GridDirections() {
  std::vector<Vec3> d;
  for (int v = 0; v <= 30; v += 10)
    for (int h = 0; h <= 90; h += 10) d.push_back(LightDirection(h, v));
  return d;
}

Capture Render(const SimScene& scene) {
  Capture c;
  c.stack.width = scene.width();
  c.stack.height = scene.height();
  c.stack.directions = GridDirections();
  c.unshadowed = cv::Mat(scene.height(), scene.width(), CV_8UC1, cv::Scalar(1));
  c.cast_shadow = cv::Mat(scene.height(), scene.width(), CV_8UC1, cv::Scalar(0));
  const cv::Mat n = scene.Normals();
  for (size_t k = 0; k < c.stack.directions.size(); ++k) {
    const Vec3& l = c.stack.directions[k];
    cv::Mat rad = scene.Radiance(l, {1, 1, 1});
    c.stack.linear.push_back(rad);
    c.stack.names.push_back(std::to_string(k));
    for (int y = 0; y < rad.rows; ++y)
      for (int x = 0; x < rad.cols; ++x) {
        const float* p = rad.ptr<float>(y) + 3 * x;
        const float* nn = n.ptr<float>(y) + 3 * x;
        const bool dark = p[0] + p[1] + p[2] <= 0;
        if (dark) c.unshadowed.at<uint8_t>(y, x) = 0;
        if (dark && nn[0] * l[0] + nn[1] * l[1] + nn[2] * l[2] > 0.05)
          c.cast_shadow.at<uint8_t>(y, x) = 1;
      }
  }
  return c;
}

cv::Mat Material(const SimScene& s, SimMaterialId id, const cv::Mat& base) {
  cv::Mat m = s.MaterialIds() == static_cast<uint8_t>(id);
  m /= 255;
  return m.mul(base);
}

SimScene Scene(const std::string& kind, int w = 160, int h = 120, double lamp_mm = 0) {
  SimConfig sim;
  sim.scene = kind;
  sim.width = w;
  sim.height = h;
  sim.matte_sphere = true;
  sim.lamp_distance_mm = lamp_mm;
  return *SimScene::Create(sim);
}

TEST(PhotometricStereo, ExactOnALambertianSceneBothWays) {
  const SimScene scene = Scene("matte");
  Capture c = Render(scene);
  for (bool robust : {false, true}) {
    PsOptions o;
    o.robust = robust;
    auto ps = PhotometricStereo(c.stack, c.stack.directions, o);
    ASSERT_TRUE(ps.ok());
    auto e = NormalError(ps->normals, scene.Normals(), c.unshadowed);
    std::printf("matte scene, unshadowed (%zu px), %s: mean %.3f deg, p95 %.3f deg\n", e.pixels,
                robust ? "robust" : "plain LS", e.mean_deg, e.p95_deg);
    EXPECT_GT(e.pixels, 10000u);
    EXPECT_LT(e.mean_deg, 0.1);
    // Albedo: I / (N.L) is radiance_scale * a / pi.
    const cv::Mat a = scene.Albedo();
    double worst = 0;
    for (int y = 0; y < a.rows; ++y)
      for (int x = 0; x < a.cols; ++x)
        if (c.unshadowed.at<uint8_t>(y, x))
          for (int ch = 0; ch < 3; ++ch) {
            const double t = a.ptr<float>(y)[3 * x + ch] * scene.radiance_scale() / std::numbers::pi;
            worst = std::max(worst, std::abs(ps->albedo.ptr<float>(y)[3 * x + ch] / t - 1));
          }
    EXPECT_LT(worst, 0.01);
  }
}

TEST(PhotometricStereo, RobustRemovesASharpHighlightPlainLeastSquaresKeeps) {
  // "sharp": a Lambertian plane, a sphere with a sharp lobe (ks 0.5, n 300), no cast shadow.
  const SimScene scene = Scene("sharp");
  Capture c = Render(scene);
  PsOptions plain, robust;
  plain.robust = false;
  auto a = PhotometricStereo(c.stack, c.stack.directions, plain);
  auto b = PhotometricStereo(c.stack, c.stack.directions, robust);
  ASSERT_TRUE(a.ok() && b.ok());
  const cv::Mat sphere = Material(scene, SimMaterialId::kSphere, c.unshadowed);
  const cv::Mat plane = Material(scene, SimMaterialId::kPlane, c.unshadowed);
  auto ea = NormalError(a->normals, scene.Normals(), sphere);
  auto eb = NormalError(b->normals, scene.Normals(), sphere);
  auto pa = NormalError(a->normals, scene.Normals(), plane);
  auto pb = NormalError(b->normals, scene.Normals(), plane);
  std::printf("| \"sharp\" scene | pixels | plain LS mean / p95 (deg) | robust mean / p95 (deg) |\n");
  std::printf("| Lambertian plane, unshadowed | %zu | %.2f / %.2f | %.2f / %.2f |\n", pa.pixels,
              pa.mean_deg, pa.p95_deg, pb.mean_deg, pb.p95_deg);
  std::printf("| sphere with a sharp lobe, unshadowed | %zu | %.2f / %.2f | %.2f / %.2f |\n",
              ea.pixels, ea.mean_deg, ea.p95_deg, eb.mean_deg, eb.p95_deg);
  EXPECT_LT(pb.mean_deg, 0.1);
  EXPECT_LT(eb.mean_deg, 0.6 * ea.mean_deg);
}

TEST(PhotometricStereo, WhereItFailsOnTheFullScene) {
  // "full": a broad gloss on the plane (ks 0.05, n 10), a glossy sphere (0.5, 120), a
  // glossy relief (0.25, 40) and the sphere's cast shadow.
  const SimScene scene = Scene("full");
  Capture c = Render(scene);
  PsOptions unmasked, plain, robust;
  unmasked.robust = plain.robust = false;
  unmasked.dark_fraction = 0;
  auto u = PhotometricStereo(c.stack, c.stack.directions, unmasked);
  auto a = PhotometricStereo(c.stack, c.stack.directions, plain);
  auto b = PhotometricStereo(c.stack, c.stack.directions, robust);
  ASSERT_TRUE(u.ok() && a.ok() && b.ok());
  const cv::Mat n = scene.Normals();
  struct Region { const char* name; cv::Mat mask; };
  const Region regions[] = {
      {"matte sphere, unshadowed", Material(scene, SimMaterialId::kMatte, c.unshadowed)},
      {"plane (broad gloss), unshadowed", Material(scene, SimMaterialId::kPlane, c.unshadowed)},
      {"plane (broad gloss), in a cast shadow in some images", Material(scene, SimMaterialId::kPlane, c.cast_shadow)},
      {"glossy sphere, unshadowed", Material(scene, SimMaterialId::kSphere, c.unshadowed)},
  };
  std::printf("| \"full\" scene | pixels | LS, no shadow mask | LS, masked | robust, masked |\n");
  std::vector<AngularError> eu, ea, eb;
  for (const auto& r : regions) {
    eu.push_back(NormalError(u->normals, n, r.mask));
    ea.push_back(NormalError(a->normals, n, r.mask));
    eb.push_back(NormalError(b->normals, n, r.mask));
    std::printf("| %s | %zu | %.2f / %.2f | %.2f / %.2f | %.2f / %.2f |\n", r.name, ea.back().pixels,
                eu.back().mean_deg, eu.back().p95_deg, ea.back().mean_deg, ea.back().p95_deg,
                eb.back().mean_deg, eb.back().p95_deg);
  }
  EXPECT_LT(eb[0].mean_deg, 0.5);             // Lambertian: exact
  EXPECT_LT(ea[2].mean_deg, eu[2].mean_deg);  // the shadow mask matters in cast shadows
  EXPECT_LT(eb[3].mean_deg, ea[3].mean_deg);  // the robust estimator on the glossy sphere
  EXPECT_GT(eb[1].mean_deg, 2.0);             // a broad lobe is not an outlier: it fails
}

TEST(PhotometricStereo, NearLampCorrectionRemovesTheFarLampError) {
  // A lamp 300 mm from a 100 mm field (6 scene units): the far-lamp assumption tilts every
  // pixel's light by up to ~15 deg at the corners and changes its irradiance by the fall-off.
  const SimScene scene = Scene("matte", 160, 120, 300);
  Capture c = Render(scene);
  PsOptions far, near0, near, plane;
  near0.lamp.distance_mm = near.lamp.distance_mm = plane.lamp.distance_mm = 300;
  near0.lamp.mm_per_px = near.lamp.mm_per_px = plane.lamp.mm_per_px = 100.0 / scene.height();
  // [light_frame] surface_depth_mm: the plane's true depth at the image centre.
  plane.lamp.plane_z_mm = scene.plane_depth_mm();
  // The scene's true depth: its plane lies ~50 mm behind the arm's centre of rotation.
  near.lamp.depth_mm = cv::Mat(scene.height(), scene.width(), CV_32FC1);
  for (int y = 0; y < scene.height(); ++y)
    for (int x = 0; x < scene.width(); ++x)
      near.lamp.depth_mm.at<float>(y, x) =
          static_cast<float>(scene.SurfacePoint(x, y)[2] * scene.mm_per_unit());
  auto a = PhotometricStereo(c.stack, c.stack.directions, far);
  auto b0 = PhotometricStereo(c.stack, c.stack.directions, near0);
  auto b = PhotometricStereo(c.stack, c.stack.directions, near);
  auto bp = PhotometricStereo(c.stack, c.stack.directions, plane);
  ASSERT_TRUE(a.ok() && b0.ok() && b.ok() && bp.ok());
  const cv::Mat n = scene.Normals();
  // Relit error: albedo * max(0, N.L) against the far-lamp truth rho at off-grid directions.
  auto relit = [&](const PsResult& ps) {
    double se = 0, st = 0;
    for (const auto& hv : {std::pair{45.0, 20.0}, {15.0, 25.0}, {75.0, 5.0}, {35.0, 12.0}}) {
      const Vec3 l = LightDirection(hv.first, hv.second);
      const cv::Mat t = scene.Brdf(l);
      for (int y = 0; y < t.rows; ++y)
        for (int x = 0; x < t.cols; ++x) {
          if (!c.unshadowed.at<uint8_t>(y, x)) continue;
          const float* nn = ps.normals.ptr<float>(y) + 3 * x;
          const double nl = std::max(0.0, nn[0] * l[0] + nn[1] * l[1] + nn[2] * l[2]);
          for (int ch = 0; ch < 3; ++ch) {
            const double d = ps.albedo.ptr<float>(y)[3 * x + ch] * nl - t.ptr<float>(y)[3 * x + ch];
            se += d * d;
            st += t.ptr<float>(y)[3 * x + ch] * t.ptr<float>(y)[3 * x + ch];
          }
        }
    }
    return std::sqrt(se / st);
  };
  auto ea = NormalError(a->normals, n, c.unshadowed), eb0 = NormalError(b0->normals, n, c.unshadowed),
       eb = NormalError(b->normals, n, c.unshadowed), ebp = NormalError(bp->normals, n, c.unshadowed);
  const double ra = relit(*a), rb0 = relit(*b0), rb = relit(*b), rbp = relit(*bp);
  std::printf("| lamp 300 mm from a 100 mm field (matte scene) | normals mean / p95 (deg) | relit rel. RMS | PS time (s) |\n");
  std::printf("| far-lamp assumption | %.2f / %.2f | %.4f | %.3f |\n", ea.mean_deg, ea.p95_deg, ra, a->time_s);
  std::printf("| near lamp, surface taken at z = 0 | %.2f / %.2f | %.4f | %.3f |\n", eb0.mean_deg,
              eb0.p95_deg, rb0, b0->time_s);
  std::printf("| near lamp, surface_depth_mm = %g | %.2f / %.2f | %.4f | %.3f |\n",
              plane.lamp.plane_z_mm, ebp.mean_deg, ebp.p95_deg, rbp, bp->time_s);
  std::printf("| near lamp, the surface's depth known | %.2f / %.2f | %.4f | %.3f |\n", eb.mean_deg,
              eb.p95_deg, rb, b->time_s);
  EXPECT_GT(ea.mean_deg, 2.0);
  EXPECT_LT(eb.mean_deg, 0.1);
  EXPECT_LT(rb, ra / 10);
  EXPECT_LT(eb0.mean_deg, ea.mean_deg);
  EXPECT_LT(rbp, rb0);  // the plane's depth given: closer than the plane through the centre
}

TEST(PhotometricStereo, HeightFromNormalsRecoversAPeriodicRelief) {
  // z = A sin(2 pi x / W) cos(2 pi y / H), x right and y up in pixels (y = H - row).
  const int w = 64, h = 48;
  const double amp = 3, kx = 2 * std::numbers::pi / w, ky = 2 * std::numbers::pi / h;
  cv::Mat nrm(h, w, CV_32FC3), truth(h, w, CV_32FC1);
  for (int r = 0; r < h; ++r)
    for (int x = 0; x < w; ++x) {
      const double y = h - r;
      const double zx = amp * kx * std::cos(kx * x) * std::cos(ky * y);
      const double zy = -amp * ky * std::sin(kx * x) * std::sin(ky * y);
      const double len = std::sqrt(zx * zx + zy * zy + 1);
      nrm.at<cv::Vec3f>(r, x) = cv::Vec3f(-zx / len, -zy / len, 1 / len);
      truth.at<float>(r, x) = amp * std::sin(kx * x) * std::cos(ky * y);
    }
  cv::Mat z = IntegrateNormals(nrm);
  double err = 0;
  for (int r = 0; r < h; ++r)
    for (int x = 0; x < w; ++x) err = std::max(err, static_cast<double>(std::abs(z.at<float>(r, x) - truth.at<float>(r, x))));
  EXPECT_LT(err, 0.1 * amp);
}

TEST(PhotometricStereo, PlaceLampTakesTheSessionsFrameUnlessTold) {
  LightFrameConfig frame;
  frame.lamp_distance_mm = 500;
  frame.field_height_mm = 100;
  frame.surface_depth_mm = -50;
  auto from_session = PlaceLamp({}, &frame, 200);
  ASSERT_TRUE(from_session.ok()) << from_session.error().ToString();
  EXPECT_TRUE(from_session->near());
  EXPECT_DOUBLE_EQ(from_session->distance_mm, 500);
  EXPECT_DOUBLE_EQ(from_session->mm_per_px, 0.5);
  EXPECT_DOUBLE_EQ(from_session->plane_z_mm, -50);
  LampPlacement far;
  far.far = true;
  auto told_far = PlaceLamp(far, &frame, 200);
  ASSERT_TRUE(told_far.ok());
  EXPECT_FALSE(told_far->near());
  auto none = PlaceLamp({}, nullptr, 200);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->near());
  LampPlacement no_field;
  no_field.lamp_distance_mm = 400;
  auto refused = PlaceLamp(no_field, nullptr, 200);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().ToString().find("--field-height-mm"), std::string::npos);
  LampPlacement too_deep{400, 100, -350, false};
  auto deep = PlaceLamp(too_deep, nullptr, 200);
  ASSERT_FALSE(deep.ok());
  EXPECT_NE(deep.error().ToString().find("--surface-depth-mm"), std::string::npos);
}

}  // namespace
}  // namespace rig
