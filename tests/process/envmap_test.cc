// process/render/envmap: a small bright disc renders as the point lamp at its centre, a
// uniform map gives the analytic integral, rotating the map moves the light as a lamp's h,
// energy outside the model's region is reported, and bad maps are refused naming the file.
#include "process/render/envmap.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "process/model/light_direction.h"
#include "tests/support/run_rig.h"
#include "tests/support/synthetic_model.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

// SH order 2 on a 24x16 image, seeded coefficients around a constant term, lamps on h 0-90,
// v 0-30 (10° steps), capture lamp (2, 1.5, 1); one pixel flagged.
Model SyntheticModel() {
  Model model = testing::SyntheticShModel(11, 0.1f);
  model.valid() = cv::Mat(16, 24, CV_8U, cv::Scalar(1));
  model.valid().at<uint8_t>(3, 5) = 0;
  return model;
}

double AngleDeg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a[0] * b[0] + a[1] * b[1] + a[2] * b[2], -1.0, 1.0)) * 180 / M_PI;
}

// A 512x256 map, black but for a white disc of `radius_deg` around `centre`, its radiance
// scaled so that radiance × solid angle sums to 1 (a unit lamp), the solid angle of a texel
// computed here as (2π/W)(π/H)·cos(latitude).
cv::Mat DiscMap(const Vec3& centre, double radius_deg) {
  cv::Mat map(256, 512, CV_32FC3, cv::Scalar::all(0));
  double omega = 0;
  for (int r = 0; r < map.rows; ++r)
    for (int c = 0; c < map.cols; ++c) {
      const Vec3 d = EnvmapDirection((c + 0.5) / map.cols, (r + 0.5) / map.rows, 0);
      if (AngleDeg(d, centre) > radius_deg) continue;
      map.at<cv::Vec3f>(r, c) = cv::Vec3f(1, 1, 1);
      omega += (2 * M_PI / map.cols) * (M_PI / map.rows) * std::cos(M_PI * (0.5 - (r + 0.5) / map.rows));
    }
  return map / omega;
}

double RelativeError(const cv::Mat& a, const cv::Mat& b) {
  return cv::norm(a, b, cv::NORM_INF) / cv::norm(b, cv::NORM_INF);
}

cv::Mat PointLamp(const Model& m, const Vec3& d) {
  cv::Mat sum;
  m.AddLamp(d, {1, 1, 1}, &sum);
  return sum;
}

TEST(Envmap, MapCentreFacesTheCameraAndColumnsRunWithTheRigsH) {
  const Vec3 c = EnvmapDirection(0.5, 0.5, 0);
  EXPECT_NEAR(c[2], 1, 1e-12);
  const Vec3 d = EnvmapDirection(0.5 + 30.0 / 360, 0.5 - 15.0 / 180, 0);
  const Vec3 l = LightDirection(30, 15);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(d[i], l[i], 1e-12);
  const Vec3 r = EnvmapDirection(0.5, 0.5 - 15.0 / 180, 30);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(r[i], l[i], 1e-12);
  EXPECT_NEAR(EnvmapDirection(0.5, 0.0001, 0)[1], 1, 1e-6);  // top row: up
}

TEST(Envmap, SmallBrightDiscRendersAsThePointLampAtItsCentre) {
  const Model model = SyntheticModel();
  auto wrapped = WrapHarmonic(model);
  const Vec3 centre = LightDirection(45, 15);
  const cv::Mat map = DiscMap(centre, 2.5);
  const cv::Mat lamp = PointLamp(model, centre);
  EnvmapOptions o;
  auto projected = RenderEnvironment(*wrapped, &model, map, o);
  ASSERT_TRUE(projected.ok()) << projected.error().ToString();
  EXPECT_TRUE(projected->projected);
  EXPECT_EQ(projected->terms, 9);
  EXPECT_LT(RelativeError(projected->radiance, lamp), 0.01);
  EXPECT_LT(projected->outside_energy_fraction, 1e-12);
  EXPECT_EQ(projected->radiance.at<cv::Vec3f>(3, 5), cv::Vec3f(0, 0, 0));  // flagged stays 0
  o.force_sampling = true;
  o.samples = 64;
  auto sampled = RenderEnvironment(*wrapped, &model, map, o);
  ASSERT_TRUE(sampled.ok());
  EXPECT_FALSE(sampled->projected);
  EXPECT_GT(sampled->distinct_lamps, 1);
  EXPECT_LT(RelativeError(sampled->radiance, lamp), 0.01);
  // Not just any picture: a lamp 30° away differs by far more.
  EXPECT_GT(RelativeError(PointLamp(model, LightDirection(75, 15)), lamp), 0.05);
}

TEST(Envmap, UniformMapGivesTheAnalyticIntegral) {
  const Model model = SyntheticModel();
  auto wrapped = WrapHarmonic(model);
  cv::Mat map(256, 512, CV_32FC3, cv::Scalar::all(1));
  EnvmapOptions o;
  o.extrapolate = true;
  o.intensity = 0.5;
  auto out = RenderEnvironment(*wrapped, &model, map, o);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out->outside_energy_fraction, 0);
  // ∫ Y_00 dω = √(4π), ∫ Y_lm dω = 0 for l > 0: pixel = E · 0.5 · c_00 · √(4π).
  const double e_bgr[3] = {1.0, 1.5, 2.0};
  double worst = 0;
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 24; ++x) {
      if (y == 3 && x == 5) continue;
      for (int c = 0; c < 3; ++c) {
        const double want = e_bgr[c] * 0.5 * model.coefficients()[0].at<cv::Vec3f>(y, x)[c] *
                            std::sqrt(4 * M_PI);
        worst = std::max(worst, std::abs(out->radiance.at<cv::Vec3f>(y, x)[c] - want) / want);
      }
    }
  EXPECT_LT(worst, 1e-3);
  // Importance sampling converges to the same integral.
  o.force_sampling = true;
  o.samples = 4096;
  auto sampled = RenderEnvironment(*wrapped, &model, map, o);
  ASSERT_TRUE(sampled.ok());
  EXPECT_LT(RelativeError(sampled->radiance, out->radiance), 0.03);
  // Restricted to the sampled region, most of a uniform sphere is outside.
  o.extrapolate = false;
  o.force_sampling = false;
  auto restricted = RenderEnvironment(*wrapped, &model, map, o);
  ASSERT_TRUE(restricted.ok());
  EXPECT_GT(restricted->outside_energy_fraction, 0.8);
  EXPECT_LT(restricted->outside_energy_fraction, 1.0);
  EXPECT_LT(cv::mean(restricted->radiance)[1], cv::mean(out->radiance)[1]);
}

TEST(Envmap, RotatingTheMapMovesTheLightAsALampsH) {
  const Model model = SyntheticModel();
  auto wrapped = WrapHarmonic(model);
  const cv::Mat map = DiscMap(LightDirection(30, 15), 2.5);
  EnvmapOptions o;
  o.rotate_deg = 25;
  auto out = RenderEnvironment(*wrapped, &model, map, o);
  ASSERT_TRUE(out.ok());
  const cv::Mat moved = PointLamp(model, LightDirection(55, 15));
  const cv::Mat unmoved = PointLamp(model, LightDirection(30, 15));
  EXPECT_LT(RelativeError(out->radiance, moved), 0.01);
  EXPECT_GT(RelativeError(out->radiance, unmoved), 0.03);
}

TEST(Envmap, BadMapsAreRefusedNamingTheFile) {
  cv::Mat ok(8, 16, CV_32FC3, cv::Scalar::all(1));
  EXPECT_TRUE(CheckEnvironmentMap(ok, "m.hdr").ok());
  auto err = [](const cv::Mat& m) {
    Status st = CheckEnvironmentMap(m, "m.hdr");
    EXPECT_FALSE(st.ok());
    return st.ok() ? std::string() : st.error().ToString();
  };
  EXPECT_NE(err(cv::Mat(8, 12, CV_32FC3, cv::Scalar::all(1))).find("2:1"), std::string::npos);
  cv::Mat nan = ok.clone();
  nan.at<cv::Vec3f>(2, 3)[1] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_NE(err(nan).find("not finite"), std::string::npos);
  cv::Mat inf = ok.clone();
  inf.at<cv::Vec3f>(2, 3)[0] = std::numeric_limits<float>::infinity();
  EXPECT_NE(err(inf).find("m.hdr"), std::string::npos);
  cv::Mat neg = ok.clone();
  neg.at<cv::Vec3f>(1, 1)[2] = -0.5f;
  EXPECT_NE(err(neg).find("negative"), std::string::npos);
  const std::string dir = testing::FreshTempDir("envmap");
  auto missing = LoadEnvironmentMap(dir + "/none.hdr");
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().ToString().find("none.hdr"), std::string::npos);
  { std::ofstream(dir + "/junk.hdr") << "not a picture"; }
  auto junk = LoadEnvironmentMap(dir + "/junk.hdr");
  ASSERT_FALSE(junk.ok());
  EXPECT_NE(junk.error().ToString().find("junk.hdr"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig
