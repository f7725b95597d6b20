// The session's PCA model fitted band by band (FitPcaHdrFromBands): from radiance maps held in
// memory as they arrived (MapStore) and from the same maps' EXR files the folders are equal
// byte for byte, and both equal FitPcaHdrAuto on the whole maps followed by PcaModel::Save;
// the curve's sample read in bands in any order is the whole maps' curve.
#include "process/model/session/pca_session.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "process/io/exr_io.h"
#include "process/model/light_direction.h"
#include "process/model/session/map_store.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 97, kHeight = 61;

// A glossy, textured scene with a cast shadow, lit from direction l (BGR radiance; a few
// samples negative or not finite, as merged maps can hold).
cv::Mat Render(const Vec3& l, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, 0.01f);
  cv::Mat m(kHeight, kWidth, CV_32FC3);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const double u = (x + 0.5) / kWidth - 0.5, v = (y + 0.5) / kHeight - 0.5;
      Vec3 n = {0.5 * std::sin(9 * u), 0.4 * std::cos(7 * v), 1};
      const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (auto& q : n) q /= nn;
      const double ndl = std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
      const double spec = std::pow(std::max(0.0, 2 * ndl * n[2] - l[2]), 30);
      const bool shadow = x > kWidth / 2 && x < kWidth / 2 + 40 * l[0] && y > kHeight / 3;
      auto* px = m.ptr<cv::Vec3f>(y) + x;
      for (int c = 0; c < 3; ++c) {
        const double albedo = (0.2 + 0.5 * ((x / 7 + y / 5) % 2)) * (1.0 - 0.2 * c);
        const double lit = (shadow ? 0.05 : 1.0) * (albedo * ndl + 4.0 * spec) + 0.01;
        (*px)[c] = static_cast<float>(30.0 * lit * (1 + noise(rng)));
      }
    }
  }
  m.at<cv::Vec3f>(3, 4)[1] = -0.5f;
  m.at<cv::Vec3f>(5, 6)[0] = std::numeric_limits<float>::quiet_NaN();
  return m;
}

std::string Bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

class PcaSessionFitTest : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("rig_pca_session_fit_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    for (int v = 0; v <= 30; v += 10)
      for (int h = 0; h <= 90; h += 15) {
        directions_.push_back(LightDirection(h, v));
        maps_.push_back(Render(directions_.back(), static_cast<unsigned>(maps_.size())));
        paths_.push_back((dir_ / ("m" + std::to_string(maps_.size()) + ".exr")).string());
        ASSERT_TRUE(WriteRgbExr(paths_.back(), maps_.back(), {}, ExrPixelType::kFloat).ok());
      }
    options_.components = {6, 9};
    options_.qualities = {90};
    options_.resolutions = {8};
    options_.max_bytes_per_pixel = 1e9;
  }
  void TearDown() override { fs::remove_all(dir_); }

  void ExpectSameFolder(const fs::path& a, const fs::path& b) {
    int files = 0;
    for (const auto& e : fs::directory_iterator(a)) {
      EXPECT_EQ(Bytes(e.path()), Bytes(b / e.path().filename())) << e.path() << " vs " << b;
      ++files;
    }
    int other = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(b)) ++other;
    EXPECT_EQ(files, other);
    EXPECT_GE(files, 3);  // info.json and the planes of 6 or 9 components
  }

  fs::path dir_;
  std::vector<Vec3> directions_;
  std::vector<cv::Mat> maps_;
  std::vector<std::string> paths_;
  PcaHdrChoiceOptions options_;
  const std::array<double, 3> lamp_ = {2.0, 1.5, 1.0};
};

TEST_F(PcaSessionFitTest, FromMemoryFromFilesAndWholeMapsTheSameBytes) {
  MapStore store(ExrPixelType::kFloat, paths_.size(), MapStore::DefaultMaxBytes());
  std::vector<std::string> keys;
  // The maps arrive out of order, as a resumed session's may.
  for (size_t i = paths_.size(); i-- > 0;) {
    keys.insert(keys.begin(), std::to_string(i));
    ASSERT_TRUE(store.Add(keys.front(), maps_[i], cv::Mat()).ok());
  }
  auto mem = store.Bands(keys);
  ASSERT_TRUE(mem.ok());
  auto from_memory = FitPcaHdrFromBands(**mem, directions_, lamp_, {}, options_,
                                        (dir_ / "memory").string(), 7);
  ASSERT_TRUE(from_memory.ok()) << from_memory.error().ToString();
  auto files = OpenMapFiles(paths_);
  ASSERT_TRUE(files.ok());
  auto from_files = FitPcaHdrFromBands(**files, directions_, lamp_, {}, options_,
                                       (dir_ / "files").string(), 32);
  ASSERT_TRUE(from_files.ok()) << from_files.error().ToString();
  ExpectSameFolder(dir_ / "memory", dir_ / "files");

  auto whole = FitPcaHdrAuto(maps_, directions_, lamp_, {}, options_);
  ASSERT_TRUE(whole.ok()) << whole.error().ToString();
  ASSERT_TRUE(whole->model.Save((dir_ / "whole").string()).ok());
  ExpectSameFolder(dir_ / "memory", dir_ / "whole");
  EXPECT_EQ(from_memory->choice_region, cv::Rect(0, 0, kWidth, kHeight));
  EXPECT_EQ(from_memory->choice.chosen, whole->chosen);
  EXPECT_EQ(from_memory->curve.max, whole->model.hdr()->curve.max);
}

TEST_F(PcaSessionFitTest, TheCurveSampledInBandsInAnyOrderIsTheWholeMapsCurve) {
  HdrCurveOptions o;
  o.curve = HdrCurve::kLog;
  const HdrCodeCurve whole = FitHdrCurveOfRadiance(maps_, lamp_, o);
  HdrCurveSampler sampler(maps_.size(), static_cast<size_t>(kWidth) * kHeight, lamp_);
  std::vector<int> starts;
  for (int y = 0; y < kHeight; y += 5) starts.push_back(y);
  std::reverse(starts.begin(), starts.end());
  for (int y0 : starts)
    for (size_t l = 0; l < maps_.size(); ++l)
      sampler.Add(l, static_cast<size_t>(y0) * kWidth,
                  maps_[l].rowRange(y0, std::min(kHeight, y0 + 5)));
  const HdrCodeCurve banded = sampler.Curve(o);
  EXPECT_EQ(banded.max, whole.max);
  EXPECT_EQ(banded.floor, whole.floor);
  // And it is the reflectance's curve (radiance ÷ lamp), as FitHdrCurve takes it.
  const HdrCodeCurve rho = FitHdrCurve(ReflectanceOf(maps_, lamp_), o);
  EXPECT_NEAR(banded.max, rho.max, 1e-6 * rho.max);
  EXPECT_GT(banded.max, 0);
}

// The per-byte choice's rule: the smallest candidate in the budget whose excess of squared
// held-out error over the best's is within one standard error of that excess across the lamps
// held out. Known answers: the per-lamp shares sum to the relative error squared, the best's
// excess is 0, the chosen is within noise, every smaller candidate in the budget is not; at
// noise_z = 0 the best itself is chosen, and a huge noise_z takes the smallest.
TEST_F(PcaSessionFitTest, TheChoiceTakesTheSmallestCandidateWithinTheNoiseOfTheBest) {
  PcaHdrChoiceOptions o = options_;
  o.components = {2, 6, 9};
  o.qualities = {60, 95};
  auto fit = ChoosePcaHdr(maps_, directions_, lamp_, o);
  ASSERT_TRUE(fit.ok()) << fit.error().ToString();
  ASSERT_EQ(fit->candidates.size(), 2u * 3u * 2u);
  const auto& best = fit->candidates[fit->best];
  const auto& chosen = fit->candidates[fit->chosen];
  EXPECT_EQ(best.excess, 0);
  for (const auto& c : fit->candidates) {
    double sum = 0;
    for (double e : c.per_lamp) sum += e;
    EXPECT_EQ(c.per_lamp.size(), 5u);  // 28 lamps, ceil(28 / 6) held out, inside the outline
    EXPECT_NEAR(std::sqrt(sum), c.held_out_relative, 1e-12);
    EXPECT_GE(c.held_out_relative, best.held_out_relative);
    EXPECT_GE(c.excess_se, 0);
    if (c.bytes_per_pixel < chosen.bytes_per_pixel) {
      EXPECT_GT(c.excess, c.excess_se) << c.components;
    }
  }
  EXPECT_LE(chosen.excess, chosen.excess_se);
  EXPECT_NE(fit->reason.find("standard error"), std::string::npos) << fit->reason;
  // The two-component candidates are beyond the noise of the best.
  EXPECT_GT(fit->candidates[0].excess, fit->candidates[0].excess_se) << PcaHdrChoiceMarkdown(*fit);
  EXPECT_GT(fit->candidates[0].held_out_relative, 0.1);  // a map's non-finite samples left out

  o.noise_z = 0;
  auto strict = ChoosePcaHdr(maps_, directions_, lamp_, o);
  ASSERT_TRUE(strict.ok());
  EXPECT_EQ(strict->chosen, strict->best);
  o.noise_z = 1e9;
  auto loose = ChoosePcaHdr(maps_, directions_, lamp_, o);
  ASSERT_TRUE(loose.ok());
  for (const auto& c : loose->candidates)
    EXPECT_GE(c.bytes_per_pixel, loose->candidates[loose->chosen].bytes_per_pixel);
}

// The held-out lamps lie inside the set's outline, so the fold measures relighting between
// lamps: on the rig's default grid (h 0-90°, v 0-30°, 10° steps) the lamps of the outer rows and
// columns are never held out; on a dome its lowest ring is the outline.
TEST(HeldOutLamps, InsideTheOutlineOfTheGridAndOfADome) {
  std::vector<Vec3> grid;
  std::vector<std::pair<int, int>> pose;
  for (int v = 0; v <= 30; v += 10)
    for (int h = 0; h <= 90; h += 10) {
      grid.push_back(LightDirection(h, v));
      pose.emplace_back(h, v);
    }
  const std::vector<int> inner = InteriorLamps(grid);
  ASSERT_EQ(inner.size(), 16u);  // h 10-80 at v 10 and 20
  for (int i : inner) {
    EXPECT_GT(pose[i].first, 0);
    EXPECT_LT(pose[i].first, 90);
    EXPECT_GT(pose[i].second, 0);
    EXPECT_LT(pose[i].second, 30);
  }
  PcaHdrChoiceOptions o;
  const std::vector<int> held = ChoiceHeldOutLamps(grid, o);
  ASSERT_EQ(held.size(), HeldOutLamps(grid.size(), o.validation_every).size());  // 7 of 40
  for (int i : held) EXPECT_NE(std::find(inner.begin(), inner.end(), i), inner.end()) << i;
  EXPECT_EQ(held.front(), inner.front());
  EXPECT_EQ(held.back(), inner.back());
  EXPECT_TRUE(std::is_sorted(held.begin(), held.end()));
  EXPECT_EQ(std::adjacent_find(held.begin(), held.end()), held.end());
  EXPECT_NE(HeldOutRuleName(grid, o).find("outline"), std::string::npos);
  o.held_out = "every";
  EXPECT_EQ(ChoiceHeldOutLamps(grid, o), HeldOutLamps(grid.size(), 6));
  EXPECT_EQ(HeldOutRuleName(grid, o), "every 6th");

  // A dome: rings at 15, 40 and 65° of elevation (12, 10, 6 lamps) and the zenith.
  std::vector<Vec3> dome;
  const double pi = std::acos(-1.0);
  for (auto [elevation, count] : std::vector<std::pair<double, int>>{{15, 12}, {40, 10}, {65, 6}}) {
    for (int k = 0; k < count; ++k) {
      const double e = elevation * pi / 180, a = 2 * pi * (k + 0.5 * (count == 10)) / count;
      dome.push_back({std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)});
    }
  }
  dome.push_back({0, 0, 1});
  const std::vector<int> dome_inner = InteriorLamps(dome);
  EXPECT_EQ(dome_inner.size(), 17u);  // all but the lowest ring
  for (int i : dome_inner) EXPECT_GE(i, 12);

  // Too few lamps inside (a single row): every n-th instead.
  std::vector<Vec3> row;
  for (int h = 0; h <= 90; h += 10) row.push_back(LightDirection(h, 20));
  EXPECT_TRUE(InteriorLamps(row).empty());
  EXPECT_EQ(ChoiceHeldOutLamps(row, PcaHdrChoiceOptions{}), HeldOutLamps(row.size(), 6));
}

}  // namespace
}  // namespace rig
