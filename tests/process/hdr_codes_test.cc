// Reflectance of radiance maps as 8-bit codes (process/model/hdr_codes.h) and the PCA family
// fitted to them: the curves against their formulas, the range from the data's quantiles, the
// samples from maps, and a PCA model of an HDR scene (a matte surface with a highlight 200×
// brighter) written, read back and decoded to linear reflectance and radiance.
#include <cmath>
#include <cstring>
#include <random>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "process/model/any/load_model.h"
#include "process/model/hdr_codes.h"
#include "process/model/pca/pca.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

TEST(HdrCodes, LogCurveIsRelativeAboveItsFloorAndZeroAtZero) {
  HdrCodeCurve c{HdrCurve::kLog, 100.0, 0.01};
  EXPECT_EQ(c.Encode(0), 0);
  EXPECT_EQ(c.Encode(-1), 0);
  EXPECT_NEAR(c.Encode(100), 255, 1e-9);
  EXPECT_NEAR(c.Decode(255), 100, 1e-9);
  for (double rho : {0.001, 0.05, 1.0, 37.0}) EXPECT_NEAR(c.Decode(c.Encode(rho)), rho, 1e-9 * rho);
  // Far above the floor a code is a constant ratio: ln(1 + 1e4) / 255 per code.
  const double step = std::log1p(100 / 0.01) / 255;
  EXPECT_NEAR(c.TopStep(), std::expm1(step), 1e-3 * c.TopStep());
  EXPECT_NEAR(c.Encode(50) - c.Encode(25), std::log(2.0) / step, 0.01);
}

TEST(HdrCodes, SrgbCurveScalesThePhotographsCurve) {
  HdrCodeCurve c{HdrCurve::kSrgb, 8.0, 1};
  EXPECT_NEAR(c.Encode(8), 255, 1e-4);
  EXPECT_NEAR(c.Encode(8 * 0.2140), 255 * 0.5, 0.05);  // sRGB(0.214) = 0.5
  EXPECT_NEAR(c.Decode(c.Encode(3.3)), 3.3, 1e-4);
}

TEST(HdrCodes, RangeFromTheDataQuantiles) {
  // ρ = 0.001 · 1.001^i, i = 0 .. 9999 in every channel: quantiles known.
  cv::Mat m(100, 100, CV_32FC3);
  for (int i = 0; i < 10000; ++i) {
    const float v = static_cast<float>(0.001 * std::pow(1.001, i));
    m.at<cv::Vec3f>(i / 100, i % 100) = {v, v, v};
  }
  m.at<cv::Vec3f>(0, 0) = {0, 0, 0};  // a black pixel: counted in max's quantile, not floor's
  HdrCurveOptions o;
  o.high = 0.9;
  o.low = 0.1;
  const HdrCodeCurve c = FitHdrCurve({m}, o);
  EXPECT_NEAR(c.max, 0.001 * std::pow(1.001, 9000), 0.01 * c.max);
  EXPECT_NEAR(c.floor, 0.001 * std::pow(1.001, 1000), 0.01 * c.floor);
  o.max_stops = 2;  // the floor no lower than max / 4
  EXPECT_NEAR(FitHdrCurve({m}, o).floor, c.max / 4, 1e-9 * c.max);
}

TEST(HdrCodes, SamplesFromMapsDivideByTheLampAndClampTheEnds) {
  cv::Mat map(1, 3, CV_32FC3);
  map.at<cv::Vec3f>(0, 0) = {0.5f, 1.0f, 2.0f};  // B, G, R
  map.at<cv::Vec3f>(0, 1) = {-1.0f, NAN, 0.0f};
  map.at<cv::Vec3f>(0, 2) = {1e6f, 1e6f, 1e6f};
  const HdrCodeCurve c{HdrCurve::kLog, 10.0, 0.01};
  const std::array<double, 3> lamp = {2.0, 1.0, 0.5};  // R, G, B
  const LightSamples s = SamplesFromMaps({map}, {{0, 0, 1}}, lamp, c);
  ASSERT_EQ(s.values.size(), 9u);
  EXPECT_EQ(s.value(0, 0, 0), std::lround(c.Encode(2.0 / 2.0)));  // R
  EXPECT_EQ(s.value(0, 0, 1), std::lround(c.Encode(1.0 / 1.0)));  // G
  EXPECT_EQ(s.value(0, 0, 2), std::lround(c.Encode(0.5 / 0.5)));  // B
  for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(s.value(1, 0, ch), 0);
  for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(s.value(2, 0, ch), 255);
}

// An HDR scene: matte albedo 0.2–0.5 and a Phong highlight up to 100, under 40 lamps.
struct HdrScene {
  int width = 48, height = 32;
  std::vector<Vec3> lights;
  HdrScene() {
    for (double v : {0.0, 10.0, 20.0, 30.0})
      for (double h = 0; h <= 90; h += 10) lights.push_back(LightDirection(h, v));
  }
  double Rho(int x, int y, const Vec3& l, int c) const {
    const double u = (x + 0.5) / width - 0.5, w = (y + 0.5) / height - 0.5;
    Vec3 n = {0.6 * u, 0.6 * w, 1};
    const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (auto& q : n) q /= nn;
    const double albedo = (0.2 + 0.3 * ((x / 6 + y / 6) % 2)) * (c == 0 ? 1.0 : c == 1 ? 0.8 : 0.6);
    const double ndl = std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
    const double rz = 2 * ndl * n[2] - l[2];
    return albedo * ndl + 100.0 * std::pow(std::max(0.0, rz), 40);
  }
  std::vector<cv::Mat> Radiance(const std::array<double, 3>& lamp) const {
    std::vector<cv::Mat> out;
    for (const Vec3& l : lights) {
      cv::Mat m(height, width, CV_32FC3);
      for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
          for (int c = 0; c < 3; ++c) m.at<cv::Vec3f>(y, x)[2 - c] = static_cast<float>(Rho(x, y, l, c) * lamp[c]);
      out.push_back(m);
    }
    return out;
  }
};

TEST(HdrPca, ModelOfRadianceMapsDecodesToLinearReflectanceAndRadiance) {
  const HdrScene scene;
  const std::array<double, 3> lamp = {2.0, 1.5, 1.0};
  const auto maps = scene.Radiance(lamp);
  HdrCurveOptions co;
  co.curve = HdrCurve::kPower;
  co.gamma = 1.25;
  co.high = 1.0;
  const HdrCodeCurve curve = FitHdrCurve(ReflectanceOf(maps, lamp), co);
  EXPECT_GT(curve.max, 50);  // the highlight is in range
  const LightSamples s = SamplesFromMaps(maps, scene.lights, lamp, curve);
  PcaOptions o;
  o.components = 12;
  o.grid_resolution = 16;
  o.jpeg_quality = 95;
  o.thresholds = kHdrMaskThresholds;
  auto m = FitPca(s, o);
  ASSERT_TRUE(m.ok()) << m.error().ToString();
  LightFrameConfig frame;
  frame.h_offset_deg = 0;
  m->set_hdr({curve, lamp, frame});
  const std::string dir = testing::FreshTempDir("hdr_pca") + "/model";
  ASSERT_TRUE(m->Save(dir).ok());
  {
    std::ifstream f(dir + "/info.json");
    const auto info = nlohmann::json::parse(f);
    EXPECT_EQ(info.at("rig").at("values").at("encoding"), "power");
    EXPECT_DOUBLE_EQ(info.at("rig").at("values").at("max").get<double>(), curve.max);
  }
  auto loaded = LoadReflectanceModel(dir);
  ASSERT_TRUE(loaded.ok()) << loaded.error().ToString();
  const ReflectanceModel& r = **loaded;
  EXPECT_EQ(r.encoding(), ValueEncoding::kLinear);
  EXPECT_EQ(r.lamp_radiance_rgb(), lamp);
  // At sampled lamps: ρ within a few percent of the truth overall, the highlight kept.
  double err = 0, ref = 0, peak = 0, peak_truth = 0;
  for (int l : {3, 14, 25, 36}) {
    const cv::Mat rho = r.EvaluateRho(scene.lights[l]);
    cv::Mat radiance;
    r.AddLamp(scene.lights[l], {1, 1, 1}, &radiance);
    for (int y = 0; y < scene.height; ++y)
      for (int x = 0; x < scene.width; ++x)
        for (int c = 0; c < 3; ++c) {
          const double t = scene.Rho(x, y, scene.lights[l], c), p = rho.at<cv::Vec3f>(y, x)[2 - c];
          err += (p - t) * (p - t);
          ref += t * t;
          peak = std::max(peak, p);
          peak_truth = std::max(peak_truth, t);
          EXPECT_NEAR(radiance.at<cv::Vec3f>(y, x)[2 - c], p * lamp[c], 1e-4 * (1 + p * lamp[c]));
        }
  }
  const double power_error = std::sqrt(err / ref);
  EXPECT_LT(power_error, 0.10);
  EXPECT_GT(peak, 0.8 * peak_truth);
  EXPECT_GT(peak_truth, 20);
  // The same model in log codes: a curve that spends its codes on the shadows leaves the
  // highlight, which dominates linear error, coarse — the reason the session default is not log.
  co.curve = HdrCurve::kLog;
  const HdrCodeCurve log_curve = FitHdrCurve(ReflectanceOf(maps, lamp), co);
  auto lm = FitPca(SamplesFromMaps(maps, scene.lights, lamp, log_curve), o);
  ASSERT_TRUE(lm.ok());
  lm->set_hdr({log_curve, lamp, frame});
  const auto wrapped = WrapPca(std::move(*lm));
  double lerr = 0;
  for (int l : {3, 14, 25, 36}) {
    const cv::Mat rho = wrapped->EvaluateRho(scene.lights[l]);
    for (int y = 0; y < scene.height; ++y)
      for (int x = 0; x < scene.width; ++x)
        for (int c = 0; c < 3; ++c) {
          const double d = rho.at<cv::Vec3f>(y, x)[2 - c] - scene.Rho(x, y, scene.lights[l], c);
          lerr += d * d;
        }
  }
  EXPECT_GT(std::sqrt(lerr / ref), 1.5 * power_error);
  fs::remove_all(fs::path(dir).parent_path());
}

// What the per-byte choice scores (the model as its files would hold it, made in memory) is
// what Save writes and Load reads back: the same bytes in all, the same planes, ranges and
// basis, at two qualities; and the lossy planes do differ from the fitted ones.
TEST(HdrPca, TheModelAsStoredInMemoryIsTheModelSavedAndLoadedBack) {
  const HdrScene scene;
  const auto maps = scene.Radiance({1, 1, 1});
  const HdrCodeCurve curve{HdrCurve::kPower, 3, 0.01, 1.25};
  PcaOptions o;
  o.components = 7;
  o.grid_resolution = 8;
  auto m = FitPca(SamplesFromMaps(maps, scene.lights, {1, 1, 1}, curve), o);
  ASSERT_TRUE(m.ok());
  m->set_hdr({curve, {1, 1, 1}, {}});
  const std::string dir = testing::FreshTempDir("hdr_pca_stored") + "/model";
  for (int q : {80, 100}) {
    m->set_jpeg_quality(q);
    uint64_t bytes = 0;
    auto mem = m->AsStored(&bytes);
    ASSERT_TRUE(mem.ok()) << mem.error().ToString();
    ASSERT_TRUE(m->Save(dir).ok());
    auto back = PcaModel::Load(dir);
    ASSERT_TRUE(back.ok()) << back.error().ToString();
    EXPECT_EQ(bytes, FolderBytes(dir)) << q;
    ASSERT_EQ(mem->planes().size(), back->planes().size());
    int lossy = 0;
    for (size_t p = 0; p < back->planes().size(); ++p) {
      EXPECT_EQ(cv::norm(mem->planes()[p], back->planes()[p], cv::NORM_INF), 0) << q << " plane " << p;
      lossy += cv::norm(m->planes()[p], back->planes()[p], cv::NORM_INF) > 0;
    }
    EXPECT_GT(lossy, 0) << q;
    EXPECT_EQ(mem->basis().values, back->basis().values);
    ASSERT_EQ(mem->quantisation().size(), back->quantisation().size());
    for (size_t p = 0; p < back->quantisation().size(); ++p) {
      EXPECT_EQ(mem->quantisation()[p].min, back->quantisation()[p].min);
      EXPECT_EQ(mem->quantisation()[p].max, back->quantisation()[p].max);
    }
    EXPECT_EQ(mem->jpeg_quality(), q);
    ASSERT_TRUE(mem->hdr().has_value());
    EXPECT_EQ(mem->hdr()->curve.max, back->hdr()->curve.max);
  }
  fs::remove_all(fs::path(dir).parent_path());
}

TEST(HdrPca, BadValuesBlockIsRefusedNamingTheFile) {
  const HdrScene scene;
  const auto maps = scene.Radiance({1, 1, 1});
  const HdrCodeCurve curve{HdrCurve::kLog, 100, 0.01};
  PcaOptions o;
  o.components = 3;
  o.grid_resolution = 8;
  auto m = FitPca(SamplesFromMaps(maps, scene.lights, {1, 1, 1}, curve), o);
  ASSERT_TRUE(m.ok());
  m->set_hdr({curve, {1, 1, 1}, {}});
  const std::string dir = testing::FreshTempDir("hdr_pca_bad") + "/model";
  ASSERT_TRUE(m->Save(dir).ok());
  nlohmann::json info;
  {
    std::ifstream f(dir + "/info.json");
    info = nlohmann::json::parse(f);
  }
  info["rig"]["values"]["floor"] = 1000.0;  // above max
  {
    std::ofstream f(dir + "/info.json");
    f << info.dump();
  }
  auto loaded = LoadReflectanceModel(dir);
  ASSERT_FALSE(loaded.ok());
  EXPECT_NE(loaded.error().ToString().find("info.json"), std::string::npos) << loaded.error().ToString();
  // A sign that is a float past int's range is refused by name, not converted (undefined
  // behaviour under UBSan before the integer check).
  info["rig"]["values"]["floor"] = 0.01;
  info["rig"]["values"]["light_frame"]["h_sign"] = 1.6e70;
  {
    std::ofstream f(dir + "/info.json");
    f << info.dump();
  }
  auto bad_sign = LoadReflectanceModel(dir);
  ASSERT_FALSE(bad_sign.ok());
  EXPECT_NE(bad_sign.error().ToString().find("h_sign"), std::string::npos) << bad_sign.error().ToString();
  info["rig"]["values"]["light_frame"]["h_sign"] = 1;
  // Without the block the model is a photographs' one: sRGB codes.
  info["rig"].erase("values");
  {
    std::ofstream f(dir + "/info.json");
    f << info.dump();
  }
  auto plain = LoadReflectanceModel(dir);
  ASSERT_TRUE(plain.ok()) << plain.error().ToString();
  EXPECT_EQ((*plain)->encoding(), ValueEncoding::kSrgb);
  fs::remove_all(fs::path(dir).parent_path());
}

}  // namespace
}  // namespace rig

namespace rig {
namespace {

// The table's code is HdrCode's for every float tried: each curve, random bit patterns (any
// sign, size, NaN, infinity), and the floats either side of every code's first radiance.
TEST(HdrCodes, TheCodeTableGivesHdrCodesOwnCodeForEveryFloat) {
  std::mt19937 rng(7);
  for (HdrCurve kind : {HdrCurve::kPower, HdrCurve::kLog, HdrCurve::kSrgb}) {
    HdrCodeCurve c;
    c.curve = kind;
    c.gamma = 1.25;
    c.max = 3.7;
    c.floor = 0.002;
    const double lamp = 1.7;
    const HdrCodeTable table(c, lamp);
    int mismatches = 0, distinct = 0;
    uint8_t last = 0;
    for (int i = 0; i < 2000000; ++i) {
      const uint32_t bits = rng();
      float f;
      std::memcpy(&f, &bits, sizeof f);
      if (table(f) != HdrCode(f, lamp, c)) ++mismatches;
    }
    for (float f = 1e-6f; f < 20.f; f = std::nextafter(f * 1.0001f, 1e30f)) {
      for (float g : {std::nextafter(f, 0.f), f, std::nextafter(f, 1e30f)})
        if (table(g) != HdrCode(g, lamp, c)) ++mismatches;
      const uint8_t code = table(f);
      if (code != last) ++distinct;
      last = code;
    }
    // Every half (what a session's maps hold): the buckets' codes and the searched ones.
    for (uint32_t h = 0; h < 65536; ++h) {
      const float f = static_cast<float>(cv::float16_t::fromBits(static_cast<uint16_t>(h)));
      if (table(f) != HdrCode(f, lamp, c)) ++mismatches;
    }
    EXPECT_EQ(mismatches, 0) << HdrCurveName(kind);
    EXPECT_GT(distinct, 200) << HdrCurveName(kind);  // the sweep crosses the codes
  }
}

}  // namespace
}  // namespace rig
