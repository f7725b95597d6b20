// rig tonemap honours the picture's header: its VIEW (the foveal grid it prints), its
// PRIMARIES (converted to the display's, out-of-gamut colours desaturated or clipped by
// --gamut), and refuses a bad --gamut or a malformed header with exit 2.
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "tests/support/run_rig.h"

namespace rig {
namespace {

using testing::FreshTempDir;
using testing::RunRig;

// An RGBE picture with `extra` header lines: a grey ramp in its upper half (so the tone
// mapping has a range to compress) and a saturated green patch below.
std::string WriteHdr(const std::string& dir, const std::string& name, const std::string& extra) {
  cv::Mat img(120, 160, CV_32FC3);
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const float v = std::pow(10.0f, -2.0f + 4.0f * x / img.cols);
      img.at<cv::Vec3f>(y, x) = y < 60 ? cv::Vec3f(v, v, v) : cv::Vec3f(0.02f, 1.0f, 0.02f) * v;
    }
  }
  std::vector<uchar> bytes;
  EXPECT_TRUE(cv::imencode(".hdr", img, bytes));
  std::string s(bytes.begin(), bytes.end());
  s.insert(s.find('\n') + 1, extra);
  const std::string path = dir + "/" + name;
  std::ofstream(path, std::ios::binary) << s;
  return path;
}

TEST(TonemapCommand, TheFilesViewSetsTheFovealGridUnlessFovIsGiven) {
  const std::string dir = FreshTempDir("tonemap_view");
  const std::string hdr = WriteHdr(dir, "view.hdr", "VIEW= -vtv -vh 20 -vv 15\n");
  auto r = RunRig("tonemap " + hdr + " --out " + dir + "/a.png");
  ASSERT_EQ(r.status, 0) << r.output;
  // 2·tan(10°) / 1° + 0.5 = 20.7 → 20; 2·tan(7.5°) / 1° + 0.5 = 15.6 → 15.
  EXPECT_NE(r.output.find("foveal 20x15"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("the file's view"), std::string::npos) << r.output;
  r = RunRig("tonemap " + hdr + " --fov-deg 40 --out " + dir + "/b.png");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("foveal 42x31"), std::string::npos) << r.output;  // pcond's default
  std::filesystem::remove_all(dir);
}

TEST(TonemapCommand, GamutDesaturatesAWideGreenUnlessClipIsAsked) {
  const std::string dir = FreshTempDir("tonemap_gamut");
  // Rec. 2020 primaries: its green lies outside the display's (sRGB) gamut.
  const std::string hdr = WriteHdr(
      dir, "wide.hdr", "PRIMARIES= 0.708 0.292 0.170 0.797 0.131 0.046 0.3127 0.3290\n");
  auto d = RunRig("tonemap " + hdr + " --out " + dir + "/d.png");
  ASSERT_EQ(d.status, 0) << d.output;
  EXPECT_NE(d.output.find("converted to the display's primaries, gamut desaturate"),
            std::string::npos)
      << d.output;
  auto c = RunRig("tonemap " + hdr + " --gamut clip --out " + dir + "/c.png");
  ASSERT_EQ(c.status, 0) << c.output;
  const cv::Mat pd = cv::imread(dir + "/d.png"), pc = cv::imread(dir + "/c.png");
  ASSERT_FALSE(pd.empty());
  ASSERT_FALSE(pc.empty());
  // The patch's middle: clipping zeroes red and blue (they go negative in sRGB);
  // desaturation lifts them towards the grey of the same luminance (the most negative one
  // just to 0, the gamut's edge).
  const cv::Vec3b vd = pd.at<cv::Vec3b>(90, 100), vc = pc.at<cv::Vec3b>(90, 100);
  EXPECT_EQ(vc[0], 0);
  EXPECT_EQ(vc[2], 0);
  EXPECT_GT(vd[0] + vd[2], 10) << vd;
  EXPECT_GT(vd[1], vd[0]);
  EXPECT_GT(vd[1], vd[2]);
  // The grey ramp is in gamut: the same both ways.
  EXPECT_EQ(pd.at<cv::Vec3b>(30, 100), pc.at<cv::Vec3b>(30, 100));
  std::filesystem::remove_all(dir);
}

TEST(TonemapCommand, BadGamutOrHeaderIsExitTwoNamingIt) {
  const std::string dir = FreshTempDir("tonemap_bad");
  const std::string good = WriteHdr(dir, "good.hdr", "");
  auto r = RunRig("tonemap " + good + " --gamut vivid --out " + dir + "/x.png");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--gamut"), std::string::npos) << r.output;
  const std::string bad = WriteHdr(dir, "bad.hdr", "COLORCORR=1 1\n");
  r = RunRig("tonemap " + bad + " --out " + dir + "/y.png");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("bad.hdr"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("COLORCORR"), std::string::npos) << r.output;
  const std::string view = WriteHdr(dir, "view.hdr", "VIEW= -vtv -vh 200\n");
  r = RunRig("tonemap " + view + " --out " + dir + "/z.png");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("view.hdr"), std::string::npos) << r.output;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rig
