// The model fitted from radiance maps held in memory (MapStore, as the capture keeps them while
// it merges) against the model fitted from the same maps' EXR files: equal value for value,
// for half and float maps, with saturated and black flags, non-finite and negative samples,
// one map without a flags channel, bands smaller than the selection and two workers; what
// the store refuses and when it turns itself off.
#include "process/model/session/map_store.h"

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>

#include "process/hdr/hdr.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/session/model_stream.h"
#include "process/model/session/selection_gram.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 83, kHeight = 57;

struct Pose {
  double h, v;
};

std::vector<Pose> Grid() {
  std::vector<Pose> g;
  for (int v = 0; v <= 30; v += 10)
    for (int h = 0; h <= 90; h += 15) g.push_back({double(h), double(v)});
  return g;
}

// A glossy, textured scene lit from pose p; flags mark saturated (1) and black (2) pixels,
// with some samples made non-finite or negative (missing without a flag).
RadianceMap Render(const Pose& p, size_t index, bool with_flags) {
  const Vec3 l = LightDirection(p.h, p.v);
  std::mt19937 rng(static_cast<unsigned>(1000 + index));
  std::normal_distribution<float> noise(0.f, 0.01f);
  RadianceMap m;
  m.radiance.create(kHeight, kWidth, CV_32FC3);
  if (with_flags) m.flags = cv::Mat::zeros(kHeight, kWidth, CV_8U);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const double u = (x + 0.5) / kWidth - 0.5, v = (y + 0.5) / kHeight - 0.5;
      Vec3 n = {0.5 * std::sin(9 * u), 0.4 * std::cos(7 * v), 1};
      const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (auto& q : n) q /= nn;
      const double ndl = std::max(0.0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
      const double spec = std::pow(std::max(0.0, 2 * ndl * n[2] - l[2]), 20);
      auto* px = m.radiance.ptr<cv::Vec3f>(y) + x;
      for (int c = 0; c < 3; ++c) {
        const double albedo = (0.2 + 0.5 * ((x / 7 + y / 5) % 2)) * (1.0 - 0.2 * c);
        (*px)[c] = static_cast<float>(3.0 * (albedo * ndl + 0.8 * spec) + 0.01) + noise(rng);
      }
      if (with_flags && spec > 0.6 && (x + y + int(index)) % 3 == 0) m.flags.at<uint8_t>(y, x) = kFlagSaturated;
      if (with_flags && x < 3 && y % 11 == int(index % 11)) m.flags.at<uint8_t>(y, x) = kFlagBlack;
    }
  }
  // Missing without a flag: a NaN, an infinity and a negative sample in some maps.
  if (index % 4 == 1) m.radiance.at<cv::Vec3f>(5, 7)[1] = std::nanf("");
  if (index % 5 == 2) m.radiance.at<cv::Vec3f>(40, 60)[0] = INFINITY;
  if (index % 6 == 3) m.radiance.at<cv::Vec3f>(20, 30)[2] = -0.5f;
  return m;
}

class MapStoreTest : public ::testing::TestWithParam<ExrPixelType> {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("rig_map_store_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The maps written as the merge writes them, and kept in `store` as the capture keeps them.
  void Capture(MapStore* store, StreamFitInput* in, std::vector<std::string>* keys) {
    const auto grid = Grid();
    std::vector<double> h, v;
    for (size_t i = 0; i < grid.size(); ++i) {
      // Map 2 has no flags channel at all (valid everywhere unless non-finite).
      RadianceMap m = Render(grid[i], i, i != 2);
      const std::string key = "p" + std::to_string(i);
      const std::string path = (dir_ / (key + ".exr")).string();
      ASSERT_TRUE(WriteRadianceMap(path, m, GetParam(), 2).ok());
      ASSERT_TRUE(store->Add(key, m.radiance, m.flags).ok());
      in->paths.push_back(path);
      in->directions.push_back(LightDirection(grid[i].h, grid[i].v));
      keys->push_back(key);
      h.push_back(grid[i].h);
      v.push_back(grid[i].v);
    }
    in->weights = GridQuadratureWeights(h, v);
    in->lamp_radiance_rgb = {1.5, 1.2, 0.9};
    in->band_rows = 8;        // bands far smaller than the image
    in->selection_rows = 24;  // the selection sees three of them
  }

  static ExrImage Read(const fs::path& p) {
    auto r = ReadExr(p.string());
    EXPECT_TRUE(r.ok()) << r.error().ToString();
    return r.ok() ? std::move(r).value() : ExrImage{};
  }

  fs::path dir_;
};

TEST_P(MapStoreTest, TheModelFromMemoryEqualsTheModelFromTheFilesValueForValue) {
  MapStore store(GetParam(), Grid().size(), size_t{1} << 30);
  StreamFitInput in;
  std::vector<std::string> keys;
  Capture(&store, &in, &keys);
  ASSERT_FALSE(store.off());
  EXPECT_EQ(store.maps(), keys.size());

  FitOptions o;
  o.basis = BasisKind::kHsh;
  o.transform.space = FitSpace::kLog;  // missing samples must stay out of the log
  auto files = FitModelStreaming(in, o, (dir_ / "files.exr").string(), ExrPixelType::kFloat);
  ASSERT_TRUE(files.ok()) << files.error().ToString();
  o.threads = 2;  // two workers fit bands from memory
  auto bands = store.Bands(keys);
  ASSERT_TRUE(bands.ok()) << bands.error().ToString();
  auto memory = FitModelFromBands(**bands, in, o, (dir_ / "memory.exr").string(), ExrPixelType::kFloat);
  ASSERT_TRUE(memory.ok()) << memory.error().ToString();

  // The same choice, the same pixels left to their own samples, the same coefficients.
  EXPECT_EQ(memory->selection.order, files->selection.order);
  EXPECT_EQ(memory->selection.projector.lambda, files->selection.projector.lambda);
  EXPECT_EQ(memory->loo_rmse, files->loo_rmse);
  EXPECT_GT(files->missing.pixels_with_missing, 50u);  // flags, NaN, inf and negatives were seen
  EXPECT_EQ(memory->missing.pixels_with_missing, files->missing.pixels_with_missing);
  EXPECT_EQ(memory->missing.flagged, files->missing.flagged);
  EXPECT_EQ(memory->missing.patterns, files->missing.patterns);
  const ExrImage a = Read(dir_ / "files.exr"), b = Read(dir_ / "memory.exr");
  ASSERT_EQ(a.channel_names, b.channel_names);
  ASSERT_GT(a.channel_names.size(), 3u);
  EXPECT_EQ(a.channel_names.back(), "valid");
  for (size_t c = 0; c < a.channels.size(); ++c) {
    EXPECT_EQ(cv::norm(a.channels[c], b.channels[c], cv::NORM_INF), 0.0) << a.channel_names[c];
  }
}

TEST_P(MapStoreTest, AMapReadBackFromItsFileIsHeldAsTheMergedOne) {
  MapStore merged(GetParam(), Grid().size(), size_t{1} << 30);
  StreamFitInput in;
  std::vector<std::string> keys;
  Capture(&merged, &in, &keys);
  MapStore reread(GetParam(), keys.size(), size_t{1} << 30);
  for (size_t i = 0; i < keys.size(); ++i) ASSERT_TRUE(reread.AddFile(keys[i], in.paths[i]).ok());
  auto a = merged.Bands(keys), b = reread.Bands(keys);
  ASSERT_TRUE(a.ok() && b.ok());
  std::vector<cv::Mat> ra, va, rb, vb;
  ASSERT_TRUE((*a)->Read(0, kHeight, &ra, &va).ok());
  ASSERT_TRUE((*b)->Read(0, kHeight, &rb, &vb).ok());
  ASSERT_EQ(ra.size(), rb.size());
  ASSERT_EQ(va.size(), ra.size());
  for (size_t i = 0; i < ra.size(); ++i) {
    // NaN != NaN: compare the bits.
    EXPECT_EQ(std::memcmp(ra[i].data, rb[i].data, ra[i].total() * ra[i].elemSize()), 0) << keys[i];
    EXPECT_EQ(cv::norm(va[i], vb[i], cv::NORM_INF), 0.0) << keys[i];
  }
  // The map without flags reads as valid everywhere; a flagged pixel as invalid.
  EXPECT_EQ(cv::countNonZero(va[2]), kWidth * kHeight);
  EXPECT_LT(cv::countNonZero(va[0]), kWidth * kHeight);
}

// The selection's Gram matrix accumulated map by map as the maps arrive (the store planned for
// the fit) against the same matrix from every map at once, and against the plain sum over the
// complete pixels (SampleGram of each band, as the fit computed it before), far and near lamp.
TEST_P(MapStoreTest, TheGramAccumulatedAsTheMapsArriveIsTheBatchGramBitForBit) {
  for (const double distance : {0.0, 300.0}) {
    SCOPED_TRACE(distance > 0 ? "near lamp" : "far lamp");
    LightFrameConfig frame;
    frame.lamp_distance_mm = distance;
    frame.field_height_mm = distance > 0 ? 100 : 0;
    FitTransform transform;
    transform.space = FitSpace::kLog;
    const std::array<double, 3> e = {1.5, 1.2, 0.9};  // as Capture sets it
    std::map<std::string, Vec3> planned;
    const auto grid = Grid();
    for (size_t i = 0; i < grid.size(); ++i)
      planned["p" + std::to_string(i)] = LightDirection(grid[i].h, grid[i].v);
    MapStore store(GetParam(), grid.size(), size_t{1} << 30);
    store.PlanSelectionGram(planned, e, transform, frame, 8, 24);
    StreamFitInput in;
    std::vector<std::string> keys;
    Capture(&store, &in, &keys);
    in.near_lamp = NearLamp::FromLightFrame(frame, kHeight);
    // Replaced, dropped and read back from its file: arrival order and repeats do not matter.
    ASSERT_TRUE(store.AddFile(keys[3], in.paths[3]).ok());
    store.Drop(keys[5]);
    ASSERT_TRUE(store.AddFile(keys[5], in.paths[5]).ok());

    const SelectionLayout layout{kWidth, kHeight, in.band_rows, in.selection_rows};
    const SampleSpace space{in.lamp_radiance_rgb, transform, in.near_lamp};
    auto accumulated = store.SelectionGram(keys, in.directions, layout, space);
    ASSERT_TRUE(accumulated.has_value());
    auto files = OpenMapFiles(in.paths);
    ASSERT_TRUE(files.ok());
    auto batch = SelectionGramOfBands(**files, in.directions, layout, space, 2);
    ASSERT_TRUE(batch.ok()) << batch.error().ToString();
    EXPECT_EQ(accumulated->count, batch->count);
    ASSERT_EQ(accumulated->gram.size(), batch->gram.size());
    EXPECT_EQ(std::memcmp(accumulated->gram.data(), batch->gram.data(),
                          sizeof(double) * static_cast<size_t>(batch->gram.size())),
              0);

    // The matrix it stands for: Σ over the complete pixels of every selection band.
    Eigen::MatrixXd plain = Eigen::MatrixXd::Zero(batch->gram.rows(), batch->gram.cols());
    double count = 0;
    size_t incomplete = 0;
    for (const auto& [y0, y1] : layout.Bands()) {
      std::vector<cv::Mat> bgr, valid;
      ASSERT_TRUE((*files)->Read(y0, y1, &bgr, &valid).ok());
      DivideByFalloff(in.near_lamp, in.directions, 0, y0, kWidth, kHeight, &bgr);
      SampleMatrix y;
      std::vector<uint8_t> missing;
      ASSERT_TRUE(BuildSamples(bgr, valid, e, transform, &y, &missing).ok());
      double c = 0;
      plain += SampleGram(y, missing, 1, &c);
      count += c;
      incomplete += static_cast<size_t>(3 * (y1 - y0) * kWidth) - static_cast<size_t>(c);
    }
    EXPECT_GT(incomplete, 30u);  // the correction for pixels some map lacks was exercised
    EXPECT_EQ(batch->count, count);
    EXPECT_LT((batch->gram - plain).cwiseAbs().maxCoeff(), 1e-12 * plain.cwiseAbs().maxCoeff());

    // Planned for another lamp radiance (e.g. one a reference patch gives): not used.
    SampleSpace other = space;
    other.lamp_radiance_rgb[1] *= 1.01;
    EXPECT_FALSE(store.SelectionGram(keys, in.directions, layout, other).has_value());
    EXPECT_FALSE(store.SelectionGram(keys, in.directions, SelectionLayout{kWidth, kHeight, 8, 32}, space)
                     .has_value());

    // The model from memory (its Gram accumulated) equals the model from the files.
    FitOptions o;
    o.basis = BasisKind::kHsh;
    o.transform = transform;
    auto from_files = FitModelStreaming(in, o, (dir_ / "files.exr").string(), ExrPixelType::kFloat);
    ASSERT_TRUE(from_files.ok()) << from_files.error().ToString();
    o.threads = 2;
    auto bands = store.Bands(keys);
    ASSERT_TRUE(bands.ok());
    ASSERT_TRUE((*bands)->SelectionGram(in.directions, layout, space).has_value());
    auto memory = FitModelFromBands(**bands, in, o, (dir_ / "memory.exr").string(), ExrPixelType::kFloat);
    ASSERT_TRUE(memory.ok()) << memory.error().ToString();
    EXPECT_EQ(memory->selection.order, from_files->selection.order);
    EXPECT_EQ(memory->selection.projector.lambda, from_files->selection.projector.lambda);
    EXPECT_EQ(memory->loo_rmse, from_files->loo_rmse);
    const ExrImage a = Read(dir_ / "files.exr"), b = Read(dir_ / "memory.exr");
    ASSERT_EQ(a.channel_names, b.channel_names);
    for (size_t c = 0; c < a.channels.size(); ++c)
      EXPECT_EQ(cv::norm(a.channels[c], b.channels[c], cv::NORM_INF), 0.0) << a.channel_names[c];
  }
}

INSTANTIATE_TEST_SUITE_P(HalfAndFloat, MapStoreTest,
                         ::testing::Values(ExrPixelType::kHalf, ExrPixelType::kFloat),
                         [](const auto& info) {
                           return info.param == ExrPixelType::kHalf ? "half" : "float";
                         });

TEST(MapStore, TurnsItselfOffWhenThePlannedMapsWouldNotFitAndSaysWhy) {
  // 40 maps of 83x57 in half with flags: 40 x 83 x 57 x 7 bytes = 1.3 MB.
  MapStore store(ExrPixelType::kHalf, 40, 1000000);
  RadianceMap m = Render({30, 10}, 0, true);
  ASSERT_TRUE(store.Add("h030_v10", m.radiance, m.flags).ok());
  EXPECT_TRUE(store.off());
  EXPECT_EQ(store.maps(), 0u);
  EXPECT_EQ(store.bytes(), 0u);
  EXPECT_NE(store.off_reason().find("40 maps of 83x57"), std::string::npos) << store.off_reason();
  auto bands = store.Bands({"h030_v10"});
  ASSERT_FALSE(bands.ok());
  // A larger bound keeps it: 6 bytes of radiance and one of validity per pixel.
  MapStore roomy(ExrPixelType::kHalf, 40, 2000000);
  ASSERT_TRUE(roomy.Add("h030_v10", m.radiance, m.flags).ok());
  EXPECT_FALSE(roomy.off());
  EXPECT_EQ(roomy.bytes(), size_t{83} * 57 * 7);
}

TEST(MapStore, RefusesAMapOfAnotherSizeAndNamesTheMapItDoesNotHold) {
  MapStore store(ExrPixelType::kFloat, 4, size_t{1} << 30);
  RadianceMap m = Render({0, 0}, 0, false);
  ASSERT_TRUE(store.Add("a", m.radiance, m.flags).ok());
  cv::Mat small(10, 10, CV_32FC3, cv::Scalar::all(1));
  Status st = store.Add("b", small, cv::Mat());
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().ToString().find("10x10"), std::string::npos) << st.error().ToString();
  auto bands = store.Bands({"a", "c"});
  ASSERT_FALSE(bands.ok());
  EXPECT_NE(bands.error().ToString().find("c"), std::string::npos);
  store.Drop("a");
  EXPECT_FALSE(store.Has("a"));
  EXPECT_EQ(store.bytes(), 0u);
}

}  // namespace
}  // namespace rig
