// The streamed PCA fit against the in-memory one on a synthetic capture written as JPEGs (a
// textured Lambertian + Phong scene with a cast shadow and clipped highlights): the same
// choice, the same info.json and the same plane files, byte for byte, with bands far smaller
// than the solver's blocks; and what it refuses.
#include "process/model/pca/pca_stream.h"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>

#include "process/io/jpeg_io.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/any/rti_fit.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 96, kHeight = 80, kLights = 24;

std::vector<Vec3> Lights() {
  std::vector<Vec3> d;
  for (int i = 0; i < kLights; ++i) {
    const double el = (18.0 + 60.0 * i / (kLights - 1)) * M_PI / 180.0;
    const double az = i * 2.39996322972865332;
    d.push_back({std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)});
  }
  return d;
}

// The 8-bit code of pixel (x, y) under light l: bumpy normals, a checker and stripe albedo, a
// Phong lobe bright enough to clip, and a wall at x = 30 casting a shadow towards +x.
uint8_t Code(int x, int y, const Vec3& l, int c) {
  const double u = (x + 0.5) / kWidth - 0.5, v = (y + 0.5) / kHeight - 0.5;
  Vec3 n = {0.45 * std::sin(11 * u) * std::cos(7 * v), 0.35 * std::cos(9 * v + 2 * u), 1};
  const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (auto& q : n) q /= nn;
  const double tint[3] = {1.0, 0.8, 0.55};
  const double albedo = (0.3 + 0.3 * ((x / 8 + y / 8) % 2) + 0.1 * ((x % 5) == 0)) * tint[c];
  const double ndl = std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
  const double rz = 2 * ndl * n[2] - l[2];
  const double spec = 1.6 * std::pow(std::max(0.0, rz), 24);
  // The wall (height 6 pixels) shadows x in (30, 30 + 6·lx/lz) when the lamp is at -x.
  const bool shadow = l[0] < 0 && x > 30 && x < 30 + 6 * (-l[0]) / l[2];
  const double radiance = shadow ? 0.01 : 1.15 * (albedo * ndl + spec) + 0.004;
  const double srgb = radiance <= 0.0031308 ? 12.92 * radiance
                                            : 1.055 * std::pow(radiance, 1 / 2.4) - 0.055;
  return static_cast<uint8_t>(std::clamp(std::lround(255 * srgb), 0L, 255L));
}

class PcaStreamTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("rig_pca_stream_{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "images");
    const auto lights = Lights();
    std::ofstream lp(dir_ / "capture.lp");
    lp << kLights << "\n";
    for (int l = 0; l < kLights; ++l) {
      cv::Mat rgb(kHeight, kWidth, CV_8UC3);
      for (int y = 0; y < kHeight; ++y)
        for (int x = 0; x < kWidth; ++x)
          for (int c = 0; c < 3; ++c) rgb.ptr<uint8_t>(y)[x * 3 + c] = Code(x, y, lights[l], c);
      const std::string name = fmt::format("images/light_{:02d}.jpg", l);
      ASSERT_TRUE(WriteJpeg((dir_ / name).string(), rgb, JpegColor::kYcbcr, 95).ok());
      lp << fmt::format("{} {:.6f} {:.6f} {:.6f}\n", name, lights[l][0], lights[l][1],
                        lights[l][2]);
    }
    lp.close();
    lp_ = (dir_ / "capture.lp").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  static std::string Bytes(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
  }

  // The in-memory fit and the streamed one into two folders; the same files, byte for byte.
  void ExpectSameModel(const PcaChoiceOptions& co, int band_rows, int threads) {
    auto cap = LoadRtiCapture(lp_);
    ASSERT_TRUE(cap.ok()) << cap.error().ToString();
    ASSERT_GT(cap->masked_samples, 0u) << "the scene is meant to clip and go black somewhere";
    auto fit = FitPcaAuto(cap->samples, nullptr, co);
    ASSERT_TRUE(fit.ok()) << fit.error().ToString();
    const fs::path mem = dir_ / "memory", str = dir_ / "stream";
    ASSERT_TRUE(fit->model.Save(mem.string()).ok());

    PcaStreamOptions so;
    so.band_rows = band_rows;
    so.threads = threads;
    so.lp = lp_;
    auto streamed = FitPcaStreaming(cap->entries, co, str.string(), so);
    ASSERT_TRUE(streamed.ok()) << streamed.error().ToString();
    EXPECT_EQ(streamed->bands, (kHeight + band_rows - 1) / band_rows);
    EXPECT_EQ(streamed->width, kWidth);
    EXPECT_EQ(streamed->height, kHeight);

    // The same choice: every candidate's numbers, the chosen one, the reason.
    const PcaChoice& a = fit->choice;
    const PcaChoice& b = streamed->choice;
    EXPECT_EQ(a.chosen, b.chosen);
    EXPECT_EQ(a.best, b.best);
    EXPECT_EQ(a.reason, b.reason);
    ASSERT_EQ(a.candidates.size(), b.candidates.size());
    for (size_t i = 0; i < a.candidates.size(); ++i) {
      EXPECT_EQ(a.candidates[i].validation_mse, b.candidates[i].validation_mse) << i;
      EXPECT_EQ(a.candidates[i].jpeg_mse, b.candidates[i].jpeg_mse) << i;
      EXPECT_EQ(a.candidates[i].bytes_per_pixel, b.candidates[i].bytes_per_pixel) << i;
    }
    // The same masks and refits.
    EXPECT_EQ(streamed->masked_samples, cap->masked_samples);
    EXPECT_DOUBLE_EQ(streamed->pixels_with_masked, cap->pixels_with_masked);
    EXPECT_EQ(streamed->stats.masked_samples, fit->stats.masked_samples);
    EXPECT_EQ(streamed->stats.refitted_pixels, fit->stats.refitted_pixels);
    EXPECT_GT(streamed->stats.refitted_pixels, 0u);

    // The same files.
    const int files = (fit->model.components() + 2) / 3;
    std::vector<std::string> names = {"info.json"};
    for (int j = 0; j < files; ++j) names.push_back(fmt::format("plane_{}.jpg", j));
    size_t count = 0;
    for (const auto& e : fs::directory_iterator(str)) {
      (void)e;
      ++count;
    }
    EXPECT_EQ(count, names.size());
    for (const auto& name : names) {
      ASSERT_TRUE(fs::exists(str / name)) << name;
      EXPECT_TRUE(Bytes(mem / name) == Bytes(str / name)) << name << " differs";
    }
    // And it reads back as the model it is.
    auto back = PcaModel::Load(str.string());
    ASSERT_TRUE(back.ok()) << back.error().ToString();
    EXPECT_EQ(back->components(), fit->model.components());
  }

  fs::path dir_;
  std::string lp_;
};

TEST_F(PcaStreamTest, SameModelAsInMemoryWithEveryPixelSampled) {
  // 7680 pixels < basis_pixels: every pixel is in the sample; bands of 3 rows (288 pixels)
  // against the solver's blocks of 2048.
  ExpectSameModel(PcaChoiceOptions{}, 3, 2);
}

TEST_F(PcaStreamTest, SameModelAsInMemoryWithASeededSampleAndOneThread) {
  PcaChoiceOptions co;
  co.base.basis_pixels = 1500;  // a seeded sample: the ranges come from blocks of sampled pixels
  co.base.seed = 7;
  co.validation_pixels = 500;
  co.components = {3, 6, 9};
  co.resolutions = {8, 12};
  co.qualities = {80, 95};
  ExpectSameModel(co, 1, 1);
}

TEST_F(PcaStreamTest, SameModelAsInMemoryWithDroppedSamplesAndOddBands) {
  PcaChoiceOptions co;
  co.base.mask = PcaMaskMode::kDrop;
  co.base.basis_pixels = 4000;
  co.base.threads = 3;  // the in-memory path's blocks follow its threads; the stream's follow it
  co.components = {4, 7};
  co.resolutions = {10};
  co.qualities = {90};
  ExpectSameModel(co, 7, 3);
}

TEST_F(PcaStreamTest, SampleBytesFromTheFirstHeader) {
  auto entries = ReadLp(lp_);
  ASSERT_TRUE(entries.ok());
  auto bytes = RtiSampleBytes(*entries);
  ASSERT_TRUE(bytes.ok()) << bytes.error().ToString();
  EXPECT_EQ(*bytes, uint64_t{kWidth} * kHeight * kLights * 3);
  auto halved = RtiSampleBytes(*entries, 2);
  ASSERT_TRUE(halved.ok());
  EXPECT_EQ(*halved, uint64_t{kWidth / 2} * (kHeight / 2) * kLights * 3);
}

TEST_F(PcaStreamTest, RefusesLightsBelowTheHorizonAndImagesOfAnotherSize) {
  auto entries = ReadLp(lp_);
  ASSERT_TRUE(entries.ok());
  PcaStreamOptions so;
  so.lp = lp_;
  {
    auto below = *entries;
    below[5].direction = {0.6, 0.8, 0.0};
    auto r = FitPcaStreaming(below, PcaChoiceOptions{}, (dir_ / "x").string(), so);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().ToString().find("horizon"), std::string::npos) << r.error().ToString();
  }
  {
    cv::Mat small(10, 10, CV_8UC3, cv::Scalar(100, 100, 100));
    ASSERT_TRUE(WriteJpeg((dir_ / "small.jpg").string(), small, JpegColor::kYcbcr, 90).ok());
    auto odd = *entries;
    odd[3].image = (dir_ / "small.jpg").string();
    auto r = FitPcaStreaming(odd, PcaChoiceOptions{}, (dir_ / "x").string(), so);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.error().ToString().find("10x10"), std::string::npos) << r.error().ToString();
  }
}

// rig fit --lp above --stream-above-mb (0 here) writes the in-memory path's model.
TEST_F(PcaStreamTest, RigFitStreamsAboveTheBoundAndRefusesLooReport) {
  const char* rig = std::getenv("RIG_BINARY");
  if (!rig || !fs::exists(rig)) GTEST_SKIP() << "no rig binary";
  const std::string mem = (dir_ / "cli_memory").string(), str = (dir_ / "cli_stream").string();
  const std::string base = fmt::format("{} fit --lp {} --components 6 --grid 12 --jpeg-quality 90",
                                       rig, lp_);
  ASSERT_EQ(std::system((base + " --out " + mem + " > /dev/null").c_str()), 0);
  ASSERT_EQ(std::system((base + " --out " + str + " --stream-above-mb 0 > " +
                         (dir_ / "stream.txt").string()).c_str()), 0);
  EXPECT_NE(Bytes(dir_ / "stream.txt").find("streaming"), std::string::npos);
  for (const char* name : {"info.json", "plane_0.jpg", "plane_1.jpg"})
    EXPECT_TRUE(Bytes(fs::path(mem) / name) == Bytes(fs::path(str) / name)) << name;
  const int rc = std::system((base + " --loo-report " + (dir_ / "loo.md").string() +
                              " --stream-above-mb 0 2> " + (dir_ / "err.txt").string()).c_str());
  EXPECT_EQ(WEXITSTATUS(rc), 2);
  EXPECT_NE(Bytes(dir_ / "err.txt").find("--loo-report"), std::string::npos);
}

}  // namespace
}  // namespace rig
