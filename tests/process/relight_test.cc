// process/render/relight without the command line: lamps add in linear radiance, colour and
// intensity scale each channel, the region check refuses or warns, a sweep runs along its
// path with one tone mapping, and WriteRender writes frames without overwriting.
#include "process/render/relight.h"

#include <filesystem>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"

#include "process/model/light_direction.h"
#include "tests/support/run_rig.h"
#include "tests/support/synthetic_model.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

// An SH order-2 model of a 24x16 image with seeded random coefficients (a positive constant
// term, so renders are bright), sampled on the default grid: h 0-90, v 0-30, 10° steps.
Model SyntheticModel() { return testing::SyntheticShModel(7, 0.05f); }

RelightLamp Lamp(double h, double v, std::array<double, 3> rgb = {1, 1, 1}, double intensity = 1) {
  RelightLamp l;
  l.h_deg = h;
  l.v_deg = v;
  l.rgb = rgb;
  l.intensity = intensity;
  return l;
}

cv::Mat RenderOne(const Model& model, std::vector<RelightLamp> lamps) {
  RelightRequest request;
  request.lamps = std::move(lamps);
  auto out = Relight(*WrapHarmonic(model), request);
  EXPECT_TRUE(out.ok()) << out.error().ToString();
  if (!out.ok()) return {};
  EXPECT_EQ(out->radiance.size(), 1u);
  return out->radiance[0];
}

TEST(Relight, TwoLampsRenderTheSumOfTheirSingleRenders) {
  const Model model = SyntheticModel();
  const cv::Mat a = RenderOne(model, {Lamp(20, 10)}), b = RenderOne(model, {Lamp(75, 25)});
  const cv::Mat ab = RenderOne(model, {Lamp(20, 10), Lamp(75, 25)});
  ASSERT_EQ(ab.type(), CV_32FC3);
  const double scale = cv::norm(ab, cv::NORM_INF);
  ASSERT_GT(scale, 0);
  EXPECT_LT(cv::norm(a + b, ab, cv::NORM_INF), 1e-5 * scale);
}

TEST(Relight, LampColourIntensityAndCaptureLampScaleEachChannelExactly) {
  const Model model = SyntheticModel();
  const cv::Mat white = RenderOne(model, {Lamp(45, 20)});
  const cv::Mat coloured = RenderOne(model, {Lamp(45, 20, {2, 1, 0.25}, 1.5)});
  const cv::Mat rho = model.EvaluateRho(LightDirection(45, 20));
  std::vector<cv::Mat> w, c, r;
  cv::split(white, w);
  cv::split(coloured, c);
  cv::split(rho, r);
  const double colour[3] = {0.25 * 1.5, 1 * 1.5, 2 * 1.5};  // B, G, R
  const double lamp[3] = {1.0, 1.5, 2.0};                   // capture lamp, B, G, R
  for (int ch = 0; ch < 3; ++ch) {
    const double scale = cv::norm(w[ch], cv::NORM_INF);
    ASSERT_GT(scale, 0);
    EXPECT_LT(cv::norm(w[ch], r[ch] * lamp[ch], cv::NORM_INF), 1e-5 * scale) << ch;
    EXPECT_LT(cv::norm(c[ch], w[ch] * colour[ch], cv::NORM_INF), 1e-5 * scale * colour[ch]) << ch;
  }
}

TEST(Relight, LampsOutsideTheSampledRegionAreRefusedUnlessExtrapolated) {
  const Model model = SyntheticModel();
  RelightRequest request;
  request.lamps = {Lamp(150, 60)};
  auto refused = Relight(*WrapHarmonic(model), request);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kInvalidInput);
  EXPECT_NE(refused.error().message.find("outside the sampled region"), std::string::npos);

  std::vector<std::string> warnings;
  request.extrapolate = true;
  request.on_warning = [&](const std::string& m) { warnings.push_back(m); };
  auto rendered = Relight(*WrapHarmonic(model), request);
  ASSERT_TRUE(rendered.ok()) << rendered.error().ToString();
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("extrapolated"), std::string::npos);

  // A sweep leaving the region: refused within --sweep.
  RelightRequest sweep;
  sweep.sweep = SampleLampPath({Lamp(0, 15), Lamp(170, 15)}, 8);
  auto swept = Relight(*WrapHarmonic(model), sweep);
  ASSERT_FALSE(swept.ok());
  EXPECT_EQ(swept.error().context.rfind("--sweep", 0), 0u) << swept.error().ToString();
}

TEST(Relight, SweepRunsAlongItsPathWithOneToneMappingAndIsWrittenOnce) {
  const std::vector<RelightLamp> path = SampleLampPath({Lamp(0, 15), Lamp(90, 15)}, 5);
  ASSERT_EQ(path.size(), 5u);
  EXPECT_DOUBLE_EQ(path.front().h_deg, 0);
  EXPECT_DOUBLE_EQ(path[2].h_deg, 45);
  EXPECT_NEAR(path.back().h_deg, 90, 1e-12);
  for (const auto& l : path) EXPECT_DOUBLE_EQ(l.v_deg, 15);

  const Model model = SyntheticModel();
  RelightRequest request;
  request.lamps = {Lamp(30, 0)};
  request.sweep = path;
  request.display = RenderDisplay::kToneMap;
  auto out = Relight(*WrapHarmonic(model), request);
  ASSERT_TRUE(out.ok()) << out.error().ToString();
  ASSERT_EQ(out->radiance.size(), 5u);
  // Each frame: the held lamp plus the moving one.
  const cv::Mat third = RenderOne(model, {Lamp(30, 0), path[2]});
  EXPECT_LT(cv::norm(out->radiance[2], third, cv::NORM_INF), 1e-5 * cv::norm(third, cv::NORM_INF));
  // Ward on a sweep: one Ward mapping for every frame (not replaced by a linear scale), the
  // brightest frame's, so that frame's picture is its own Ward picture.
  EXPECT_EQ(out->tonemap.method, ToneMapMethod::kWard);
  ASSERT_NE(out->tonemap.ward_fixed, nullptr);
  EXPECT_NE(out->display_note.find("Ward"), std::string::npos);
  {
    size_t brightest = 0;
    double best = -1;
    for (size_t i = 0; i < out->radiance.size(); ++i) {
      const double m = cv::mean(Luminance(out->radiance[i]))[0];
      if (m > best) best = m, brightest = i;
    }
    ToneMapOptions own = out->tonemap;
    own.ward_fixed = nullptr;
    auto fixed = ToneMap(out->radiance[brightest], out->tonemap, nullptr);
    auto adapted = ToneMap(out->radiance[brightest], own, nullptr);
    ASSERT_TRUE(fixed.ok() && adapted.ok());
    EXPECT_LE(cv::norm(*fixed, *adapted, cv::NORM_INF), 1.0);
  }
  // Linear on a sweep: one linear scale.
  request.tonemap.method = ToneMapMethod::kLinear;
  auto lin = Relight(*WrapHarmonic(model), request);
  ASSERT_TRUE(lin.ok());
  EXPECT_EQ(lin->tonemap.method, ToneMapMethod::kLinear);
  EXPECT_GT(lin->tonemap.linear_scale, 0);

  const std::string dir = testing::FreshTempDir("relight");
  const std::string video = dir + "/sweep.avi";
  auto files = WriteRender(*out, request, dir + "/sweep.png", 12);
  ASSERT_TRUE(files.ok()) << files.error().ToString();
  EXPECT_EQ(files->frames, 5u);
  EXPECT_FALSE(files->video);
  EXPECT_EQ(files->frame_dir, dir + "/sweep");
  EXPECT_TRUE(fs::exists(dir + "/sweep/frame_0004.png"));
  // The frame folder exists now: nothing is overwritten.
  auto again = WriteRender(*out, request, video, 12);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("exists"), std::string::npos);
  fs::remove_all(dir);
}

TEST(Relight, OutputKindsFollowTheExtension) {
  EXPECT_EQ(RenderFileKindOf("a/b.EXR"), RenderFileKind::kExr);
  EXPECT_EQ(RenderFileKindOf("b.jpeg"), RenderFileKind::kPicture);
  EXPECT_EQ(RenderFileKindOf("b.tif"), RenderFileKind::kPicture);
  EXPECT_EQ(RenderFileKindOf("b.TIFF"), RenderFileKind::kPicture);
  EXPECT_EQ(RenderFileKindOf("b.avi"), RenderFileKind::kVideo);
  EXPECT_EQ(RenderFileKindOf("b.bmp"), RenderFileKind::kUnknown);
  EXPECT_EQ(SweepFrameDir("out/s.avi"), "out/s");
  EXPECT_EQ(SweepFrameDir("out/s.exr"), "out/s");
}

}  // namespace
}  // namespace rig

namespace rig {
namespace {

TEST(Relight, FlaggedPixelsAreFilledFromNeighboursInPicturesAndStayFlaggedInExr) {
  Model model = SyntheticModel();
  model.valid() = cv::Mat(16, 24, CV_8U, cv::Scalar(1));
  model.valid().at<uint8_t>(5, 7) = 0;
  model.valid().at<uint8_t>(5, 8) = 0;
  RelightRequest request;
  request.lamps = {Lamp(40, 10)};
  request.display = RenderDisplay::kToneMap;
  auto out = Relight(*WrapHarmonic(model), request);
  ASSERT_TRUE(out.ok()) << out.error().ToString();
  EXPECT_EQ(out->radiance[0].at<cv::Vec3f>(5, 7), cv::Vec3f(0, 0, 0));
  const std::string dir = testing::FreshTempDir("relight-fill");
  auto png = WriteRender(*out, request, dir + "/a.png", 12);
  ASSERT_TRUE(png.ok()) << png.error().ToString();
  EXPECT_EQ(png->filled_pixels, 2u);
  cv::Mat pic = cv::imread(dir + "/a.png");
  ASSERT_FALSE(pic.empty());
  // Filled: as bright as its neighbours (no black speck).
  const double neighbour = pic.at<cv::Vec3b>(4, 7)[1], filled = pic.at<cv::Vec3b>(5, 7)[1];
  EXPECT_GT(filled, 0.8 * neighbour);
  EXPECT_LT(filled, 1.2 * neighbour + 2);
  request.display = RenderDisplay::kRadiance;
  auto exr = WriteRender(*out, request, dir + "/a.exr", 12);
  ASSERT_TRUE(exr.ok());
  EXPECT_EQ(exr->filled_pixels, 0u);
  auto back = ReadRgbExr(dir + "/a.exr");
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->at<cv::Vec3f>(5, 7), cv::Vec3f(0, 0, 0));  // still flagged in radiance
  size_t n = 0;
  const cv::Mat f = FillFlaggedPixels(out->radiance[0], model.valid(), &n);
  EXPECT_EQ(n, 2u);
  EXPECT_GT(f.at<cv::Vec3f>(5, 8)[1], 0);
  EXPECT_EQ(f.at<cv::Vec3f>(0, 0), out->radiance[0].at<cv::Vec3f>(0, 0));  // valid untouched
  fs::remove_all(dir);
}

TEST(Relight, DirectionLampsBypassTheLightFrameAndAzimuthElevationIsTheImagePlaneConvention) {
  Model model = SyntheticModel();
  model.info().light_frame.h_offset_deg = 10;  // a rig whose H is off by 10°
  RelightLamp by_angles = Lamp(30, 15);
  RelightLamp by_dir;
  by_dir.direction = LightDirection(30, 15, model.info().light_frame);
  EXPECT_LT(cv::norm(RenderOne(model, {by_angles}), RenderOne(model, {by_dir}), cv::NORM_INF), 1e-6);
  RelightLamp raw;
  raw.direction = LightDirection(30, 15);  // without the frame: a different light
  EXPECT_GT(cv::norm(RenderOne(model, {by_angles}), RenderOne(model, {raw}), cv::NORM_INF), 1e-3);
  const Vec3 up = AzimuthElevationDirection(90, 0), top = AzimuthElevationDirection(0, 90);
  EXPECT_NEAR(up[1], 1, 1e-12);   // azimuth 90°: +y (up in the image)
  EXPECT_NEAR(top[2], 1, 1e-12);  // elevation 90°: from the camera
  EXPECT_EQ(LampName(by_angles), "30,15");
  EXPECT_EQ(LampName(raw).rfind("dir=", 0), 0u);
}

TEST(Relight, IntensityShowsThroughTheCurveOfTheUnitLamps) {
  const Model model = SyntheticModel();
  RelightRequest request;
  request.display = RenderDisplay::kToneMap;
  request.tonemap.srgb = true;
  request.lamps = {Lamp(40, 10)};
  auto one = Relight(*WrapHarmonic(model), request);
  request.lamps = {Lamp(40, 10, {1, 1, 1}, 2)};
  auto two = Relight(*WrapHarmonic(model), request);
  ASSERT_TRUE(one.ok() && two.ok());
  EXPECT_FALSE(one->tonemap.ward_fixed);  // intensity 1: as before, the image's own curve
  ASSERT_TRUE(two->tonemap.ward_fixed);
  auto p1 = RenderPicture(one->radiance[0], request, one->tonemap);
  auto p2 = RenderPicture(two->radiance[0], request, two->tonemap);
  auto p2_own = ToneMap(two->radiance[0], request.tonemap);
  ASSERT_TRUE(p1.ok() && p2.ok() && p2_own.ok());
  EXPECT_GT(cv::mean(*p2)[1], cv::mean(*p1)[1] + 5);
  EXPECT_LT(std::abs(cv::mean(*p2_own)[1] - cv::mean(*p1)[1]), 1.0);  // what Ward alone does
}

}  // namespace
}  // namespace rig
