// process/export: harmonic models into relight's web format, .ptm and .rti and back (exact maps
// between the bases, round-trip PSNR at 12 lights), hand-made files rendered as relight renders
// them (facts of ../shared/docs/rti-formats.md), orientation, and refusals naming file and field.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "process/export/convert.h"
#include "process/export/load_any.h"
#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/model/harmonic/fit.h"
#include "process/model/harmonic/model.h"
#include "process/model/harmonic/loo.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr int kW = 64, kH = 48;

std::vector<Vec3> GridLights() {
  std::vector<Vec3> l;
  for (double v = 0; v <= 30; v += 10)
    for (double h = 0; h <= 90; h += 10) l.push_back(LightDirection(h, v));
  return l;
}

// 12 lights inside the sampled region, off the grid.
std::vector<Vec3> TwelveLights() {
  std::vector<Vec3> l;
  for (double v : {5.0, 15.0, 25.0})
    for (double h : {5.0, 35.0, 55.0, 85.0}) l.push_back(LightDirection(h, v));
  return l;
}

// A model whose coefficients vary smoothly over the image (as a real object's do; noise per
// pixel is not what JPEG planes are for), fitted "in sRGB space": renders between ~0.2 and
// ~0.8 of full scale. `grey` makes the three channels proportional (an exact LRGB).
Model SmoothModel(BasisKind kind, int order, FitSpace space = FitSpace::kSrgb, bool grey = false) {
  ModelInfo info;
  info.method = FitMethod::kLs;
  info.transform.space = space;
  info.lamp_directions = GridLights();
  info.sample_spacing_deg = SampleSpacingDeg(info.lamp_directions);
  Model m(Basis(kind, order), info, kW, kH);
  const auto b = m.basis().Eval(Vec3{0, 0, 1});
  const float tint[3] = {0.8f, 1.0f, 0.9f};
  for (int k = 0; k < m.basis().size(); ++k) {
    cv::Mat c(kH, kW, CV_32FC3);
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        cv::Vec3f v;
        for (int ch = 0; ch < 3; ++ch) {
          const float g = grey ? 0.f : 0.05f * ch;
          v[ch] = k == 0 ? (0.45f + 0.15f * std::sin(x / 7.0f + g) * std::cos(y / 5.0f)) /
                               static_cast<float>(b[0])
                         : 0.06f * std::sin(x / (5.0f + k) + k + g) * std::cos(y / (4.0f + k));
          if (grey) v[ch] *= tint[ch];
        }
        c.at<cv::Vec3f>(y, x) = v;
      }
    m.coefficients().push_back(c);
  }
  return m;
}

// One folder for the whole process (FreshTempDir empties it on every call).
std::string Temp(const std::string& name) {
  static const std::string dir = testing::FreshTempDir("export");
  return dir + "/" + name;
}

double RoundTripDb(const Model& model, const std::string& path) {
  auto loaded = LoadAnyModel(path);
  EXPECT_TRUE(loaded.ok()) << loaded.error().ToString();
  if (!loaded.ok()) return 0;
  EXPECT_EQ((*loaded)->width(), kW);
  EXPECT_EQ((*loaded)->height(), kH);
  const double db = RenderPsnrDb(*WrapHarmonic(model), **loaded, TwelveLights());
  std::printf("round trip %s: %.2f dB\n", path.c_str(), db);
  return db;
}

TEST(ExportConvert, PtmTermOrderMapsExactlyOntoRelightsOrder) {
  const Model m = SmoothModel(BasisKind::kPtm, 2);
  auto c = ConvertToRelight(m, RelightTarget{RelightType::kPtm, 6, false});
  ASSERT_TRUE(c.ok()) << c.error().ToString();
  EXPECT_TRUE(c->exact);
  EXPECT_LT(c->map_residual, 1e-12);
  EXPECT_GT(c->psnr_db, 100);
  // Our order 1, lu, lv, lu², lu·lv, lv² is relight's: the planes are the coefficients × 255.
  for (int j = 0; j < 6; ++j)
    EXPECT_LT(cv::norm(c->coefficients.planes[j], m.coefficients()[j] * 255.0, cv::NORM_INF), 1e-3)
        << "term " << j;
}

TEST(ExportConvert, HshMapsExactlyOntoRelightsWeightsWithNineAndFourTerms) {
  for (auto [order, terms] : {std::pair{2, 9}, std::pair{1, 4}}) {
    const Model m = SmoothModel(BasisKind::kHsh, order);
    auto c = ConvertToRelight(m, RelightTarget{RelightType::kHsh, terms, false});
    ASSERT_TRUE(c.ok()) << c.error().ToString();
    EXPECT_TRUE(c->exact);
    EXPECT_LT(c->map_residual, 1e-9);
    // The same function wherever relight does not clamp θ (at π/2 − 0.01) ...
    EXPECT_GT(RenderPsnrDb(*WrapHarmonic(m), *WrapRelight(c->coefficients, ""), TwelveLights()), 100);
    // ... and the sampled lights on the horizon (h 90°, v 0°) say what the clamp costs.
    EXPECT_THAT(c->how, HasSubstr("horizon"));
    EXPECT_GT(c->psnr_db, 45);
    std::printf("hsh order %d -> %d terms: %.2f dB over the 40 sampled lights\n", order, terms, c->psnr_db);
  }
  // HSH order 2 cannot go into 4 terms: refitted, and the loss reported.
  auto c24 = ConvertToRelight(SmoothModel(BasisKind::kHsh, 2), RelightTarget{RelightType::kHsh, 4, false});
  ASSERT_TRUE(c24.ok());
  EXPECT_FALSE(c24->exact);
  EXPECT_LT(c24->psnr_db, 100);
}

TEST(ExportConvert, ShAndLinearFitSpaceAreRefittedAndTheReportedPsnrIsTheMeasuredOne) {
  for (const Model& m : {SmoothModel(BasisKind::kSh, 2), SmoothModel(BasisKind::kPtm, 2, FitSpace::kLinear)}) {
    auto c = ConvertToRelight(m, RelightTarget{RelightType::kHsh, 9, false});
    ASSERT_TRUE(c.ok()) << c.error().ToString();
    EXPECT_FALSE(c->exact);
    EXPECT_EQ(c->lights, 40);
    EXPECT_THAT(c->how, HasSubstr("refitted"));
    const auto back = WrapRelight(c->coefficients, "");
    EXPECT_NEAR(RenderPsnrDb(*WrapHarmonic(m), *back, GridLights()), c->psnr_db, 1e-6);
    EXPECT_GT(c->psnr_db, 25);  // a smooth model: the refit is close, and not identical
    std::printf("%s %s refit onto hsh9: %.2f dB at the 40 sampled lights\n", m.basis().name().c_str(),
                FitSpaceName(m.info().transform.space), c->psnr_db);
  }
}

TEST(ExportRoundTrip, WebFormatPtmAndHshHoldTheModelAbove45Db) {
  for (auto [kind, type, terms] : {std::tuple{BasisKind::kPtm, RelightType::kPtm, 6},
                                   std::tuple{BasisKind::kHsh, RelightType::kHsh, 9}}) {
    const Model m = SmoothModel(kind, 2);
    auto c = ConvertToRelight(m, RelightTarget{type, terms, false});
    ASSERT_TRUE(c.ok());
    for (bool ycbcr : {true, false}) {
      const std::string dir = Temp(std::string(RelightTypeName(type)) + (ycbcr ? "-ycc" : "-rgb"));
      WebWriteOptions o;
      o.ycbcr = ycbcr;
      ASSERT_TRUE(WriteRelightWeb(dir, c->coefficients, o).ok());
      EXPECT_GE(RoundTripDb(m, dir), 45.0);
      // relight's fields, in its order.
      std::ifstream f(dir + "/info.json");
      const auto info = nlohmann::ordered_json::parse(f);
      std::vector<std::string> keys;
      for (auto it = info.begin(); it != info.end(); ++it) keys.push_back(it.key());
      EXPECT_THAT(keys, ::testing::ElementsAre("width", "height", "format", "type", "colorspace",
                                                "lights", "nplanes", "quality", "colorprofile",
                                                "materials"));
      EXPECT_EQ(info["nplanes"], 3 * terms);
      EXPECT_EQ(info["materials"][0]["scale"].size(), static_cast<size_t>(3 * terms));
      EXPECT_EQ(info["lights"].size(), 120u);
      for (int j = 0; j < terms; ++j) EXPECT_TRUE(fs::exists(dir + fmt::format("/plane_{}.jpg", j)));
    }
  }
}

TEST(ExportRoundTrip, PtmRgbAndRtiHoldTheModelAbove45Db) {
  const Model ptm = SmoothModel(BasisKind::kPtm, 2);
  auto c = ConvertToRelight(ptm, RelightTarget{RelightType::kPtm, 6, false});
  ASSERT_TRUE(c.ok());
  const std::string p = Temp("m.ptm");
  ASSERT_TRUE(WritePtm(p, c->coefficients).ok());
  EXPECT_GE(RoundTripDb(ptm, p), 45.0);

  const Model hsh = SmoothModel(BasisKind::kHsh, 2);
  auto h = ConvertToRelight(hsh, RelightTarget{RelightType::kHsh, 9, false});
  ASSERT_TRUE(h.ok());
  const std::string r = Temp("m.rti");
  ASSERT_TRUE(WriteRti(r, h->coefficients).ok());
  EXPECT_GE(RoundTripDb(hsh, r), 45.0);
}

// A refit on every core: told each stage to its end, in order, and the same planes as a
// refit told nothing; RTIViewer's 16 HSH terms hold an SH of order 3 better than 9 do.
TEST(ExportConvert, RefitProgressReachesEveryLightAndHsh16HoldsMoreThan9) {
  const Model m = SmoothModel(BasisKind::kSh, 3);
  std::vector<std::string> stages;
  std::vector<size_t> last;
  bool monotonic = true;
  const LightProgress progress = [&](const char* stage, size_t done, size_t total) {
    if (stages.empty() || stages.back() != stage) {
      stages.push_back(stage);
      last.push_back(0);
    }
    monotonic = monotonic && done == last.back() + 1 && done <= total;
    last.back() = done;
  };
  const RelightTarget t16{RelightType::kHsh, 16, false};
  auto told = ConvertToRelight(m, t16, progress);
  ASSERT_TRUE(told.ok()) << told.error().ToString();
  EXPECT_THAT(stages, ::testing::ElementsAre("refitting", "measuring the error"));
  EXPECT_TRUE(monotonic);
  ASSERT_EQ(last.size(), 2u);
  EXPECT_EQ(last[0], static_cast<size_t>(told->lights));
  EXPECT_EQ(last[1], static_cast<size_t>(told->lights));
  auto quiet = ConvertToRelight(m, t16);
  ASSERT_TRUE(quiet.ok());
  for (int j = 0; j < 16; ++j)
    EXPECT_EQ(cv::norm(told->coefficients.planes[j], quiet->coefficients.planes[j], cv::NORM_INF), 0) << j;
  auto nine = ConvertToRelight(m, RelightTarget{RelightType::kHsh, 9, false});
  ASSERT_TRUE(nine.ok());
  EXPECT_GT(told->psnr_db, nine->psnr_db + 3) << told->psnr_db << " " << nine->psnr_db;
}

TEST(ExportRoundTrip, PtmLrgbHoldsAModelWithProportionalChannels) {
  const Model m = SmoothModel(BasisKind::kPtm, 2, FitSpace::kSrgb, /*grey=*/true);
  auto c = ConvertToRelight(m, RelightTarget{RelightType::kPtm, 6, true});
  ASSERT_TRUE(c.ok()) << c.error().ToString();
  EXPECT_FALSE(c->exact);  // a factorisation: exact only because the channels are proportional
  EXPECT_GT(c->psnr_db, 45);
  const std::string p = Temp("lrgb.ptm");
  ASSERT_TRUE(WritePtm(p, c->coefficients).ok());
  EXPECT_GE(RoundTripDb(m, p), 45.0);
  // relight's lptm web format: plane_0 the albedo bytes, planes 3..8 the luminance.
  const std::string web = Temp("lrgb-web");
  ASSERT_TRUE(WriteRelightWeb(web, c->coefficients, {}).ok());
  std::ifstream info_file(web + "/info.json");
  const auto info = nlohmann::json::parse(info_file);
  EXPECT_EQ(info["colorspace"], "lrgb");
  EXPECT_EQ(info["nplanes"], 9);
  EXPECT_EQ(info["materials"][0]["scale"][0], 1);
  EXPECT_EQ(info["materials"][0]["bias"][0], 0);
  EXPECT_FALSE(fs::exists(web + "/plane_3.jpg"));
  EXPECT_GE(RoundTripDb(m, web), 45.0);
  // A coloured model is factorised with a loss, reported.
  auto coloured = ConvertToRelight(SmoothModel(BasisKind::kPtm, 2), RelightTarget{RelightType::kPtm, 6, true});
  ASSERT_TRUE(coloured.ok());
  std::printf("coloured PTM -> LRGB: %.2f dB\n", coloured->psnr_db);
  EXPECT_LT(coloured->psnr_db, c->psnr_db);
}

// ---- hand-made files ---------------------------------------------------------------------

std::string WriteBytes(const std::string& path, const std::string& header, const std::vector<uint8_t>& data) {
  std::ofstream f(path, std::ios::binary);
  f << header;
  f.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
  return path;
}

// A 16x8 PTM_FORMAT_RGB, scale 1 and bias 0: red has constant 50 and x 100; green constant 80;
// blue constant 20. File row 0 (the bottom image row) has blue's constant 200.
std::string HandMadePtm(const std::string& path) {
  const int w = 16, h = 8;
  std::vector<uint8_t> d(static_cast<size_t>(w) * h * 18, 0);
  for (int k = 0; k < 3; ++k)
    for (int fy = 0; fy < h; ++fy)
      for (int x = 0; x < w; ++x) {
        uint8_t* px = &d[(static_cast<size_t>(k) * w * h + fy * w + x) * 6];  // x² y² xy x y 1
        if (k == 0) { px[3] = 100; px[5] = 50; }
        if (k == 1) px[5] = 80;
        if (k == 2) px[5] = fy == 0 ? 200 : 20;
      }
  return WriteBytes(path, "PTM_1.2\nPTM_FORMAT_RGB\n16\n8\n1 1 1 1 1 1\n0 0 0 0 0 0\n", d);
}

TEST(ExportReaders, HandMadePtmRgbRendersAsRelightDoes) {
  auto m = LoadAnyModel(HandMadePtm(Temp("rgb.ptm")));
  ASSERT_TRUE(m.ok()) << m.error().ToString();
  const RelightCoefficients* c = RelightCoefficientsOf(**m);
  ASSERT_NE(c, nullptr);
  const cv::Mat v = RenderRelight(*c, Vec3{0.6, 0, 0.8});
  // Light x = 0.6 gives +60 on red; the others keep their constants.
  EXPECT_FLOAT_EQ(v.at<cv::Vec3f>(0, 0)[2], 110.f);
  EXPECT_FLOAT_EQ(v.at<cv::Vec3f>(0, 0)[1], 80.f);
  EXPECT_FLOAT_EQ(v.at<cv::Vec3f>(0, 0)[0], 20.f);
  // File row 0 is the bottom image row.
  EXPECT_FLOAT_EQ(v.at<cv::Vec3f>(7, 3)[0], 200.f);
  EXPECT_FLOAT_EQ(v.at<cv::Vec3f>(6, 3)[0], 20.f);
  // Behind the interface: the sRGB decode of value / 255.
  const cv::Mat rho = (*m)->EvaluateRho(Vec3{0.6, 0, 0.8});
  EXPECT_NEAR(rho.at<cv::Vec3f>(0, 0)[2], SrgbDecode(110.f / 255.f), 1e-6);
  EXPECT_EQ((*m)->family(), "ptm");
  EXPECT_EQ((*m)->encoding(), ValueEncoding::kSrgb);
}

TEST(ExportReaders, HandMadePtmLrgbScalesRgbByLuminance) {
  const int w = 16, h = 8;
  std::vector<uint8_t> d;
  for (int i = 0; i < w * h; ++i) d.insert(d.end(), {0, 0, 0, 64, 0, 255});  // x² y² xy x y 1
  for (int i = 0; i < w * h; ++i) d.insert(d.end(), {100, 50, 20});
  auto m = LoadAnyModel(WriteBytes(Temp("lrgb.ptm"), "PTM_1.2\nPTM_FORMAT_LRGB\n16\n8\n1 1 1 1 1 1\n0 0 0 0 0 0\n", d));
  ASSERT_TRUE(m.ok()) << m.error().ToString();
  EXPECT_EQ((*m)->family(), "ptm-lrgb");
  const cv::Mat v = RenderRelight(*RelightCoefficientsOf(**m), Vec3{0.6, 0, 0.8});
  const double l = (255 + 64 * 0.6) / 255;  // 1.15
  EXPECT_NEAR(v.at<cv::Vec3f>(4, 4)[2], 100 * l, 1e-4);
  EXPECT_NEAR(v.at<cv::Vec3f>(4, 4)[1], 50 * l, 1e-4);
  EXPECT_NEAR(v.at<cv::Vec3f>(4, 4)[0], 20 * l, 1e-4);
}

TEST(ExportReaders, HandMadeRtiKeepsTermZeroAndReadsTopDown) {
  const int w = 16, h = 8, t = 9;
  std::string header = "#HSH1.2\n# a comment\n3\n16 8 3\n9 2 1\n";
  std::vector<uint8_t> d;
  auto put = [&](float v) {
    uint8_t b[4];
    std::memcpy(b, &v, 4);
    d.insert(d.end(), b, b + 4);
  };
  for (int j = 0; j < t; ++j) put(1.0f);  // scale: coefficient/255 = byte/255 · 1 + bias
  for (int j = 0; j < t; ++j) put(0.0f);  // bias
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < t; ++j) d.push_back(j == 0 ? (y == 0 ? 250 : 100 + 10 * k) : 0);
  auto m = LoadAnyModel(WriteBytes(Temp("hsh.rti"), header, d));
  ASSERT_TRUE(m.ok()) << m.error().ToString();
  const RelightCoefficients* c = RelightCoefficientsOf(**m);
  ASSERT_NE(c, nullptr);
  EXPECT_EQ(c->terms, 9);
  EXPECT_FLOAT_EQ(c->planes[0].at<cv::Vec3f>(3, 3)[2], 100.f);  // R
  EXPECT_FLOAT_EQ(c->planes[0].at<cv::Vec3f>(3, 3)[0], 120.f);  // B
  EXPECT_FLOAT_EQ(c->planes[0].at<cv::Vec3f>(0, 3)[1], 250.f);  // file row 0 is the top row
  const cv::Mat v = RenderRelight(*c, Vec3{0.3, 0.2, 0.93});
  EXPECT_NEAR(v.at<cv::Vec3f>(3, 3)[2], 100 / std::sqrt(2 * M_PI), 1e-4);
}

TEST(ExportWriters, PtmBottomUpRowsAndBiasesWithinTheByteRangeHoldTheCoefficients) {
  RelightCoefficients c;
  c.type = RelightType::kPtm;
  c.terms = 6;
  c.width = 4;
  c.height = 3;
  for (int j = 0; j < 6; ++j) c.planes.push_back(cv::Mat(3, 4, CV_32FC3, cv::Scalar::all(0)));
  c.planes[0].at<cv::Vec3f>(0, 0) = cv::Vec3f(300, 310, 320);  // above 255, all positive
  c.planes[0].at<cv::Vec3f>(2, 0) = cv::Vec3f(200, 210, 220);  // bottom-left, B G R
  c.planes[3] = cv::Scalar::all(-125);                        // x², all negative
  const std::string p = Temp("bias.ptm");
  ASSERT_TRUE(WritePtm(p, c).ok());
  auto back = ReadPtm(p);
  ASSERT_TRUE(back.ok()) << back.error().ToString();
  for (int j = 0; j < 6; ++j)
    EXPECT_LT(cv::norm(back->planes[j], c.planes[j], cv::NORM_INF), 320.0 / 254 / 2 + 1e-3) << j;
  // The header's biases are bytes (the specification's, which strict readers hold to), even
  // for a term all positive or all negative, and the first pixel of the file is the bottom-left
  // one: its red constant (file coefficient 6) is 200.
  std::ifstream f(p, std::ios::binary);
  std::string line, scales, biases;
  for (int i = 0; i < 4; ++i) std::getline(f, line);
  std::getline(f, scales);
  std::getline(f, biases);
  double scale[6], bias[6];
  std::istringstream ss(scales), bs(biases);
  for (int i = 0; i < 6; ++i) ss >> scale[i];
  for (int i = 0; i < 6; ++i) bs >> bias[i];
  for (int i = 0; i < 6; ++i) {
    EXPECT_GE(bias[i], 0) << i;
    EXPECT_LE(bias[i], 255) << i;
    EXPECT_EQ(bias[i], std::round(bias[i])) << i;
  }
  EXPECT_GE(bias[0], 254);  // x², all -125: the range -125..0, 0 at the top byte
  unsigned char px[6];
  f.read(reinterpret_cast<char*>(px), 6);
  EXPECT_NEAR((px[5] - bias[5]) * scale[5], 220.0, 320.0 / 254);  // R of the bottom-left pixel
}

// ---- refusals ------------------------------------------------------------------------------

// relight's sh folders (type "sh", rgb): read and rendered with Rti::lightWeightsSh. The
// expected values come from the trigonometric form of the same harmonics (0.5/sqrt(pi),
// 0.5 sqrt(3/pi) sin(phi) sin(theta), ...), not from the constants the reader uses.
TEST(ExportReaders, ShFoldersRenderWithRelightsRealHarmonics) {
  for (int terms : {9, 4}) {
    RelightCoefficients c;
    c.type = RelightType::kSh;
    c.terms = terms;
    c.width = kW;
    c.height = kH;
    for (int j = 0; j < terms; ++j) {
      cv::Mat p(kH, kW, CV_32FC3);
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
          for (int ch = 0; ch < 3; ++ch)
            p.at<cv::Vec3f>(y, x)[ch] = (j == 0 ? 300.f : 40.f / (j + 1)) + 0.5f * x + 10.f * ch;
      c.planes.push_back(p);
    }
    const std::string dir = Temp("sh" + std::to_string(terms));
    ASSERT_TRUE(WriteRelightWeb(dir, c, {}).ok());
    auto m = LoadAnyModel(dir);
    ASSERT_TRUE(m.ok()) << m.error().ToString();
    EXPECT_EQ((*m)->family(), "sh");
    const RelightCoefficients* back = RelightCoefficientsOf(**m);
    ASSERT_NE(back, nullptr);
    EXPECT_EQ(back->terms, terms);
    const double theta = 40 * M_PI / 180, phi = 120 * M_PI / 180;
    const Vec3 d{std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
    const double st = std::sin(theta), ct = std::cos(theta);
    const double y[9] = {0.5 / std::sqrt(M_PI),
                         0.5 * std::sqrt(3 / M_PI) * std::sin(phi) * st,
                         0.5 * std::sqrt(3 / M_PI) * ct,
                         0.5 * std::sqrt(3 / M_PI) * std::cos(phi) * st,
                         0.25 * std::sqrt(15 / M_PI) * std::sin(2 * phi) * st * st,
                         0.5 * std::sqrt(15 / M_PI) * st * ct * std::sin(phi),
                         0.25 * std::sqrt(5 / M_PI) * (3 * ct * ct - 1),
                         0.5 * std::sqrt(15 / M_PI) * st * ct * std::cos(phi),
                         0.25 * std::sqrt(15 / M_PI) * st * st * std::cos(2 * phi)};
    const cv::Mat v = RenderRelight(*back, d);
    for (int x : {3, 30, 60}) {
      for (int ch = 0; ch < 3; ++ch) {
        double want = 0;
        for (int j = 0; j < terms; ++j) want += y[j] * c.planes[j].at<cv::Vec3f>(20, x)[ch];
        // The planes as written: 8-bit JPEG at q95 of a ramp, half a step of each range.
        EXPECT_NEAR(v.at<cv::Vec3f>(20, x)[ch], want, 1.0) << "terms " << terms << " x " << x << " ch " << ch;
      }
    }
  }
  // A type not read (relight's dmd) says what is.
  const std::string rbf = Temp("sh9");
  {
    std::ifstream f(rbf + "/info.json");
    auto info = nlohmann::ordered_json::parse(f);
    info["type"] = "dmd";
    std::ofstream(rbf + "/info.json") << info.dump();
  }
  auto r = LoadAnyModel(rbf);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().ToString(), HasSubstr("sh rgb"));
}

TEST(ExportReaders, TruncatedAndInconsistentFilesAreRefusedWithFileAndField) {
  const std::string good = HandMadePtm(Temp("good.ptm"));
  const auto size = fs::file_size(good);
  const std::string cut = Temp("cut.ptm");
  fs::copy_file(good, cut);
  fs::resize_file(cut, size - 10);
  auto r = LoadAnyModel(cut);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().ToString(), HasSubstr(cut));
  EXPECT_THAT(r.error().ToString(), HasSubstr("truncated"));

  auto check = [](const std::string& path, const char* field) {
    auto m = LoadAnyModel(path);
    ASSERT_FALSE(m.ok()) << path;
    EXPECT_THAT(m.error().ToString(), HasSubstr(path));
    EXPECT_THAT(m.error().ToString(), HasSubstr(field));
  };
  check(WriteBytes(Temp("lum.ptm"), "PTM_1.2\nPTM_FORMAT_LUM\n16\n8\n", {}), "format");
  check(WriteBytes(Temp("huge.ptm"), "PTM_1.2\nPTM_FORMAT_RGB\n100000\n100000\n1 1 1 1 1 1\n0 0 0 0 0 0\n", {}),
        "width, height");
  check(WriteBytes(Temp("big.ptm"), "PTM_1.2\nPTM_FORMAT_RGB\n16000\n16000\n1 1 1 1 1 1\n0 0 0 0 0 0\n", {1, 2}),
        "truncated");
  check(WriteBytes(Temp("scale.ptm"), "PTM_1.2\nPTM_FORMAT_RGB\n16\n8\n1 1 1 1 1\n0 0 0 0 0 0\n", {}), "scale");
  check(WriteBytes(Temp("hdr.ptm"), "PTM_1.2\nPTM_FORMAT_RGB\n16\n", {}), "height");
  check(WriteBytes(Temp("ptm.rti"), "#HSH1.2\n1\n16 8 3\n6 1 1\n", {}), "rti_type");
  check(WriteBytes(Temp("c4.rti"), "#HSH1.2\n3\n16 8 4\n9 2 1\n", {}), "components");
  check(WriteBytes(Temp("e2.rti"), "#HSH1.2\n3\n16 8 3\n9 2 2\n", {}), "element_size");
  check(WriteBytes(Temp("short.rti"), "#HSH1.2\n3\n16 8 3\n9 2 1\n", std::vector<uint8_t>(100)), "truncated");

  // A web folder whose plane count disagrees with its type, or that lacks a plane.
  const Model m = SmoothModel(BasisKind::kPtm, 2);
  auto c = ConvertToRelight(m, RelightTarget{RelightType::kPtm, 6, false});
  ASSERT_TRUE(c.ok());
  const std::string dir = Temp("web");
  ASSERT_TRUE(WriteRelightWeb(dir, c->coefficients, {}).ok());
  {
    std::ifstream f(dir + "/info.json");
    auto info = nlohmann::ordered_json::parse(f);
    info["nplanes"] = 17;
    std::ofstream(dir + "/info.json") << info.dump();
  }
  check(dir, "nplanes");
  {
    std::ifstream f(dir + "/info.json");
    auto info = nlohmann::ordered_json::parse(f);
    info["nplanes"] = 18;
    info["materials"][0]["bias"].erase(0);
    std::ofstream(dir + "/info.json") << info.dump();
  }
  check(dir, "materials[0].bias");
  {
    std::ifstream f(dir + "/info.json");
    auto info = nlohmann::ordered_json::parse(f);
    info["materials"][0]["bias"] = info["materials"][0]["scale"];
    std::ofstream(dir + "/info.json") << info.dump();
  }
  fs::remove(dir + "/plane_5.jpg");
  check(dir, "plane_5.jpg");
  // Writing over a model is refused.
  EXPECT_FALSE(WriteRelightWeb(dir, c->coefficients, {}).ok());
}

TEST(ExportLp, WrittenLpReadsBackWithItsDirections) {
  const std::string dir = testing::FreshTempDir("export-lp");
  const auto lights = GridLights();
  std::vector<std::string> names;
  for (size_t i = 0; i < lights.size(); ++i) names.push_back(fmt::format("img_{:02}.png", i));
  ASSERT_TRUE(WriteLp(dir + "/dirs.lp", names, lights).ok());
  auto lp = ReadLp(dir + "/dirs.lp");
  ASSERT_TRUE(lp.ok()) << lp.error().ToString();
  ASSERT_EQ(lp->size(), lights.size());
  for (size_t i = 0; i < lights.size(); ++i) {
    EXPECT_THAT((*lp)[i].image, HasSubstr(names[i]));
    Vec3 expected = lights[i];
    LiftToLowestElevation(&expected);  // the grid's horizon row is read just above it
    for (int k = 0; k < 3; ++k) EXPECT_NEAR((*lp)[i].direction[k], expected[k], 1e-6);
  }
}

// A light a fraction of a degree below the horizon (calibration noise) is read just above it,
// its azimuth kept; one well below is left for the families to refuse or fit.
TEST(ExportLp, LightsWithinTheHorizonsToleranceAreLiftedJustAboveIt) {
  const std::string dir = testing::FreshTempDir("lp-horizon");
  auto dir_at = [](double az_deg, double el_deg) {
    const double a = az_deg * M_PI / 180, e = el_deg * M_PI / 180;
    return Vec3{std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)};
  };
  const std::vector<Vec3> lights = {dir_at(30, -0.07), dir_at(120, 0.0), dir_at(200, -5.0),
                                    dir_at(45, 40.0)};
  ASSERT_TRUE(WriteLp(dir + "/dirs.lp", {"a.jpg", "b.jpg", "c.jpg", "d.jpg"}, lights).ok());
  auto lp = ReadLp(dir + "/dirs.lp");
  ASSERT_TRUE(lp.ok()) << lp.error().ToString();
  const double lowest = std::sin(kLowestElevationDeg * M_PI / 180);
  for (int i : {0, 1}) {
    EXPECT_NEAR((*lp)[i].direction[2], lowest, 1e-6) << i;
    const double az = std::atan2((*lp)[i].direction[1], (*lp)[i].direction[0]) * 180 / M_PI;
    EXPECT_NEAR(az, i == 0 ? 30 : 120, 1e-4);  // .lp files hold 6 decimals
  }
  EXPECT_NEAR((*lp)[2].direction[2], lights[2][2], 1e-6);  // 5 degrees below: as written
  for (int k = 0; k < 3; ++k) EXPECT_NEAR((*lp)[3].direction[k], lights[3][k], 1e-6);
}

}  // namespace
}  // namespace rig
