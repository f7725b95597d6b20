// The PCA family against known truth: a synthetic multi-light capture whose radiance is a
// Lambertian scene (rank 3 in the light direction, plus texture) with a specular lobe; the
// relight web format read back with relight's published reconstruction, independently of
// our renderer; masks, the size choice and the leave-one-out harness.
#include <cmath>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "process/io/jpeg_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/holdout.h"
#include "process/model/pca/pca.h"
#include "process/model/pca/pca_choice.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

struct Scene {
  int width = 64, height = 48;
  double specular = 0;  // strength of a Phong lobe (exponent 20)
  double gain = 1;      // > 1 clips the brightest samples at 255
  bool srgb = true;     // false: codes linear in radiance (a Lambertian scene is then rank 3)
};

std::vector<Vec3> HemisphereLights() {
  std::vector<Vec3> out;
  for (double elev : {15.0, 30.0, 45.0, 60.0, 75.0}) {
    const int n = elev < 70 ? 10 : 5;
    for (int i = 0; i < n; ++i) {
      const double az = (i + 0.5 * (elev > 40)) * 2 * M_PI / n, e = elev * M_PI / 180;
      out.push_back({std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e)});
    }
  }
  return out;
}

// The encoded value (0..255, unclipped) of pixel (x, y) under light l.
double Truth(const Scene& s, int x, int y, const Vec3& l, int c) {
  const double u = (x + 0.5) / s.width - 0.5, v = (y + 0.5) / s.height - 0.5;
  Vec3 n = {0.5 * std::sin(7 * u), 0.4 * std::cos(5 * v), 1};
  const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (auto& q : n) q /= nn;
  const double albedo = (0.35 + 0.25 * ((x / 8 + y / 8) % 2)) * (c == 0 ? 1.0 : c == 1 ? 0.8 : 0.6);
  const double ndl = std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
  // Phong about the view direction (0, 0, 1).
  const double rz = 2 * ndl * n[2] - l[2];
  const double spec = s.specular * std::pow(std::max(0.0, rz), 20);
  const double radiance = s.gain * (albedo * ndl + spec);
  return 255.0 * (s.srgb ? SrgbEncode(static_cast<float>(radiance)) : radiance);
}

LightSamples MakeSamples(const Scene& s, const std::vector<Vec3>& lights) {
  LightSamples out;
  out.width = s.width;
  out.height = s.height;
  out.directions = lights;
  out.values.resize(out.pixels() * lights.size() * 3);
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x)
      for (size_t l = 0; l < lights.size(); ++l)
        for (int c = 0; c < 3; ++c) {
          const size_t p = static_cast<size_t>(y) * s.width + x;
          out.values[(p * lights.size() + l) * 3 + c] = static_cast<uint8_t>(
              std::clamp(std::lround(Truth(s, x, y, lights[l], c)), 0L, 255L));
        }
  MaskLdrSamples(&out);
  return out;
}

// Error of a render (B, G, R, code/255) against the unclipped truth, in codes.
double RmsAgainstTruth(const Scene& s, const cv::Mat& pred, const Vec3& l) {
  double sum = 0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double d = pred.at<cv::Vec3f>(y, x)[2 - c] * 255.0 -
                         std::min(255.0, Truth(s, x, y, l, c));
        sum += d * d;
      }
  return std::sqrt(sum / (s.width * s.height * 3.0));
}

std::string TempDir(const std::string& name) {
  const fs::path p = fs::temp_directory_path() /
                     ("rig-pca-test-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p.string();
}

// A matte scene with codes linear in radiance (rank 3 in the light direction) at a gain,
// under the lights above 15° (no facet in attached shadow).
Scene MatteLinearScene(double gain) {
  Scene s{48, 40, 0.0, gain};
  s.srgb = false;
  return s;
}
std::vector<Vec3> HighLights() {
  auto lights = HemisphereLights();
  lights.erase(lights.begin(), lights.begin() + 10);
  return lights;
}

// RMS against the unclipped truth over every pixel and light, counting only truths below
// `below` (codes).
double RmsOverLights(const Scene& scene, const PcaModel& m, const std::vector<Vec3>& lights,
                     double below) {
  double sum = 0;
  size_t n = 0;
  for (const auto& l : lights) {
    const cv::Mat pred = m.Render(l);
    for (int y = 0; y < scene.height; ++y)
      for (int x = 0; x < scene.width; ++x)
        for (int c = 0; c < 3; ++c) {
          const double t = Truth(scene, x, y, l, c);
          if (t >= below) continue;
          const double d = pred.at<cv::Vec3f>(y, x)[2 - c] * 255.0 - t;
          sum += d * d;
          ++n;
        }
  }
  return std::sqrt(sum / static_cast<double>(n));
}

TEST(PcaModel, LambertianSceneIsRankThreeAndHeldOutLightsAreReproduced) {
  // Codes linear in radiance, every light above every facet's horizon: ρ·(n·l) is exactly a
  // mean plus three components in the light direction.
  Scene scene;
  scene.srgb = false;
  auto lights = HemisphereLights();
  lights.erase(lights.begin(), lights.begin() + 10);  // the 15° ring would shadow some facets
  const Vec3 held = lights[12];
  lights.erase(lights.begin() + 12);
  const LightSamples s = MakeSamples(scene, lights);
  PcaOptions o;
  o.components = 3;
  o.grid_resolution = 16;
  auto m = FitPca(s, o);
  ASSERT_TRUE(m.ok()) << m.error().ToString();
  // At the sampled lights only 8-bit rounding and quantisation remain; at a held-out light
  // the grid's bilinear reading of a function linear in l adds a little.
  EXPECT_LT(RmsAgainstTruth(scene, m->Render(lights[3]), lights[3]), 1.0);
  EXPECT_LT(RmsAgainstTruth(scene, m->Render(held), held), 2.0);
  o.components = 1;
  auto one = FitPca(s, o);
  ASSERT_TRUE(one.ok());
  EXPECT_GT(RmsAgainstTruth(scene, one->Render(held), held),
            2 * RmsAgainstTruth(scene, m->Render(held), held));
}

TEST(PcaModel, SavedFolderRendersIdenticallyAndHasRelightsFields) {
  const Scene scene{64, 48, 0.6, 1.0};
  const LightSamples s = MakeSamples(scene, HemisphereLights());
  PcaOptions o;
  o.components = 5;
  o.grid_resolution = 12;
  o.jpeg_quality = 90;
  auto m = FitPca(s, o);
  ASSERT_TRUE(m.ok());
  const std::string dir = TempDir("format");
  ASSERT_TRUE(m->Save(dir).ok());
  auto back = PcaModel::Load(dir);
  ASSERT_TRUE(back.ok()) << back.error().ToString();

  std::ifstream f(fs::path(dir) / "info.json");
  const auto info = nlohmann::json::parse(f);
  EXPECT_EQ(info["type"], "bilinear");
  EXPECT_EQ(info["colorspace"], "mrgb");
  EXPECT_EQ(info["format"], "jpg");
  EXPECT_EQ(info["width"], 64);
  EXPECT_EQ(info["height"], 48);
  EXPECT_EQ(info["nplanes"], 5);
  EXPECT_EQ(info["resolution"], 12);
  EXPECT_EQ(info["basis"].size(), static_cast<size_t>((5 + 1) * 12 * 12 * 3));
  EXPECT_EQ(info["materials"].size(), 1u);
  EXPECT_EQ(info["materials"][0]["scale"].size(), 5u);
  EXPECT_EQ(info["materials"][0]["bias"].size(), 5u);
  EXPECT_EQ(info["materials"][0]["range"].size(), 5u);
  EXPECT_EQ(info["lights"].size(), HemisphereLights().size() * 3);
  EXPECT_TRUE(fs::exists(fs::path(dir) / "plane_0.jpg"));
  EXPECT_TRUE(fs::exists(fs::path(dir) / "plane_1.jpg"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "plane_2.jpg"));
  // The planes are YCbCr JPEGs without chroma subsampling (JFIF, no Adobe RGB marker), as
  // relight writes and every relight reader decodes them.
  std::ifstream jf(fs::path(dir) / "plane_0.jpg", std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(jf)), {});
  EXPECT_NE(bytes.find("JFIF"), std::string::npos);
  EXPECT_EQ(bytes.find("Adobe"), std::string::npos);
  {
    const auto sof = bytes.find("\xFF\xC0", 0) != std::string::npos ? bytes.find("\xFF\xC0")
                                                                   : bytes.find("\xFF\xC2");
    ASSERT_NE(sof, std::string::npos);
    // SOF: length(2) precision(1) height(2) width(2) components(1), then per component
    // id(1) sampling(1) table(1): every sampling factor 1x1 (0x11).
    ASSERT_EQ(static_cast<uint8_t>(bytes[sof + 9]), 3);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(static_cast<uint8_t>(bytes[sof + 11 + 3 * c]), 0x11);
  }

  // Relight's published reconstruction (rti-formats.md, "bilinear, mrgb"), written here
  // from the files alone, against our renderer of the loaded model.
  auto planes0 = ReadJpeg((fs::path(dir) / "plane_0.jpg").string());
  auto planes1 = ReadJpeg((fs::path(dir) / "plane_1.jpg").string());
  ASSERT_TRUE(planes0.ok() && planes1.ok());
  const int res = 12, k = 5, ndim = res * res;
  const auto basis = info["basis"].get<std::vector<int>>();
  const auto scale = info["materials"][0]["scale"].get<std::vector<double>>();
  const auto bias = info["materials"][0]["bias"].get<std::vector<double>>();
  const auto range = info["materials"][0]["range"].get<std::vector<double>>();
  for (const Vec3& l : {Vec3{0.3, -0.2, 0.93}, Vec3{-0.6, 0.5, 0.62}, Vec3{0.05, 0.9, 0.43}}) {
    const double sum = std::abs(l[0]) + std::abs(l[1]) + std::abs(l[2]);
    const double X = (l[0] + l[1]) / sum, Y = (l[1] - l[0]) / sum;
    const double u = (X + 1) / 2 * (res - 1), v = (Y + 1) / 2 * (res - 1);
    const int sx = std::clamp(static_cast<int>(std::floor(u)), 0, res - 2);
    const int sy = std::clamp(static_cast<int>(std::floor(v)), 0, res - 2);
    const double dx = u - sx, dy = v - sy;
    double b[6][3];
    for (int p = 0; p <= k; ++p)
      for (int c = 0; c < 3; ++c) {
        auto at = [&](int x, int y) {
          const int raw = basis[((p * ndim) + x + y * res) * 3 + c];
          return p == 0 ? static_cast<double>(raw) : (raw - 127) / range[p - 1];
        };
        b[p][c] = at(sx, sy) * (1 - dx) * (1 - dy) + at(sx + 1, sy) * dx * (1 - dy) +
                  at(sx, sy + 1) * (1 - dx) * dy + at(sx + 1, sy + 1) * dx * dy;
      }
    const cv::Mat ours = back->Render(l);
    double worst = 0;
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x)
        for (int c = 0; c < 3; ++c) {
          double out = b[0][c];
          for (int p = 0; p < k; ++p) {
            const cv::Mat& img = p < 3 ? *planes0 : *planes1;
            const double byte = img.at<cv::Vec3b>(y, x)[p % 3];
            out += 255.0 * (byte / 255.0 - bias[p]) * scale[p] * b[p + 1][c];
          }
          worst = std::max(worst, std::abs(out - ours.at<cv::Vec3f>(y, x)[2 - c] * 255.0));
        }
    EXPECT_LT(worst, 1e-2) << "light " << l[0] << "," << l[1];
  }
  // Render of the fitted model equals the render of the one read back, except for what JPEG
  // changed in the planes (a few codes).
  const Vec3 l{0.2, 0.1, 0.97};
  EXPECT_LT(cv::norm(m->Render(l), back->Render(l), cv::NORM_INF) * 255, 12.0);
  // A smaller model saved into the same folder leaves none of the larger one's planes.
  o.components = 2;
  auto small = FitPca(s, o);
  ASSERT_TRUE(small.ok());
  ASSERT_TRUE(small->Save(dir).ok());
  EXPECT_TRUE(fs::exists(fs::path(dir) / "plane_0.jpg"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "plane_1.jpg"));
  auto small_back = PcaModel::Load(dir);
  ASSERT_TRUE(small_back.ok());
  EXPECT_EQ(small_back->components(), 2);
  fs::remove_all(dir);
}

TEST(PcaModel, ClippedSamplesAreFittedAroundNotPulledDown) {
  // A matte scene with codes linear in radiance is exactly rank 3. Its components are taken
  // from the unclipped capture (gain 1); the coefficients are then fitted to the same scene
  // at gain 2.5, whose bright samples clip at 255 (the truth there is above 255): a plain
  // fit is pulled down by them, the hinge fits around them.
  Scene scene = MatteLinearScene(1.0);
  const auto lights = HighLights();
  const LightSamples plain = MakeSamples(scene, lights);
  PcaOptions o;
  o.components = 3;
  o.grid_resolution = 16;
  o.mask = PcaMaskMode::kNone;
  auto comps = ComputePcaComponents(plain, o, 3);
  ASSERT_TRUE(comps.ok());
  // The gain-2.5 scene's components are those of gain 1 scaled: the mean scales, the
  // directions do not.
  comps->mean *= 2.5;
  scene.gain = 2.5;
  const LightSamples s = MakeSamples(scene, lights);
  size_t clipped = 0;
  for (size_t i = 0; i < s.values.size(); ++i) clipped += s.values[i] >= 250;
  ASSERT_GT(clipped, s.values.size() / 20) << "the scene must clip";
  double err[2];
  int i = 0;
  for (PcaMaskMode mode : {PcaMaskMode::kNone, PcaMaskMode::kHinge}) {
    o.mask = mode;
    PcaFitStats stats;
    auto m = FitPcaWith(s, *comps, o, &stats);
    ASSERT_TRUE(m.ok());
    if (mode == PcaMaskMode::kHinge) {
      EXPECT_GT(stats.refitted_pixels, 0u);
    }
    // Error against the truth where it is below clipping, at every sampled light.
    err[i++] = RmsOverLights(scene, *m, lights, 250);
  }
  EXPECT_LT(err[1], 0.5 * err[0]) << "none " << err[0] << " hinge " << err[1];
  // What is left is the model's own floor at this gain (8-bit planes over a 2.5x range,
  // the grid's reading of the components): measured 3.5 codes.
  EXPECT_LT(err[1], 4.0);
}

TEST(PcaModel, ImputedCensoredSamplesRecoverWhatLiesBeyondClipping) {
  // The rank-3 matte scene at gain 2.5 clips; its components computed from the clipped
  // values bend; imputing the censored samples from the components and computing them again
  // brings the model closer to the unclipped truth everywhere, beyond 255 too.
  const Scene scene = MatteLinearScene(2.5);
  const auto lights = HighLights();
  const LightSamples s = MakeSamples(scene, lights);
  PcaOptions o;
  o.components = 3;
  o.grid_resolution = 16;
  double err[2];
  for (int it : {0, 3}) {
    o.impute_iterations = it;
    auto m = FitPca(s, o);
    ASSERT_TRUE(m.ok());
    err[it ? 1 : 0] = RmsOverLights(scene, *m, lights, 1e9);
  }
  // Measured: 21.6 -> 15.9 codes RMS (what is left is mostly the 8-bit planes over the wider range).
  EXPECT_LT(err[1], 0.8 * err[0]) << "without " << err[0] << " with " << err[1];
}

TEST(PcaChoice, PicksTheSmallestModelWithinToleranceAndSaysWhenNothingFits) {
  const Scene scene{64, 48, 0.0, 1.0};  // matte: three components carry it
  const LightSamples s = MakeSamples(scene, HemisphereLights());
  PcaChoiceOptions co;
  co.components = {3, 6, 9};
  co.resolutions = {12};
  co.qualities = {95};
  co.max_bytes_per_pixel = 100;
  co.tolerance_db = 0.5;
  auto fit = FitPcaAuto(s, nullptr, co);
  ASSERT_TRUE(fit.ok()) << fit.error().ToString();
  const auto& chosen = fit->choice.candidates[fit->choice.chosen];
  EXPECT_EQ(chosen.components, 3) << PcaChoiceMarkdown(fit->choice);
  EXPECT_EQ(fit->model.components(), 3);
  EXPECT_NE(fit->choice.reason.find("3 components"), std::string::npos);

  // A glossy scene needs more than three.
  const LightSamples glossy = MakeSamples(Scene{64, 48, 0.8, 1.0}, HemisphereLights());
  co.tolerance_db = 0.05;
  auto g = FitPcaAuto(glossy, nullptr, co);
  ASSERT_TRUE(g.ok());
  EXPECT_GT(g->choice.candidates[g->choice.chosen].components, 3) << PcaChoiceMarkdown(g->choice);

  co.max_bytes_per_pixel = 0.01;
  auto tiny = FitPcaAuto(s, nullptr, co);
  ASSERT_TRUE(tiny.ok());
  EXPECT_NE(tiny->choice.reason.find("no candidate fits"), std::string::npos);
}

TEST(PcaChoice, RepeatedSplitsHoldEveryLightOutOnce) {
  PcaChoiceOptions o;
  o.validation_every = 6;
  o.validation_splits = 6;
  std::vector<int> times(45, 0);
  for (int r = 0; r < PcaChoiceSplits(o); ++r)
    for (int l : PcaChoiceHeldOutLights(45, o, r)) ++times[l];
  for (int l = 0; l < 45; ++l) EXPECT_EQ(times[l], 1) << "light " << l;
  EXPECT_NE(PcaChoiceSplitWords(o).find("once, in 6 splits"), std::string::npos);
  o.validation_splits = 3;  // offsets 0, 2, 4: half the lights, each once
  std::fill(times.begin(), times.end(), 0);
  for (int r = 0; r < PcaChoiceSplits(o); ++r)
    for (int l : PcaChoiceHeldOutLights(45, o, r)) ++times[l];
  for (int l = 0; l < 45; ++l) EXPECT_EQ(times[l], l % 2 == 0 ? 1 : 0) << "light " << l;
  o.validation_splits = 40;  // no more splits than lights in a period
  EXPECT_EQ(PcaChoiceSplits(o), 6);
  o.validation_splits = 1;
  EXPECT_EQ(PcaChoiceHeldOutLights(45, o), (std::vector<int>{0, 6, 12, 18, 24, 30, 36, 42}));
}

TEST(LeaveOneOut, EveryFoldLacksItsHeldOutImageAndIsScoredInEightBits) {
  const Scene scene;
  const LightSamples s = MakeSamples(scene, HemisphereLights());
  int calls = 0;
  auto score = LeaveOneOut(s, {0, 7, 20}, [&](const LightSamples& fold, int held, const Vec3& light)
                                              -> Result<FoldPrediction> {
    ++calls;
    EXPECT_EQ(fold.lights(), s.lights() - 1);
    for (const auto& d : fold.directions) EXPECT_NE(d, s.directions[held]);
    EXPECT_EQ(light, s.directions[held]);
    // Predict the photograph itself, off by exactly 2 codes: MSE 4.
    cv::Mat pred(s.height, s.width, CV_32FC3);
    for (size_t p = 0; p < s.pixels(); ++p)
      for (int c = 0; c < 3; ++c)
        pred.ptr<float>()[p * 3 + (2 - c)] =
            static_cast<float>(std::min(253, static_cast<int>(s.value(p, held, c))) + 2) / 255.0f;
    return FoldPrediction{pred, 1000};
  });
  ASSERT_TRUE(score.ok());
  EXPECT_EQ(calls, 3);
  for (double mse : score->mse) EXPECT_NEAR(mse, 4.0, 1e-9);
  EXPECT_NEAR(score->psnr_mean_mse_db, 10 * std::log10(255.0 * 255.0 / 4.0), 1e-9);
  EXPECT_NEAR(score->bytes_per_pixel, 1000.0 / s.pixels(), 1e-12);
}

}  // namespace
}  // namespace rig
