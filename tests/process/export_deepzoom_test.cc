// Deep-zoom pyramids of a web folder's planes: levels, tile sizes with overlap, the .dzi, the
// full level reassembling to the plane, halving as a 2x2 mean, and no overwriting.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "process/export/deepzoom.h"
#include "process/io/jpeg_io.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

cv::Mat Read(const std::string& path) {
  auto r = JpegReader::Open(path);
  EXPECT_TRUE(r.ok()) << path;
  if (!r.ok()) return {};
  cv::Mat m;
  EXPECT_TRUE((*r)->Read((*r)->height(), &m).ok());
  return m;
}

TEST(ExportDeepZoom, LevelsTilesOverlapAndTheDziAreAsDeepZoomDefinesThem) {
  const std::string dir = testing::FreshTempDir("deepzoom");
  const int W = 600, H = 300;
  cv::Mat plane(H, W, CV_8UC3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      plane.at<cv::Vec3b>(y, x) = cv::Vec3b(uint8_t(128 + 100 * std::sin(x / 30.0)), uint8_t(y * 255 / H),
                                            uint8_t(128 + 90 * std::cos((x + y) / 45.0)));
  ASSERT_TRUE(WriteJpeg(dir + "/plane_0.jpg", plane, JpegColor::kYcbcr, 98).ok());
  ASSERT_TRUE(WriteJpeg(dir + "/plane_1.jpg", plane, JpegColor::kRgb, 98).ok());
  auto report = WriteDeepZoom(dir, DeepZoomOptions{});
  ASSERT_TRUE(report.ok()) << report.error().ToString();
  EXPECT_EQ(report->files, 2);
  EXPECT_EQ(report->levels, 11);  // ceil(log2(600)) + 1
  // tiles: level L is ceil(600 / 2^(10-L)) x ceil(300 / 2^(10-L)); 256 px tiles
  long expected = 0;
  for (int L = 0; L <= 10; ++L) {
    const int w = static_cast<int>(std::ceil(W / std::pow(2.0, 10 - L))), h = static_cast<int>(std::ceil(H / std::pow(2.0, 10 - L)));
    const int nx = (w + 255) / 256, ny = (h + 255) / 256;
    expected += nx * ny;
    EXPECT_TRUE(fs::exists(fmt::format("{}/plane_0_files/{}/{}_{}.jpg", dir, L, nx - 1, ny - 1))) << L;
    EXPECT_FALSE(fs::exists(fmt::format("{}/plane_0_files/{}/{}_{}.jpg", dir, L, nx, 0))) << L;
  }
  EXPECT_EQ(report->tiles, 2 * expected);
  std::ifstream f(dir + "/plane_0.dzi");
  std::stringstream ss;
  ss << f.rdbuf();
  EXPECT_THAT(ss.str(), HasSubstr("TileSize=\"256\""));
  EXPECT_THAT(ss.str(), HasSubstr("Overlap=\"1\""));
  EXPECT_THAT(ss.str(), HasSubstr("<Size Width=\"600\" Height=\"300\"/>"));
  // overlap on inner edges only: the corner tile 257x257, the last ones cut at the image
  EXPECT_EQ(Read(dir + "/plane_0_files/10/0_0.jpg").size(), cv::Size(257, 257));
  EXPECT_EQ(Read(dir + "/plane_0_files/10/1_0.jpg").size(), cv::Size(258, 257));
  EXPECT_EQ(Read(dir + "/plane_0_files/10/2_1.jpg").size(), cv::Size(600 - 511, 300 - 255));
  EXPECT_EQ(Read(dir + "/plane_0_files/0/0_0.jpg").size(), cv::Size(1, 1));
  // the full level reassembles to the plane (a second JPEG generation at q95)
  const cv::Mat decoded = Read(dir + "/plane_0.jpg");
  cv::Mat whole(H, W, CV_8UC3);
  for (int ty = 0; ty < 2; ++ty)
    for (int tx = 0; tx < 3; ++tx) {
      const cv::Mat t = Read(fmt::format("{}/plane_0_files/10/{}_{}.jpg", dir, tx, ty));
      const int ox = tx ? 1 : 0, oy = ty ? 1 : 0;
      const int w = std::min(256, W - 256 * tx), h = std::min(256, H - 256 * ty);
      t(cv::Rect(ox, oy, w, h)).copyTo(whole(cv::Rect(256 * tx, 256 * ty, w, h)));
    }
  cv::Mat diff;
  cv::absdiff(whole, decoded, diff);
  const cv::Scalar m = cv::mean(diff);
  EXPECT_LT((m[0] + m[1] + m[2]) / 3, 1.0);
  // level 9 is the 2x2 mean of level 10
  const cv::Mat half = Read(dir + "/plane_0_files/9/0_0.jpg");
  ASSERT_EQ(half.size(), cv::Size(257, 150));
  cv::Mat expect;
  cv::Mat f32;
  decoded.convertTo(f32, CV_32F);
  cv::resize(f32, expect, cv::Size(300, 150), 0, 0, cv::INTER_AREA);
  expect.convertTo(expect, CV_8U);
  cv::absdiff(half, expect(cv::Rect(0, 0, 257, 150)), diff);
  const cv::Scalar m2 = cv::mean(diff);
  EXPECT_LT((m2[0] + m2[1] + m2[2]) / 3, 1.0);
  // nothing is overwritten
  EXPECT_FALSE(WriteDeepZoom(dir, DeepZoomOptions{}).ok());
}

TEST(ExportDeepZoom, RigExportWritesTilesOnRequest) {
  const std::string dir = testing::FreshTempDir("deepzoom-cmd");
  // a .rti of a 100x60 HSH (small: rig export measures it at 613 lights), exported to the web format with tiles
  const std::string rti = dir + "/m.rti";
  {
    std::string header = "#HSH1.2\n3\n100 60 3\n4 2 1\n";
    std::vector<char> data(2 * 4 * 4 + 100 * 60 * 3 * 4);
    const float scale = 1.0f, bias = 0.0f;
    for (int j = 0; j < 4; ++j) {
      std::memcpy(&data[4 * j], &scale, 4);
      std::memcpy(&data[16 + 4 * j], &bias, 4);
    }
    for (size_t i = 32; i < data.size(); ++i) data[i] = static_cast<char>((i * 7) % 200);
    std::ofstream(rti, std::ios::binary) << header << std::string(data.begin(), data.end());
  }
  const auto r = testing::RunRig("export " + rti + " --format relight --tiles on --out " + dir + "/web");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("deep zoom: 4 plane files x 8 levels"));
  EXPECT_TRUE(fs::exists(dir + "/web/plane_3.dzi"));
  EXPECT_TRUE(fs::exists(dir + "/web/plane_3_files/7/0_0.jpg"));
  const auto off = testing::RunRig("export " + rti + " --format relight --out " + dir + "/web2");
  ASSERT_EQ(off.status, 0) << off.output;
  EXPECT_FALSE(fs::exists(dir + "/web2/plane_0.dzi"));  // auto: 100 px needs no tiles
}

}  // namespace
}  // namespace rig
