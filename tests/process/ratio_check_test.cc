// The paper's Fig. 6 on simulated data: two surfaces of known radiance ratio seen through a
// filmic (non-linear) camera; the ratio of their 8-bit intensities varies with the exposure
// time, the ratio of their radiances (through the recovered response) stays at the truth.
#include "process/hdr/ratio_check.h"

#include <cmath>
#include <sstream>

#include <gmock/gmock.h>
#include <fmt/format.h>
#include <gtest/gtest.h>

#include "sim/bracket_synth.h"

namespace rig {
namespace {

using ::testing::HasSubstr;

constexpr double kRadianceA = 0.4, kRadianceB = 0.1;  // true ratio 4
const cv::Point kA(16, 24), kB(48, 24);

const synth::FilmicResponse& Camera() {
  static const synth::FilmicResponse f;
  return f;
}

// One response per camera: recovered from a rich scene, then used on the test scene.
const ResponseCurve& Recovered() {
  static const ResponseCurve g = [] {
    const cv::Mat truth = synth::SyntheticRadiance(240, 180);
    const Bracket one[1] = {
        synth::RenderBracket(truth, synth::ExposuresFor(1e-2, 10.0 * std::pow(10.0, 0.5), 7), Camera(), 7)};
    auto r = RecoverResponse(one, ResponseOptions{});
    EXPECT_TRUE(r.ok()) << r.error().ToString();
    return r.ok() ? *r : ResponseCurve{};
  }();
  return g;
}

// 11 exposures 1/100 s to 3.2 s, 5/6 EV apart.
std::vector<double> Times() {
  std::vector<double> t;
  for (int j = 0; j < 11; ++j) t.push_back(0.01 * std::pow(10.0, j * 0.25));
  return t;
}

// Left half radiance A, right half B (grey: the same in every channel): A saturates in the
// longest exposures, B sits in the toe of the curve in the shortest ones.
Bracket TwoSurfaces(double a = kRadianceA, double b = kRadianceB) {
  cv::Mat truth(48, 64, CV_32FC3, cv::Scalar::all(b));
  truth(cv::Rect(0, 0, 32, 48)).setTo(cv::Scalar::all(a));
  return synth::RenderBracket(truth, Times(), Camera(), 3);
}

TEST(RatioCheck, IntensityRatioDriftsWithExposureWhileRadianceRatioStaysAtTheTruth) {
  const Bracket b = TwoSurfaces();
  RatioCheckOptions o;
  o.a = kA;
  o.b = kB;
  auto r = CheckPixelRatios(b, Recovered(), o);
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  ASSERT_EQ(r->rows.size(), b.size());
  int valid = 0;
  for (const auto& row : r->rows) {
    std::printf("t %.4f s: intensity %.1f / %.1f = %.3f, radiance ratio %s\n", row.exposure_s,
                row.intensity_a, row.intensity_b, row.intensity_ratio,
                row.radiance_valid ? fmt::format("{:.4f}", row.radiance_ratio).c_str() : "-");
    if (!row.radiance_valid) continue;
    ++valid;
    EXPECT_NEAR(row.radiance_ratio, kRadianceA / kRadianceB, 0.04 * kRadianceA / kRadianceB) << row.exposure_s;
  }
  std::printf("spread: intensity %.3f, radiance %.4f; merged ratio %.4f\n", r->intensity_spread,
              r->radiance_spread, r->merged_ratio);
  // Several exposures record both surfaces; the radiance ratio is the same in all of them.
  EXPECT_GE(valid, 3);
  EXPECT_LT(r->radiance_spread, 1.05);
  EXPECT_NEAR(r->merged_ratio, 4.0, 0.1);
  // Intensities: the ratio is far from 4 in most exposures and sweeps a wide range (the
  // paper's 0.5 .. 2); when A clips in the longest exposure it falls towards 1.
  EXPECT_GT(r->intensity_spread, 2.0);
  EXPECT_LT(r->rows.back().intensity_ratio, 1.6);
  EXPECT_GT(r->intensity_spread, 20 * (r->radiance_spread - 1) + 1);
}

TEST(RatioCheck, ALinearCameraHasAConstantIntensityRatioToo) {
  // The drift comes from the response alone: through a linear 16-bit camera the intensity ratio
  // is the radiance ratio wherever neither pixel clips.
  cv::Mat truth(48, 64, CV_32FC3, cv::Scalar::all(kRadianceB));
  truth(cv::Rect(0, 0, 32, 48)).setTo(cv::Scalar::all(kRadianceA));
  Bracket b;
  for (double t : {0.1, 0.2, 0.4, 0.8}) {
    cv::Mat frame;
    cv::Mat(truth * t * 60000.0).convertTo(frame, CV_16UC3);  // A at t = 0.8: 19200 of 65535
    b.push_back({frame, Seconds(t), fmt::format("linear_{}.png", t)});
  }
  RatioCheckOptions o;
  o.a = kA;
  o.b = kB;
  auto r = CheckPixelRatios(b, LinearResponse(65536), o);
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  EXPECT_LT(r->intensity_spread, 1.01);
  EXPECT_LT(r->radiance_spread, 1.01);
  for (const auto& row : r->rows) EXPECT_NEAR(row.intensity_ratio, 4.0, 0.02);
}

TEST(RatioCheck, PixelsChosenFromTheDataAreFlatAndWellRecorded) {
  // A scene with many radiance levels: the automatic choice still gives a constant radiance
  // ratio, equal to the truth at the chosen pixels.
  cv::Mat truth(90, 120, CV_32FC3);
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x)
      truth.at<cv::Vec3f>(y, x) = cv::Vec3f::all(float(0.02 * std::pow(2.0, (x / 20) + 0.5 * (y / 30))));
  const Bracket b = synth::RenderBracket(truth, Times(), Camera(), 5);
  auto r = CheckPixelRatios(b, Recovered(), RatioCheckOptions{});
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  const double true_ratio = truth.at<cv::Vec3f>(r->a)[0] / truth.at<cv::Vec3f>(r->b)[0];
  std::printf("chosen %d,%d / %d,%d: true ratio %.3f, merged %.3f, spreads %.3f / %.4f\n", r->a.x,
              r->a.y, r->b.x, r->b.y, true_ratio, r->merged_ratio, r->intensity_spread,
              r->radiance_spread);
  EXPECT_GT(true_ratio, 1.0);  // a is the brighter one
  EXPECT_NEAR(r->merged_ratio, true_ratio, 0.04 * true_ratio);
  EXPECT_LT(r->radiance_spread, 1.05);
  // The same seed picks the same pixels.
  auto again = CheckPixelRatios(b, Recovered(), RatioCheckOptions{});
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->a, r->a);
  EXPECT_EQ(again->b, r->b);
}

TEST(RatioCheck, TableAndPlot) {
  RatioCheckOptions o;
  o.a = kA;
  o.b = kB;
  auto r = CheckPixelRatios(TwoSurfaces(), Recovered(), o);
  ASSERT_TRUE(r.ok());
  std::stringstream csv(r->Csv());
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "exposure_s,intensity_a,intensity_b,intensity_ratio,radiance_ratio");
  int rows = 0;
  while (std::getline(csv, line)) ++rows;
  EXPECT_EQ(rows, 11);
  const cv::Mat plot = PlotPixelRatios(*r);
  EXPECT_EQ(plot.type(), CV_8UC3);
  EXPECT_GT(plot.cols, 300);
  // Both lines are drawn: red (intensity) and green (radiance) pixels exist.
  int red = 0, green = 0;
  for (int y = 0; y < plot.rows; ++y)
    for (int x = 0; x < plot.cols; ++x) {
      const cv::Vec3b p = plot.at<cv::Vec3b>(y, x);
      red += p == cv::Vec3b(40, 40, 220);
      green += p == cv::Vec3b(40, 160, 40);
    }
  EXPECT_GT(red, 100);
  EXPECT_GT(green, 100);
}

TEST(RatioCheck, BadInputNamesTheFile) {
  const Bracket b = TwoSurfaces();
  RatioCheckOptions o;
  o.a = cv::Point(500, 10);
  o.b = kB;
  auto r = CheckPixelRatios(b, Recovered(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().ToString(), HasSubstr(b[0].source));
  EXPECT_THAT(r.error().ToString(), HasSubstr("outside"));
  // Both surfaces far too bright for every exposure: no frame records them.
  const Bracket blown = TwoSurfaces(400, 100);
  o.a = kA;
  auto none = CheckPixelRatios(blown, Recovered(), o);
  ASSERT_FALSE(none.ok());
  EXPECT_THAT(none.error().ToString(), HasSubstr(blown[0].source));
}

}  // namespace
}  // namespace rig
