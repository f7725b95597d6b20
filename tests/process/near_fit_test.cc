// The harmonic fit of a near lamp (docs/lights.md "Near lamps"): the simulator renders a lamp
// 300 mm from a 100 mm field exactly; the fit with the far-lamp assumption, with the samples
// divided by their fall-off, and with per-tile (or per-pixel) directions is relit at off-grid
// directions against the simulator's far-lamp truth (Brdf()). Prints the table of
// docs/lights.md; a far lamp's fit is the shared projector's, unchanged.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/session/map_store.h"
#include "process/model/harmonic/model.h"
#include "process/model/session/model_stream.h"
#include "sim/scene.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

constexpr double kLampMm = 300, kFieldMm = 100;

SimScene MakeScene(double lamp_mm) {
  SimConfig sim;
  sim.scene = "matte";
  sim.width = 160;
  sim.height = 120;
  sim.lamp_distance_mm = lamp_mm;
  sim.field_height_mm = kFieldMm;
  auto s = SimScene::Create(sim);
  EXPECT_TRUE(s.ok()) << s.error().ToString();
  return std::move(s).value();
}

// The scene's exact radiance at the 40 poses of the default grid, held as a session holds
// its maps (lamp radiance 1).
struct Capture {
  std::unique_ptr<MapStore> store;
  std::vector<std::string> keys;
  StreamFitInput in;
};

Capture Render(const SimScene& scene) {
  Capture c;
  c.store = std::make_unique<MapStore>(ExrPixelType::kFloat, 40, size_t{1} << 30);
  std::vector<double> h, v;
  for (int vd = 0; vd <= 30; vd += 10)
    for (int hd = 0; hd <= 90; hd += 10) {
      const Vec3 l = LightDirection(hd, vd);
      const std::string key = "h" + std::to_string(hd) + "_v" + std::to_string(vd);
      EXPECT_TRUE(c.store->Add(key, scene.Radiance(l, {1, 1, 1}), cv::Mat()).ok());
      c.keys.push_back(key);
      c.in.directions.push_back(l);
      h.push_back(hd);
      v.push_back(vd);
    }
  c.in.weights = GridQuadratureWeights(h, v);
  return c;
}

// The scene's surface depth (mm, relative to the arm's centre of rotation) per pixel.
cv::Mat Depth(const SimScene& scene) {
  cv::Mat d(scene.height(), scene.width(), CV_32FC1);
  for (int y = 0; y < scene.height(); ++y)
    for (int x = 0; x < scene.width(); ++x)
      d.at<float>(y, x) = static_cast<float>(scene.SurfacePoint(x, y)[2] * scene.mm_per_unit());
  return d;
}

struct Relit {
  double relative_rms = 0, psnr_db = 0, time_s = 0;
  int order = 0, tile_px = 0;
  size_t projectors = 0;
  cv::Mat coefficients;  // every term's plane, stacked (for bit-for-bit comparisons)
};

class NearFitTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("rig_near_fit_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Fits the capture with `in`'s near-lamp settings, then relights the model at off-grid
  // directions against the far-lamp truth: relative RMS (all pixels, all channels) and PSNR
  // (peak: the truth's largest value).
  Relit FitAndRelight(const SimScene& scene, const Capture& c, const StreamFitInput& in) {
    Relit out;
    auto bands = c.store->Bands(c.keys);
    EXPECT_TRUE(bands.ok()) << bands.error().ToString();
    if (!bands.ok()) return out;
    FitOptions o;  // SH, rls, order and λ from leave-one-out, linear space
    const std::string path = (dir_ / ("model" + std::to_string(fits_++) + ".exr")).string();
    auto fit = FitModelFromBands(**bands, in, o, path, ExrPixelType::kFloat);
    EXPECT_TRUE(fit.ok()) << fit.error().ToString();
    if (!fit.ok()) return out;
    out.time_s = fit->time_s;
    out.order = fit->selection.order;
    out.tile_px = fit->near_tile_px;
    out.projectors = fit->projectors;
    auto model = LoadModel(path);
    EXPECT_TRUE(model.ok()) << model.error().ToString();
    if (!model.ok()) return out;
    cv::vconcat(model->coefficients(), out.coefficients);
    double se = 0, st = 0, peak = 0, count = 0;
    for (const auto& hv : {std::pair{45.0, 20.0}, {15.0, 25.0}, {75.0, 5.0}, {35.0, 12.0}}) {
      const Vec3 l = LightDirection(hv.first, hv.second);
      const cv::Mat truth = scene.Brdf(l), rho = model->EvaluateRho(l);
      for (int y = 0; y < truth.rows; ++y)
        for (int x = 0; x < 3 * truth.cols; ++x) {
          const double t = truth.ptr<float>(y)[x], d = rho.ptr<float>(y)[x] - t;
          se += d * d;
          st += t * t;
          peak = std::max(peak, t);
          ++count;
        }
    }
    out.relative_rms = std::sqrt(se / st);
    out.psnr_db = 20 * std::log10(peak / std::sqrt(se / count));
    return out;
  }

  fs::path dir_;
  int fits_ = 0;
};

// A near-lamp fit's input: the surface on the plane z = plane_z_mm ([light_frame]
// surface_depth_mm), or at `depth` per pixel when given.
StreamFitInput NearInput(const Capture& c, int tile_px, bool falloff_only, const cv::Mat& depth,
                         double plane_z_mm = 0) {
  StreamFitInput in = c.in;
  LightFrameConfig frame;
  frame.lamp_distance_mm = kLampMm;
  frame.field_height_mm = kFieldMm;
  frame.surface_depth_mm = plane_z_mm;
  in.near_lamp = NearLamp::FromLightFrame(frame, 120);
  in.near_lamp.depth_mm = depth;
  in.near_tile_px = tile_px;
  in.near_falloff_only = falloff_only;
  return in;
}

TEST_F(NearFitTest, TheCorrectedFitRelightsANearLampFarBetterThanTheFarAssumption) {
  const SimScene scene = MakeScene(kLampMm);
  const Capture c = Render(scene);
  const cv::Mat depth = Depth(scene);
  const Relit far = FitAndRelight(scene, c, c.in);
  // The session's own knowledge: the surface taken through the centre of rotation (z = 0).
  const Relit plane = FitAndRelight(scene, c, NearInput(c, 0, false, cv::Mat()));
  // The surface's depth known, tiles from the default 0.5° bound.
  const Relit known = FitAndRelight(scene, c, NearInput(c, 0, false, depth));
  std::printf("far assumption %.4f, near at z = 0 %.4f (tile %d px), depth known %.4f (tile %d px)\n",
              far.relative_rms, plane.relative_rms, plane.tile_px, known.relative_rms, known.tile_px);
  EXPECT_GT(far.relative_rms, 0.1);  // the far-lamp assumption is badly wrong here
  EXPECT_LT(known.relative_rms, far.relative_rms / 10);
  EXPECT_LT(plane.relative_rms, far.relative_rms * 0.8);
  EXPECT_GT(known.tile_px, 1);
  EXPECT_GT(known.projectors, 1u);
}

TEST_F(NearFitTest, AFarLampTakesTheSharedProjectorBitForBit) {
  const SimScene scene = MakeScene(0);
  const Capture c = Render(scene);
  const Relit plain = FitAndRelight(scene, c, c.in);
  // A [light_frame] without a lamp distance (the field's height alone) is a far lamp.
  StreamFitInput in = c.in;
  LightFrameConfig frame;
  frame.field_height_mm = kFieldMm;
  in.near_lamp = NearLamp::FromLightFrame(frame, 120);
  EXPECT_FALSE(in.near_lamp.near());
  const Relit again = FitAndRelight(scene, c, in);
  ASSERT_FALSE(plain.coefficients.empty());
  EXPECT_EQ(cv::norm(plain.coefficients, again.coefficients, cv::NORM_INF), 0.0);
  EXPECT_EQ(again.tile_px, 0);
  EXPECT_EQ(again.projectors, 1u);
  EXPECT_LT(plain.relative_rms, 0.05);  // the far lamp's own floor: the basis, not the lamp
}

TEST_F(NearFitTest, TilesOfALampFarAwayFitAsTheSharedProjectorWithMissingSamplesToo) {
  // A lamp 10^9 mm away: every tile's directions and every fall-off equal the far lamp's to
  // ~1e-7, so 7 px tiles (crossing the 32-row bands, clipped at the image's edges) must give
  // the shared projector's coefficients, the solves for missing samples included.
  const SimScene scene = MakeScene(0);
  Capture c = Render(scene);
  Capture holed;
  holed.store = std::make_unique<MapStore>(ExrPixelType::kFloat, 40, size_t{1} << 30);
  holed.keys = c.keys;
  holed.in = c.in;
  for (size_t i = 0; i < c.keys.size(); ++i) {
    cv::Mat m = scene.Radiance(c.in.directions[i], {1, 1, 1});
    for (int k = 0; k < 30; ++k) {
      const int x = static_cast<int>((i * 37 + k * 53) % 160), y = static_cast<int>((i * 11 + k * 29) % 120);
      m.at<cv::Vec3f>(y, x)[k % 3] = k % 2 ? std::nanf("") : -1.0f;
    }
    ASSERT_TRUE(holed.store->Add(c.keys[i], m, cv::Mat()).ok());
  }
  const Relit far = FitAndRelight(scene, holed, holed.in);
  StreamFitInput in = holed.in;
  in.near_lamp.distance_mm = 1e9;
  in.near_lamp.mm_per_px = kFieldMm / 120;
  in.near_tile_px = 7;
  const Relit tiles = FitAndRelight(scene, holed, in);
  EXPECT_EQ(tiles.tile_px, 7);
  EXPECT_EQ(tiles.order, far.order);
  ASSERT_FALSE(far.coefficients.empty());
  ASSERT_EQ(far.coefficients.size(), tiles.coefficients.size());
  const double scale = cv::norm(far.coefficients, cv::NORM_INF);
  EXPECT_LT(cv::norm(far.coefficients, tiles.coefficients, cv::NORM_INF), 1e-4 * scale);
  EXPECT_NEAR(tiles.relative_rms, far.relative_rms, 1e-5);
}

TEST(NearLampFalloff, ACropIsDividedAsTheSameRegionOfTheWholeImage) {
  // The reference patch's crops are corrected with their offset in the image.
  const SimScene scene = MakeScene(kLampMm);
  const Capture c = Render(scene);
  const std::vector<Vec3> dirs = {c.in.directions[3], c.in.directions[27]};
  std::vector<cv::Mat> whole, crop;
  for (const Vec3& l : dirs) {
    whole.push_back(scene.Radiance(l, {1, 1, 1}));
    crop.push_back(whole.back()(cv::Rect(37, 21, 19, 13)).clone());
  }
  LightFrameConfig frame;
  frame.lamp_distance_mm = kLampMm;
  frame.field_height_mm = kFieldMm;
  const NearLamp lamp = NearLamp::FromLightFrame(frame, 120);
  const cv::Mat before = crop[1].clone();
  DivideByFalloff(lamp, dirs, 0, 0, 160, 120, &whole);
  DivideByFalloff(lamp, dirs, 37, 21, 160, 120, &crop);
  for (size_t i = 0; i < dirs.size(); ++i)
    EXPECT_EQ(cv::norm(crop[i], whole[i](cv::Rect(37, 21, 19, 13)), cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(crop[1], before, cv::NORM_INF), 0.0);  // the fall-off is not 1 there
}

// [light_frame] surface_depth_mm places the plane: the same directions, fall-offs and tile
// bound as a constant depth map, and the fit's header says where the surface was taken.
TEST(NearLampPlane, APlaneOffsetIsAConstantDepthMap) {
  LightFrameConfig frame;
  frame.lamp_distance_mm = kLampMm;
  frame.field_height_mm = kFieldMm;
  frame.surface_depth_mm = -50;
  const NearLamp plane = NearLamp::FromLightFrame(frame, 120);
  EXPECT_EQ(plane.plane_z_mm, -50);
  NearLamp map = plane;
  map.plane_z_mm = 0;
  map.depth_mm = cv::Mat(120, 160, CV_32FC1, cv::Scalar(-50));
  frame.surface_depth_mm = 0;
  const NearLamp through = NearLamp::FromLightFrame(frame, 120);
  for (const Vec3& l : {LightDirection(0, 0), LightDirection(70, 20), LightDirection(-30, 5)})
    for (const auto& [i, j] : {std::pair{0, 0}, {159, 119}, {80, 7}}) {
      double fp = 0, fm = 0, f0 = 0;
      const Vec3 a = plane.At(i, j, 160, 120, l, &fp), b = map.At(i, j, 160, 120, l, &fm);
      through.At(i, j, 160, 120, l, &f0);
      EXPECT_EQ(a, b);
      EXPECT_EQ(fp, fm);
      EXPECT_NE(fp, f0);  // the plane moved
      EXPECT_EQ(plane.InverseFalloff(i, j, 160, 120, l), map.InverseFalloff(i, j, 160, 120, l));
    }
  EXPECT_EQ(plane.TilePx(160, 120, 1.0), map.TilePx(160, 120, 1.0));
  NearLamp deep = plane;
  deep.plane_z_mm = -150;  // |z| bounds the tile
  EXPECT_LT(deep.TilePx(160, 120, 1.0), through.TilePx(160, 120, 1.0));
  EXPECT_LE(plane.TilePx(160, 120, 1.0), through.TilePx(160, 120, 1.0));
  // A far lamp ignores it.
  frame.lamp_distance_mm = 0;
  frame.surface_depth_mm = -50;
  const NearLamp far = NearLamp::FromLightFrame(frame, 120);
  double f = 0;
  EXPECT_FALSE(far.near());
  EXPECT_EQ(far.At(3, 4, 160, 120, LightDirection(40, 10), &f), LightDirection(40, 10));
  EXPECT_EQ(f, 1);
}

TEST_F(NearFitTest, TheHeaderSaysWhereTheSurfaceWasTaken) {
  const SimScene scene = MakeScene(kLampMm);
  const Capture c = Render(scene);
  for (double z : {0.0, -50.0}) {
    auto bands = c.store->Bands(c.keys);
    ASSERT_TRUE(bands.ok()) << bands.error().ToString();
    const std::string out = (dir_ / fmt::format("header_{}.exr", fits_++)).string();
    FitOptions o;
    o.order = 4;
    auto fit = FitModelFromBands(**bands, NearInput(c, 0, false, cv::Mat(), z), o, out,
                                 ExrPixelType::kFloat);
    ASSERT_TRUE(fit.ok()) << fit.error().ToString();
    auto header = ReadExr(out);
    ASSERT_TRUE(header.ok()) << header.error().ToString();
    ASSERT_TRUE(header->attributes.count("near_lamp"));
    EXPECT_NE(header->attributes.at("near_lamp").find(fmt::format("surface at z = {:g} mm", z)),
              std::string::npos) << header->attributes.at("near_lamp");
  }
}

TEST_F(NearFitTest, PrintsTheTableOfDocsLights) {
  const SimScene far_scene = MakeScene(0);
  const Capture far_capture = Render(far_scene);
  const SimScene scene = MakeScene(kLampMm);
  const Capture c = Render(scene);
  const cv::Mat depth = Depth(scene);
  struct Row {
    std::string name;
    Relit r;
  };
  std::vector<Row> rows;
  rows.push_back({"far lamp (reference: the simulator's lamp far)", FitAndRelight(far_scene, far_capture, far_capture.in)});
  rows.push_back({"far-lamp assumption", FitAndRelight(scene, c, c.in)});
  // Where the fit places the surface: the plane through the centre of rotation (what a
  // session's [light_frame] says; the simulator's plane lies ~50 mm behind it), or the
  // surface's depth per pixel.
  // Between them, the plane at the simulator's true depth at the image centre
  // ([light_frame] surface_depth_mm; the plane is tilted and the sphere stands in front).
  struct Surface {
    std::string where;
    cv::Mat depth;
    double plane_z_mm;
  };
  const double z_true = scene.plane_depth_mm();
  const std::vector<Surface> surfaces = {
      {"z = 0", cv::Mat(), 0},
      {fmt::format("surface_depth_mm = {:g}", z_true), cv::Mat(), z_true},
      {"depth known", depth, 0}};
  for (const auto& [where, d, z] : surfaces) {
    rows.push_back({"fall-off only, " + where, FitAndRelight(scene, c, NearInput(c, 0, true, d, z))});
    for (int tile : {32, 16, 8, 0}) {
      const Relit r = FitAndRelight(scene, c, NearInput(c, tile, false, d, z));
      rows.push_back({"per tile " + std::to_string(r.tile_px) + " px" + (tile == 0 ? " (1° bound)" : "") + ", " + where, r});
    }
  }
  // Every pixel its own projector (19200 of them): what the tiles approach.
  rows.push_back({"per pixel, depth known", FitAndRelight(scene, c, NearInput(c, 1, false, depth))});
  // The one plane that suits this scene best is not the plane's own: the sphere stands up to
  // ~66 mm in front of it; the scene's mean depth.
  const double z_mean = cv::mean(depth)[0];
  rows.push_back({fmt::format("per tile (1° bound), surface_depth_mm = {:.1f} (the scene's mean depth)", z_mean),
                  FitAndRelight(scene, c, NearInput(c, 0, false, cv::Mat(), z_mean))});
  std::printf("| lamp 300 mm from a 100 mm field, matte 160x120, 40 poses | order | projectors | relit relative RMS | PSNR (dB) | fit time (s) |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (const auto& row : rows)
    std::printf("| %s | %d | %zu | %.4f | %.2f | %.3f |\n", row.name.c_str(), row.r.order,
                row.r.projectors, row.r.relative_rms, row.r.psnr_db, row.r.time_s);
  // Every correction helps, and directions help beyond the fall-off.
  const double far_assumption = rows[1].r.relative_rms;
  for (size_t i = 2; i < rows.size(); ++i) EXPECT_LT(rows[i].r.relative_rms, far_assumption) << rows[i].name;
  // Rows 2-6 are z = 0, 7-11 the plane at its true depth, 12-16 the depth map (fall-off only,
  // then tiles down to the bound), 17 per pixel, 18 the plane at the scene's mean depth.
  ASSERT_EQ(rows.size(), 19u);
  EXPECT_LT(rows[17].r.relative_rms, rows[12].r.relative_rms);  // per pixel vs fall-off only (depth known)
  // The plane at its true depth removes part of the error of z = 0 (the sphere in front of
  // it keeps the rest), and never does worse than it, with or without tiles.
  EXPECT_LT(rows[11].r.relative_rms, 0.85 * rows[6].r.relative_rms);  // 1° tiles
  EXPECT_LT(rows[7].r.relative_rms, rows[2].r.relative_rms);          // fall-off only
  EXPECT_LT(rows[18].r.relative_rms, rows[11].r.relative_rms);        // the mean depth suits it better
  EXPECT_GT(rows[18].r.relative_rms, rows[16].r.relative_rms);        // than any plane: the depth map
}

}  // namespace
}  // namespace rig
