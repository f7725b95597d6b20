// A picture's header as Radiance and pcond take it: EXPOSURE, COLORCORR, PRIMARIES, VIEW and
// PIXASPECT lines; OpenEXR's chromaticities; the colour conversion and gamut mapping to the
// display; the stratified point samples. Synthetic inputs with known answers.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"
#include "process/render/radiance_file.h"
#include "process/render/tonemap.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

constexpr double kRad = std::numbers::pi / 180;

// ITU-R BT.2020 (D65), a gamut wider than Rec. 709's with the same white.
Chromaticities Rec2020() { return {0.708, 0.292, 0.170, 0.797, 0.131, 0.046, 0.3127, 0.3290}; }

TEST(RadianceHeader, EveryExposureAndColourCorrectionLineMultiplies) {
  auto h = ParseRadianceHeader(
      "#?RADIANCE\nEXPOSURE=0.5\npfilt -x 512\nEXPOSURE=4\nCOLORCORR= 1 2 0.5\n"
      "COLORCORR=2 1.5 4\nFORMAT=32-bit_rle_rgbe\n",
      "x.hdr");
  ASSERT_TRUE(h.ok()) << h.error().ToString();
  EXPECT_DOUBLE_EQ(h->exposure, 2.0);
  EXPECT_DOUBLE_EQ(h->colour_correction[0], 2.0);
  EXPECT_DOUBLE_EQ(h->colour_correction[1], 3.0);
  EXPECT_DOUBLE_EQ(h->colour_correction[2], 2.0);
  EXPECT_FALSE(h->primaries_given);
  EXPECT_TRUE(h->primaries.SameAs(RadiancePrimaries()));
  EXPECT_FALSE(h->view.has_value());  // a pfilt line is no view
}

TEST(RadianceHeader, PrimariesLineReplacesRadiancesDefault) {
  auto h = ParseRadianceHeader(
      "PRIMARIES= 0.708 0.292 0.170 0.797 0.131 0.046 0.3127 0.3290\n", "x.hdr");
  ASSERT_TRUE(h.ok());
  EXPECT_TRUE(h->primaries_given);
  EXPECT_TRUE(h->primaries.SameAs(Rec2020()));
  EXPECT_FALSE(h->primaries.SameAs(Rec709Primaries()));
}

TEST(RadianceHeader, ViewLinesAccumulateOntoRadiancesDefaultView) {
  auto h = ParseRadianceHeader(
      "VIEW= -vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 60\n"
      "/usr/local/bin/rpict -ab 2 -vv 40 -x 512\n",
      "x.hdr");
  ASSERT_TRUE(h.ok()) << h.error().ToString();
  ASSERT_TRUE(h->view.has_value());
  EXPECT_EQ(h->view->type, 'v');
  EXPECT_DOUBLE_EQ(h->view->horizontal_deg, 60);
  EXPECT_DOUBLE_EQ(h->view->vertical_deg, 40);
  auto one = ParseRadianceHeader("VIEW= -vta -vh 180\n", "x.hdr");
  ASSERT_TRUE(one.ok());
  EXPECT_EQ(one->view->type, 'a');
  EXPECT_DOUBLE_EQ(one->view->vertical_deg, 45);  // Radiance's default -vv
}

TEST(RadianceHeader, MalformedLinesAreErrorsNamingFileAndLine) {
  for (const char* text : {"EXPOSURE=0\n", "EXPOSURE=abc\n", "COLORCORR=1 2\n",
                           "PRIMARIES=0.64 0.33 0.3 0.6\n", "VIEW= -vh wide\n",
                           "PRIMARIES=0.1 0.1 0.2 0.2 0.3 0.3 0.33 0.33\n"}) {
    auto h = ParseRadianceHeader(text, "bad.hdr");
    ASSERT_FALSE(h.ok()) << text;
    EXPECT_NE(h.error().ToString().find("bad.hdr"), std::string::npos) << h.error().ToString();
    EXPECT_NE(h.error().ToString().find(std::string(text).substr(0, 8)), std::string::npos)
        << h.error().ToString();
  }
}

TEST(RadianceHeader, ViewExtentFollowsRadiancesSetview) {
  auto per = ViewExtent({'v', 60, 40});
  ASSERT_TRUE(per.ok());
  EXPECT_NEAR((*per)[0], 2 * std::tan(30 * kRad), 1e-12);
  EXPECT_NEAR((*per)[1], 2 * std::tan(20 * kRad), 1e-12);
  auto ang = ViewExtent({'a', 180, 180});
  ASSERT_TRUE(ang.ok());
  EXPECT_NEAR((*ang)[0], std::numbers::pi, 1e-12);
  auto hem = ViewExtent({'h', 180, 90});
  ASSERT_TRUE(hem.ok());
  EXPECT_NEAR((*hem)[0], 2.0, 1e-12);
  EXPECT_NEAR((*hem)[1], 2 * std::sin(45 * kRad), 1e-12);
  auto cyl = ViewExtent({'c', 360, 60});
  ASSERT_TRUE(cyl.ok());
  EXPECT_NEAR((*cyl)[0], 2 * std::numbers::pi, 1e-12);
  EXPECT_FALSE(ViewExtent({'v', 180, 40}).ok());  // a perspective view under 180 degrees
  EXPECT_FALSE(ViewExtent({'h', 200, 40}).ok());
  EXPECT_FALSE(ViewExtent({'x', 40, 40}).ok());
}

TEST(RadianceHeader, ViewSetsPcondsFovealGridUnlessParallelOrNarrow) {
  PictureHeader h;
  h.view = PictureView{'v', 60, 40};
  ToneMapOptions o;
  ASSERT_TRUE(ApplyPictureHeader(h, &o).ok());
  // 2·tan(30°) / 1° + 0.5 = 66.7 → 66; 2·tan(20°) / 1° + 0.5 = 42.2 → 42.
  EXPECT_EQ(FovealSampleSize(1024, 676, o), cv::Size(66, 42));
  h.view = PictureView{'a', 180, 180};  // a fisheye: π / 1° + 0.5 → 180 each way
  ASSERT_TRUE(ApplyPictureHeader(h, &o).ok());
  EXPECT_EQ(FovealSampleSize(1024, 1024, o), cv::Size(180, 180));
  for (PictureView v : {PictureView{'l', 60, 40}, PictureView{'v', 4, 40}}) {
    h.view = v;
    ASSERT_TRUE(ApplyPictureHeader(h, &o).ok());
    EXPECT_EQ(FovealSampleSize(1024, 676, o), cv::Size(42, 28)) << v.type;  // pcond's default
  }
  h.view = PictureView{'v', 190, 40};
  EXPECT_FALSE(ApplyPictureHeader(h, &o).ok());
  // Radiance's PIXASPECT stretches the default view's shorter side.
  h.view.reset();
  h.pixel_aspect = 1.5;
  ASSERT_TRUE(ApplyPictureHeader(h, &o).ok());
  EXPECT_EQ(FovealSampleSize(1024, 500, o), cv::Size(42, 31));  // 41.7 · 1.5 · 500 / 1024 + .5
}

TEST(RadianceHeader, LuminanceWeightsAreRadiancesForItsPrimaries) {
  // color.h: CIE_rf, CIE_gf, CIE_bf of the standard primaries.
  auto m = RgbToXyzWhiteBalanced(RadiancePrimaries());
  ASSERT_TRUE(m.ok());
  EXPECT_NEAR((*m)(1, 0), 0.265, 5e-4);
  EXPECT_NEAR((*m)(1, 1), 0.670, 5e-4);
  EXPECT_NEAR((*m)(1, 2), 0.065, 5e-4);
  // White goes to the equal-energy white of Y = 1, whatever the primaries.
  for (const Chromaticities& p : {Rec709Primaries(), Rec2020(), RadiancePrimaries()}) {
    auto w = RgbToXyzWhiteBalanced(p);
    ASSERT_TRUE(w.ok());
    const cv::Vec3d xyz = *w * cv::Vec3d(1, 1, 1);
    EXPECT_NEAR(xyz[0], 1, 1e-3);
    EXPECT_NEAR(xyz[1], 1, 1e-9);
    EXPECT_NEAR(xyz[2], 1, 1e-3);
  }
  ToneMapOptions o;
  PictureHeader h;  // a Radiance file without PRIMARIES
  h.primaries = RadiancePrimaries();
  ASSERT_TRUE(ApplyPictureHeader(h, &o).ok());
  const cv::Vec3f w = LuminanceWeightsBgr(o);
  EXPECT_NEAR(w[2], 0.265, 5e-4);  // R
  EXPECT_NEAR(w[0], 0.065, 5e-4);  // B
}

TEST(RadianceHeader, Rec2020ToRec709IsBt2087sMatrix) {
  auto m = RgbToRgbWhiteBalanced(Rec2020(), Rec709Primaries());
  ASSERT_TRUE(m.ok());
  const double bt2087[3][3] = {{1.6605, -0.5876, -0.0728},
                               {-0.1246, 1.1329, -0.0083},
                               {-0.0182, -0.1006, 1.1187}};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR((*m)(r, c), bt2087[r][c], 2e-3) << r << "," << c;
  auto same = RgbToRgbWhiteBalanced(Rec709Primaries(), Rec709Primaries());
  ASSERT_TRUE(same.ok());
  EXPECT_EQ(*same, cv::Matx33d::eye());
  // A different white: white still goes to white (von Kries).
  auto wb = RgbToRgbWhiteBalanced(RadiancePrimaries(), Rec709Primaries());
  ASSERT_TRUE(wb.ok());
  const cv::Vec3d white = *wb * cv::Vec3d(1, 1, 1);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(white[c], 1, 2e-3);
}

TEST(RadianceHeader, DesaturationKeepsLuminanceAndHueClipDoesNot) {
  const cv::Vec3f w(0.0722f, 0.7152f, 0.2126f);  // B, G, R
  cv::Mat px(1, 4, CV_32FC3);
  px.at<cv::Vec3f>(0, 0) = cv::Vec3f(0.1f, 0.5f, 1.6f);    // red over white, in luminance range
  px.at<cv::Vec3f>(0, 1) = cv::Vec3f(-0.2f, 0.6f, 0.5f);   // blue under 0
  px.at<cv::Vec3f>(0, 2) = cv::Vec3f(2.0f, 2.0f, 2.0f);    // brighter than white
  px.at<cv::Vec3f>(0, 3) = cv::Vec3f(0.3f, 0.4f, 0.5f);    // in gamut
  cv::Mat d = px.clone();
  MapToDisplayGamut(&d, cv::Matx33d::eye(), w, GamutMapping::kDesaturate);
  for (int i : {0, 1}) {
    const cv::Vec3f in = px.at<cv::Vec3f>(0, i), out = d.at<cv::Vec3f>(0, i);
    const float l_in = w.dot(in), l_out = w.dot(out);
    EXPECT_NEAR(l_out, l_in, 1e-5) << i;
    // Towards grey along the same direction: (out − L) = k (in − L), one channel on the edge.
    const float k = (out[1] - l_in) / (in[1] - l_in);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(out[c] - l_in, k * (in[c] - l_in), 1e-5);
    EXPECT_GT(k, 0);
    EXPECT_LT(k, 1);
    EXPECT_NEAR(std::min({out[0], out[1], out[2], 1 - out[0], 1 - out[1], 1 - out[2]}), 0, 1e-5);
  }
  EXPECT_EQ(d.at<cv::Vec3f>(0, 2), cv::Vec3f(1, 1, 1));
  EXPECT_EQ(d.at<cv::Vec3f>(0, 3), px.at<cv::Vec3f>(0, 3));
  cv::Mat c = px.clone();
  MapToDisplayGamut(&c, cv::Matx33d::eye(), w, GamutMapping::kClip);
  EXPECT_EQ(c.at<cv::Vec3f>(0, 0), px.at<cv::Vec3f>(0, 0));  // left for the encoding to clip
  // A conversion: Rec. 2020's pure green is outside Rec. 709 and is desaturated into it.
  cv::Mat g(1, 1, CV_32FC3, cv::Scalar(0, 0.5, 0));
  auto m = RgbToRgbWhiteBalanced(Rec2020(), Rec709Primaries());
  ASSERT_TRUE(m.ok());
  MapToDisplayGamut(&g, *m, w, GamutMapping::kDesaturate);
  const cv::Vec3f out = g.at<cv::Vec3f>(0, 0);
  for (int ch = 0; ch < 3; ++ch) EXPECT_GE(out[ch], 0.0f);
  EXPECT_GT(out[1], out[0]);
  EXPECT_GT(out[1], out[2]);
}

TEST(RadianceHeader, StratifiedPointsAreOnePerCell) {
  const int cols = 103, rows = 61;
  const cv::Size cells(20, 12);
  const auto idx = StratifiedPixelIndices(cols, rows, cells, 3);
  ASSERT_EQ(idx.size(), 240u);
  for (int j = 0; j < cells.height; ++j) {
    for (int i = 0; i < cells.width; ++i) {
      const int64_t k = idx[static_cast<size_t>(j) * cells.width + i];
      const int64_t x = k % cols, y = k / cols;
      EXPECT_GE(x, i * cols / cells.width);
      EXPECT_LT(x, (i + 1) * cols / cells.width);
      EXPECT_GE(y, j * rows / cells.height);
      EXPECT_LT(y, (j + 1) * rows / cells.height);
    }
  }
  EXPECT_EQ(idx, StratifiedPixelIndices(cols, rows, cells, 3));
  EXPECT_NE(idx, StratifiedPixelIndices(cols, rows, cells, 4));
  EXPECT_EQ(StratifiedPixelIndices(5, 4, cv::Size(50, 50), 1).size(), 20u);  // every pixel
}

// Writes an RGBE file whose header carries `extra` lines (OpenCV's encoder, header edited).
std::string WriteHdr(const std::string& dir, const cv::Mat& bgr, const std::string& extra) {
  std::vector<uchar> bytes;
  EXPECT_TRUE(cv::imencode(".hdr", bgr, bytes));
  std::string s(bytes.begin(), bytes.end());
  const size_t first = s.find('\n') + 1;
  s.insert(first, extra);
  const std::string path = dir + "/picture.hdr";
  std::ofstream(path, std::ios::binary) << s;
  return path;
}

TEST(RadianceHeader, ReaderDividesOutExposureAndColourCorrection) {
  const std::string dir = testing::FreshTempDir("radiance_header");
  cv::Mat img(8, 16, CV_32FC3, cv::Scalar(0.25, 0.5, 1.0));  // B, G, R
  const std::string path = WriteHdr(
      dir, img, "EXPOSURE=2\nEXPOSURE=0.25\nCOLORCORR=2 1 0.5\nVIEW= -vtv -vh 50 -vv 30\n"
                "PRIMARIES=0.708 0.292 0.170 0.797 0.131 0.046 0.3127 0.3290\n");
  auto p = ReadRadiancePicture(path);
  ASSERT_TRUE(p.ok()) << p.error().ToString();
  // Stored / (EXPOSURE 0.5 × COLORCORR): R 1 / (0.5 · 2), G 0.5 / 0.5, B 0.25 / (0.5 · 0.5).
  const cv::Vec3f v = p->radiance.at<cv::Vec3f>(3, 5);
  EXPECT_NEAR(v[2], 1.0, 1e-2);
  EXPECT_NEAR(v[1], 1.0, 1e-2);
  EXPECT_NEAR(v[0], 1.0, 1e-2);
  EXPECT_TRUE(p->header.primaries.SameAs(Rec2020()));
  ASSERT_TRUE(p->header.view.has_value());
  EXPECT_DOUBLE_EQ(p->header.view->horizontal_deg, 50);
  auto plain = ReadRadianceFile(WriteHdr(dir, img, ""));
  ASSERT_TRUE(plain.ok());
  EXPECT_NEAR(plain->at<cv::Vec3f>(0, 0)[2], 1.0, 1e-2);
  {  // no header end within 64 KiB (no newline at all): refused without reading it whole
    std::ofstream(dir + "/endless.hdr", std::ios::binary) << std::string(100000, 'a');
    auto endless = ReadRadiancePicture(dir + "/endless.hdr");
    ASSERT_FALSE(endless.ok());
    EXPECT_NE(endless.error().ToString().find("no end of the Radiance header"), std::string::npos);
  }
  auto bad = ReadRadiancePicture(WriteHdr(dir, img, "EXPOSURE=-1\n"));
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().ToString().find("picture.hdr"), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(RadianceHeader, ExrChromaticitiesAreThePicturesPrimariesRec709WhenAbsent) {
  const std::string dir = testing::FreshTempDir("exr_chroma");
  ExrImage e;
  e.width = 4;
  e.height = 3;
  e.channel_names = {"B", "G", "R"};
  for (int c = 0; c < 3; ++c) e.channels.push_back(cv::Mat(3, 4, CV_32FC1, cv::Scalar(1)));
  const std::string plain = dir + "/plain.exr", wide = dir + "/wide.exr";
  ASSERT_TRUE(WriteExr(plain, e).ok());
  const Chromaticities c = Rec2020();
  e.chromaticities = std::array<double, 8>{c.red_x,  c.red_y,  c.green_x, c.green_y,
                                           c.blue_x, c.blue_y, c.white_x, c.white_y};
  ASSERT_TRUE(WriteExr(wide, e).ok());
  auto a = ReadRadiancePicture(plain), b = ReadRadiancePicture(wide);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_FALSE(a->header.primaries_given);
  EXPECT_TRUE(a->header.primaries.SameAs(Rec709Primaries()));
  EXPECT_TRUE(b->header.primaries_given);
  EXPECT_TRUE(b->header.primaries.SameAs(Rec2020()));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rig
