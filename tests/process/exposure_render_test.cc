// Tests of process/exposure_render: round trip through a known response, saturation at both
// ends, interpolation between levels, monotonic in exposure time, bad input.
#include "process/render/exposure_render.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace rig {
namespace {

// A camera-like response per channel (B, G, R): g(z) = γ_c · ln((z + 0.5) / 256) + offset_c,
// strictly increasing.
std::array<std::vector<double>, 3> KnownResponse() {
  const double gamma[3] = {2.4, 2.2, 2.0}, offset[3] = {0.3, 0.0, -0.2};
  std::array<std::vector<double>, 3> g;
  for (int c = 0; c < 3; ++c) {
    for (int z = 0; z < 256; ++z) g[c].push_back(gamma[c] * std::log((z + 0.5) / 256) + offset[c]);
  }
  return g;
}

TEST(RenderExposure, RoundTripThroughAKnownResponseGivesBackEveryLevel) {
  auto g = KnownResponse();
  for (double t : {1.0 / 1000, 1.0 / 30, 2.0}) {
    cv::Mat radiance(1, 256, CV_32FC3);
    for (int z = 0; z < 256; ++z) {
      for (int c = 0; c < 3; ++c) {
        radiance.at<cv::Vec3f>(0, z)[c] = static_cast<float>(std::exp(g[c][z]) / t);
      }
    }
    auto out = RenderExposure(radiance, t, g);
    ASSERT_TRUE(out.ok()) << out.error().ToString();
    ASSERT_EQ(out->type(), CV_8UC3);
    for (int z = 0; z < 256; ++z) {
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(out->at<cv::Vec3b>(0, z)[c], z) << "t = " << t << " channel " << c;
      }
    }
  }
}

TEST(RenderExposure, InterpolatesBetweenLevelsInLogExposure) {
  auto g = KnownResponse();
  cv::Mat radiance(1, 2, CV_32FC3);
  const double mid = 0.5 * (g[1][10] + g[1][11]);  // half way from level 10 to 11
  radiance.at<cv::Vec3f>(0, 0) = cv::Vec3f::all(static_cast<float>(std::exp(mid - 1e-3)));
  radiance.at<cv::Vec3f>(0, 1) = cv::Vec3f::all(static_cast<float>(std::exp(mid + 1e-3)));
  auto out = RenderExposure(radiance, 1.0, g);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out->at<cv::Vec3b>(0, 0)[1], 10);
  EXPECT_EQ(out->at<cv::Vec3b>(0, 1)[1], 11);
}

TEST(RenderExposure, SaturatesBrightPixelsAndBlacksDarkOnes) {
  auto g = KnownResponse();
  cv::Mat radiance(1, 5, CV_32FC3);
  radiance.at<cv::Vec3f>(0, 0) = cv::Vec3f::all(1e6f);   // far over the top of the curve
  radiance.at<cv::Vec3f>(0, 1) = cv::Vec3f::all(1e-9f);  // far under its bottom
  radiance.at<cv::Vec3f>(0, 2) = cv::Vec3f::all(0.0f);
  radiance.at<cv::Vec3f>(0, 3) = cv::Vec3f::all(-1.0f);
  radiance.at<cv::Vec3f>(0, 4) = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
  auto out = RenderExposure(radiance, 0.01, g);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(out->at<cv::Vec3b>(0, 0), cv::Vec3b(255, 255, 255));
  for (int x = 1; x < 5; ++x) EXPECT_EQ(out->at<cv::Vec3b>(0, x), cv::Vec3b(0, 0, 0)) << x;
}

TEST(RenderExposure, LongerExposuresNeverDarkenAPixelAndEventuallySaturate) {
  auto g = KnownResponse();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> decade(-3, 3);
  cv::Mat radiance(32, 32, CV_32FC3);
  for (auto it = radiance.begin<cv::Vec3f>(); it != radiance.end<cv::Vec3f>(); ++it) {
    *it = cv::Vec3f(std::pow(10.0f, decade(rng)), std::pow(10.0f, decade(rng)),
                    std::pow(10.0f, decade(rng)));
  }
  cv::Mat previous(radiance.size(), CV_8UC3, cv::Scalar::all(0));
  for (double t = 1e-5; t <= 1e5; t *= 2) {
    auto out = RenderExposure(radiance, t, g);
    ASSERT_TRUE(out.ok());
    cv::Mat darker;
    cv::compare(*out, previous, darker, cv::CMP_LT);
    ASSERT_EQ(cv::countNonZero(darker.reshape(1)), 0) << "t = " << t;
    previous = *out;
  }
  double lo;
  cv::minMaxLoc(previous.reshape(1), &lo);
  EXPECT_EQ(lo, 255);  // at 1e5 s even 1e-3 radiance is far over the top
}

TEST(RenderExposure, ANoisyCurveThatDipsStillRendersMonotonically) {
  auto g = KnownResponse();
  for (int c = 0; c < 3; ++c) std::swap(g[c][250], g[c][251]);  // a dip near the top
  cv::Mat radiance(1, 2000, CV_32FC3);
  for (int x = 0; x < radiance.cols; ++x) {
    radiance.at<cv::Vec3f>(0, x) = cv::Vec3f::all(static_cast<float>(std::exp(-8.0 + 9.0 * x / 1999)));
  }
  auto out = RenderExposure(radiance, 1.0, g);
  ASSERT_TRUE(out.ok());
  for (int x = 1; x < radiance.cols; ++x) {
    ASSERT_GE(out->at<cv::Vec3b>(0, x)[1], out->at<cv::Vec3b>(0, x - 1)[1]) << x;
  }
}

TEST(RenderExposure, AcceptsChronoSecondsToo) {
  auto g = KnownResponse();
  cv::Mat radiance(2, 2, CV_32FC3, cv::Scalar::all(1.0));
  auto a = RenderExposure(radiance, 0.25, g);
  auto b = RenderExposure(radiance, std::chrono::duration<double>(0.25), g);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(cv::norm(*a, *b, cv::NORM_INF), 0);
}

TEST(RenderExposure, RejectsBadInput) {
  auto g = KnownResponse();
  cv::Mat radiance(2, 2, CV_32FC3, cv::Scalar::all(1.0));
  EXPECT_EQ(RenderExposure(radiance, 0.0, g).error().code, ErrorCode::kInvalidInput);
  EXPECT_EQ(RenderExposure(radiance, -1.0, g).error().code, ErrorCode::kInvalidInput);
  EXPECT_EQ(RenderExposure(cv::Mat(2, 2, CV_8UC3), 1.0, g).error().code,
            ErrorCode::kInvalidInput);
  auto short_curve = g;
  short_curve[2].pop_back();
  auto e = RenderExposure(radiance, 1.0, short_curve);
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("channel 2"), std::string::npos);
  auto nan_curve = g;
  nan_curve[0][7] = std::nan("");
  EXPECT_FALSE(RenderExposure(radiance, 1.0, nan_curve).ok());
}

}  // namespace
}  // namespace rig
