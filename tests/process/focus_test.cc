// The sharpness figure of `rig shot --preview`: known answers on synthetic frames.
#include "process/hdr/focus.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

cv::Mat Checkerboard(int w, int h, int cell) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const uint8_t v = ((x / cell + y / cell) % 2) ? 200 : 40;
      img.at<cv::Vec3b>(y, x) = {v, v, v};
    }
  return img;
}

TEST(Focus, AFlatFrameHasNoneAndBlurLowersItSteadily) {
  cv::Mat flat(90, 120, CV_8UC3, cv::Scalar(90, 90, 90));
  auto f = AnalyzeFocus(flat);
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f->whole, 0);
  const cv::Mat sharp = Checkerboard(120, 90, 6);
  double previous = AnalyzeFocus(sharp)->whole;
  EXPECT_GT(previous, 1000);
  for (double sigma : {0.7, 1.5, 3.0}) {
    cv::Mat blurred;
    cv::GaussianBlur(sharp, blurred, cv::Size(), sigma);
    const double now = AnalyzeFocus(blurred)->whole;
    EXPECT_LT(now, previous * 0.8) << "sigma " << sigma;
    previous = now;
  }
}

TEST(Focus, TheSharpestTileIsWhereTheFrameIsInFocus) {
  const cv::Mat sharp = Checkerboard(150, 120, 5);
  cv::Mat img;
  cv::GaussianBlur(sharp, img, cv::Size(), 2.5);
  // Only the bottom-right ninth is in focus.
  const cv::Rect br(100, 80, 50, 40);
  sharp(br).copyTo(img(br));
  auto f = AnalyzeFocus(img);
  ASSERT_TRUE(f.ok());
  EXPECT_EQ(f->sharpest_tile, 8);
  for (int i = 0; i < 8; ++i) EXPECT_LT(f->tiles[i] * 3, f->tiles[8]) << "tile " << i;
  // Grey and 16-bit frames give the same figure as the 8-bit BGR one.
  cv::Mat grey, grey16;
  cv::cvtColor(img, grey, cv::COLOR_BGR2GRAY);
  grey.convertTo(grey16, CV_16U, 257);
  EXPECT_NEAR(AnalyzeFocus(grey)->whole, f->whole, 1e-6 * f->whole);
  EXPECT_NEAR(AnalyzeFocus(grey16)->whole, f->whole, 1e-6 * f->whole);
}

TEST(Focus, ATinyOrEmptyFrameIsRefused) {
  EXPECT_FALSE(AnalyzeFocus(cv::Mat()).ok());
  EXPECT_FALSE(AnalyzeFocus(cv::Mat(8, 100, CV_8UC3, cv::Scalar(1, 2, 3))).ok());
  EXPECT_FALSE(AnalyzeFocus(cv::Mat(20, 20, CV_8UC4, cv::Scalar(1, 2, 3, 4))).ok());
}

}  // namespace
}  // namespace rig
