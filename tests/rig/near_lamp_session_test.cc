// A near lamp through the whole session: `rig capture --dry-run` of a simulated lamp 300 mm
// from a 100 mm field, with the lamp's distance in [light_frame], fits its model with the
// near-lamp correction (fall-off per pixel, directions per tile), and that model relights the
// scene closer to the simulator's far-lamp truth than the same maps fitted as a far lamp; with
// the simulator's plane depth in [light_frame] surface_depth_mm, closer still.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <tuple>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "capture/plan/pose.h"
#include "capture/session/session_store.h"
#include "process/export/relight_files.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/harmonic/model.h"
#include "process/model/reflectance_model.h"
#include "process/model/any/load_model.h"
#include "capture/daemon/session_model.h"
#include "sim/scene.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using testing::RunRig;

// Relative RMS of the model's ρ against the simulator's far-lamp ρ at off-grid directions,
// after the one scale that best matches them (the camera's response leaves one).
double RelitError(const fs::path& model_path, const Config& config) {
  auto model = LoadModel(model_path.string());
  EXPECT_TRUE(model.ok()) << model.error().ToString();
  auto scene = SimScene::Create(config.sim);
  EXPECT_TRUE(scene.ok()) << scene.error().ToString();
  if (!model.ok() || !scene.ok()) return 0;
  std::vector<cv::Mat> truth, fitted;
  for (const auto& hv : {std::pair{45.0, 20.0}, {15.0, 25.0}, {75.0, 5.0}, {35.0, 12.0}}) {
    const Vec3 l = LightDirection(hv.first, hv.second, config.light_frame);
    truth.push_back(scene->Brdf(l));
    fitted.push_back(model->EvaluateRho(l));
  }
  double tm = 0, mm = 0, tt = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    tm += truth[i].dot(fitted[i]);
    mm += fitted[i].dot(fitted[i]);
    tt += truth[i].dot(truth[i]);
  }
  const double s = tm / mm;
  double se = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    const cv::Mat d = fitted[i] * s - truth[i];
    se += d.dot(d);
  }
  return std::sqrt(se / tt);
}

TEST(NearLampSession, TheSessionFitCorrectsANearLampFromItsLightFrame) {
  const std::string dir = testing::FreshTempDir("near_lamp_session");
  const std::string cfg = testing::WriteSimConfig(
      dir,
      "[sim]\nwidth = 96\nheight = 72\nscene = \"matte\"\nlamp_distance_mm = 300\n"
      "field_height_mm = 100\n[light_frame]\nlamp_distance_mm = 300\nfield_height_mm = 100\n");
  const fs::path s = fs::path(dir) / "S";
  auto r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string log = testing::ReadText((s / "log.txt").string());
  EXPECT_NE(log.find("near lamp 300 mm: samples divided by their fall-off"), std::string::npos) << log;
  auto header = ReadExr((s / "model" / "model.exr").string());
  ASSERT_TRUE(header.ok()) << header.error().ToString();
  ASSERT_TRUE(header->attributes.count("near_lamp"));
  EXPECT_NE(header->attributes.at("near_lamp").find("px tile"), std::string::npos);

  // The same session's maps fitted as a far lamp: a copy whose [light_frame] has no distance.
  const fs::path far = fs::path(dir) / "far";
  fs::copy(s, far, fs::copy_options::recursive);
  {
    std::istringstream in(testing::ReadText((s / "session.toml").string()));
    std::ostringstream out;
    std::string line, table;
    while (std::getline(in, line)) {
      if (!line.empty() && line[0] == '[') table = line;
      if (table == "[light_frame]" && line.rfind("lamp_distance_mm", 0) == 0) line = "lamp_distance_mm = 0";
      out << line << "\n";
    }
    std::ofstream(far / "session.toml") << out.str();
  }
  auto session = Session::OpenExisting(far);
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  ASSERT_EQ(session->config().light_frame.lamp_distance_mm, 0);
  Status st = FitSessionModel(*session, nullptr);
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  auto far_header = ReadExr((far / "model" / "model.exr").string());
  ASSERT_TRUE(far_header.ok());
  EXPECT_FALSE(far_header->attributes.count("near_lamp"));

  const double near_error = RelitError(s / "model" / "model.exr", session->config());
  const double far_error = RelitError(far / "model" / "model.exr", session->config());

  // The same dry run with the simulator's plane stated: [light_frame] surface_depth_mm, the
  // plane's true z at the image centre (the truth's scene.json says it too).
  auto scene = SimScene::Create(session->config().sim);
  ASSERT_TRUE(scene.ok()) << scene.error().ToString();
  const double z_true = scene->plane_depth_mm();
  ASSERT_LT(z_true, -1);  // behind the centre of rotation
  const std::string depth_cfg = testing::WriteSimConfig(
      dir,
      "[sim]\nwidth = 96\nheight = 72\nscene = \"matte\"\nlamp_distance_mm = 300\n"
      "field_height_mm = 100\n[light_frame]\nlamp_distance_mm = 300\nfield_height_mm = 100\n" +
          fmt::format("surface_depth_mm = {}\n", z_true));
  const fs::path sd = fs::path(dir) / "SD";
  r = RunRig("capture --config " + depth_cfg + " --out " + sd.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  auto depth_session = Session::OpenExisting(sd);
  ASSERT_TRUE(depth_session.ok()) << depth_session.error().ToString();
  EXPECT_EQ(depth_session->config().light_frame.surface_depth_mm, z_true);
  auto depth_header = ReadExr((sd / "model" / "model.exr").string());
  ASSERT_TRUE(depth_header.ok()) << depth_header.error().ToString();
  ASSERT_TRUE(depth_header->attributes.count("near_lamp"));
  EXPECT_NE(depth_header->attributes.at("near_lamp").find(fmt::format("surface at z = {:g} mm", z_true)),
            std::string::npos) << depth_header->attributes.at("near_lamp");
  const double depth_error = RelitError(sd / "model" / "model.exr", session->config());
  const auto truth = nlohmann::json::parse(testing::ReadText((sd / "truth" / "scene.json").string()));
  ASSERT_TRUE(truth.contains("surface_depth_mm"));
  EXPECT_EQ(truth["surface_depth_mm"].get<double>(), z_true);

  // The floor through the camera: the simulator's lamp far, fitted as a far lamp.
  const std::string far_cfg = testing::WriteSimConfig(
      dir, "[sim]\nwidth = 96\nheight = 72\nscene = \"matte\"\nfield_height_mm = 100\n");
  const fs::path sf = fs::path(dir) / "SF";
  r = RunRig("capture --config " + far_cfg + " --out " + sf.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  const double floor_error = RelitError(sf / "model" / "model.exr", session->config());

  std::printf("session (camera, JPEG, merge), 96x72: relit relative RMS: the simulator's lamp "
              "far %.4f; lamp 300 mm: far-lamp fit %.4f, near-lamp fit (z = 0) %.4f, near-lamp "
              "fit (surface_depth_mm = %g) %.4f\n",
              floor_error, far_error, near_error, z_true, depth_error);
  // With the surface through the centre of rotation, and the simulator's plane ~50 mm behind
  // it, the correction is partial (docs/lights.md).
  EXPECT_LT(near_error, 0.85 * far_error);
  // The plane's true depth removes part of what the near lamp still costs above the camera's
  // floor (the sphere standing in front of the plane keeps the rest: a plane is one depth for
  // the whole field).
  EXPECT_LT(floor_error, near_error);
  EXPECT_LT(depth_error - floor_error, 0.85 * (near_error - floor_error));
  fs::remove_all(dir);
}

// An .lp capture of the simulator's exact radiance (PNG, sRGB codes): "matte" 96 x 72, 36
// lamps at v 10..40, h -80..80 (all above the horizon, as the PCA family needs), the lamp at
// `lamp_mm` (0: far) from a 100 mm field; `scale` turns radiance into [0, 1] (the first call's
// brightest sample at 0.8, then passed back in so that every capture shares it).
std::string WriteNearLampLp(const std::string& dir, double lamp_mm, double* scale) {
  SimConfig sim;
  sim.scene = "matte";
  sim.width = 96;
  sim.height = 72;
  sim.lamp_distance_mm = lamp_mm;
  sim.field_height_mm = 100;
  auto scene = SimScene::Create(sim);
  EXPECT_TRUE(scene.ok()) << scene.error().ToString();
  std::vector<std::pair<Vec3, cv::Mat>> shots;
  double peak = 0;
  for (int v = 10; v <= 40; v += 10)
    for (int h = -80; h <= 80; h += 20) {
      const Vec3 l = LightDirection(h, v);
      shots.push_back({l, scene->Radiance(l, {1, 1, 1})});
      double lo = 0, hi = 0;
      cv::minMaxLoc(shots.back().second.reshape(1), &lo, &hi);
      peak = std::max(peak, hi);
    }
  if (*scale <= 0) *scale = 0.8 / peak;
  fs::create_directories(dir);
  std::vector<std::string> names;
  std::vector<Vec3> dirs;
  for (size_t k = 0; k < shots.size(); ++k) {
    cv::Mat img(72, 96, CV_8UC3);
    for (int y = 0; y < 72; ++y)
      for (int x = 0; x < 96; ++x)
        for (int c = 0; c < 3; ++c)
          img.at<cv::Vec3b>(y, x)[c] = static_cast<uint8_t>(std::clamp(
              std::lround(255.0 * SrgbEncode(static_cast<float>(
                                      shots[k].second.at<cv::Vec3f>(y, x)[c] * *scale))),
              0L, 255L));
    names.push_back(fmt::format("img{:02d}.png", k));
    cv::imwrite(dir + "/" + names.back(), img);
    dirs.push_back(shots[k].first);
  }
  EXPECT_TRUE(WriteLp(dir + "/dirs.lp", names, dirs).ok());
  return dir + "/dirs.lp";
}

// Relative RMS of any family's ρ against the simulator's far-lamp ρ at off-grid directions
// inside the lamps' span, after one best-fit scale.
double RelitErrorOfFamily(const std::string& model_path, const SimConfig& sim) {
  auto model = LoadReflectanceModel(model_path);
  EXPECT_TRUE(model.ok()) << model.error().ToString();
  auto scene = SimScene::Create(sim);
  if (!model.ok() || !scene.ok()) return 0;
  double tm = 0, mm = 0, tt = 0;
  std::vector<std::pair<cv::Mat, cv::Mat>> pairs;
  for (const auto& hv : {std::pair{30.0, 25.0}, {-50.0, 15.0}, {10.0, 35.0}, {65.0, 20.0}}) {
    const Vec3 l = LightDirection(hv.first, hv.second);
    pairs.push_back({scene->Brdf(l), (*model)->EvaluateRho(l)});
    tm += pairs.back().first.dot(pairs.back().second);
    mm += pairs.back().second.dot(pairs.back().second);
    tt += pairs.back().first.dot(pairs.back().first);
  }
  const double s = tm / mm;
  double se = 0;
  for (const auto& [t, f] : pairs) {
    const cv::Mat d = f * s - t;
    se += d.dot(d);
  }
  return std::sqrt(se / tt);
}

// `rig fit --lp` with a near lamp in --config's [light_frame]: every sample divided by its
// pixel's fall-off (sRGB codes decoded, corrected, re-encoded), recorded in the model, and the
// PCA model relights closer to the far-lamp truth than without.
TEST(NearLampLp, AnLpFitDividesTheSamplesByTheirFalloff) {
  const std::string dir = testing::FreshTempDir("near_lamp_lp");
  double scale = 0;
  const std::string near_lp = WriteNearLampLp(dir + "/near", 300, &scale);
  const std::string far_lp = WriteNearLampLp(dir + "/far", 0, &scale);
  const std::string near_cfg = testing::WriteSimConfig(
      dir, "[light_frame]\nlamp_distance_mm = 300\nfield_height_mm = 100\n");
  fs::rename(near_cfg, dir + "/near.toml");
  const std::string depth_cfg = testing::WriteSimConfig(
      dir, "[light_frame]\nlamp_distance_mm = 300\nfield_height_mm = 100\nsurface_depth_mm = -50\n");
  fs::rename(depth_cfg, dir + "/depth.toml");
  SimConfig sim;
  sim.scene = "matte";
  sim.width = 96;
  sim.height = 72;
  sim.field_height_mm = 100;
  struct Run {
    std::string name, lp, config, family;
    double error = 0;
  };
  std::vector<Run> runs;
  for (const std::string family : {"pca", "hsh", "ptm"})
    for (const auto& [name, lp, config] :
         std::vector<std::tuple<std::string, std::string, std::string>>{
             {"the simulator's lamp far (floor)", far_lp, ""},
             {"lamp 300 mm, far assumption", near_lp, ""},
             {"lamp 300 mm, fall-off divided, z = 0", near_lp, dir + "/near.toml"},
             {"lamp 300 mm, fall-off divided, surface_depth_mm = -50", near_lp, dir + "/depth.toml"}}) {
      const std::string out =
          dir + "/" + family + std::to_string(runs.size()) + (family == "pca" ? "" : ".exr");
      auto r = RunRig("fit --lp " + lp + " --basis " + family + " --out " + out +
                      (config.empty() ? "" : " --config " + config));
      EXPECT_EQ(r.status, 0) << r.output;
      EXPECT_EQ(r.output.find("near lamp") != std::string::npos, !config.empty()) << r.output;
      if (!config.empty() && family == "pca") {
        const auto info = nlohmann::json::parse(testing::ReadText(out + "/info.json"));
        EXPECT_NE(info["rig"].value("near_lamp", std::string()).find("divided by their fall-off"),
                  std::string::npos);
      } else if (!config.empty()) {
        auto header = ReadExr(out);
        ASSERT_TRUE(header.ok());
        EXPECT_TRUE(header->attributes.count("near_lamp"));
      }
      runs.push_back({name, lp, config, family, RelitErrorOfFamily(out, sim)});
    }
  for (const Run& r : runs)
    std::printf("rig fit --lp --basis %s, %s: relit relative RMS %.4f\n", r.family.c_str(),
                r.name.c_str(), r.error);
  // Rows per family: the floor, the far assumption, divided (z = 0), divided (plane given).
  // The fall-off divided relights closer to the far lamp's truth than the far assumption
  // (PCA by most; hsh and ptm, whose floors are higher here, by less), never below the floor.
  ASSERT_EQ(runs.size(), 12u);
  EXPECT_LT(runs[2].error, 0.85 * runs[1].error);
  for (size_t f = 0; f < 3; ++f) {
    EXPECT_LT(runs[4 * f + 2].error, 0.9 * runs[4 * f + 1].error) << runs[4 * f].family;
    EXPECT_LT(runs[4 * f + 3].error, 0.9 * runs[4 * f + 1].error) << runs[4 * f].family;
    EXPECT_LT(runs[4 * f].error, runs[4 * f + 2].error) << runs[4 * f].family;
  }
  fs::remove_all(dir);
}

// The largest difference between two models' coefficients (infinity: not comparable).
double CoefficientDifference(const fs::path& a, const fs::path& b) {
  auto ma = LoadModel(a.string());
  auto mb = LoadModel(b.string());
  EXPECT_TRUE(ma.ok() && mb.ok());
  if (!ma.ok() || !mb.ok() || ma->coefficients().size() != mb->coefficients().size())
    return std::numeric_limits<double>::infinity();
  double worst = 0;
  for (size_t t = 0; t < ma->coefficients().size(); ++t)
    worst = std::max(worst, cv::norm(ma->coefficients()[t], mb->coefficients()[t], cv::NORM_INF));
  return worst;
}

// `rig fit --list` of a near-lamp session's maps with its configuration fits as the session
// does (fall-off, tiles: the same model, in memory or streamed), and better than the far
// assumption on the same maps.
TEST(NearLampSession, AListFitOfTheMapsIsTheSessionsFit) {
  const std::string dir = testing::FreshTempDir("near_lamp_list");
  const std::string cfg = testing::WriteSimConfig(
      dir,
      "[sim]\nwidth = 96\nheight = 72\nscene = \"matte\"\nlamp_distance_mm = 300\n"
      "field_height_mm = 100\n[light_frame]\nlamp_distance_mm = 300\nfield_height_mm = 100\n"
      "surface_depth_mm = -50\n");
  const fs::path s = fs::path(dir) / "S";
  auto r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  auto session = Session::OpenExisting(s);
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  const Config& config = session->config();
  {
    std::ofstream list(fs::path(dir) / "maps.txt");
    for (const Pose& p : PlanGrid(config.grid))
      list << (s / "hdr" / (p.Name() + ".exr")).string() << " " << p.h_deg << " " << p.v_deg << "\n";
  }
  const std::string list = (fs::path(dir) / "maps.txt").string();
  const std::string session_toml = (s / "session.toml").string();
  const fs::path in_memory = fs::path(dir) / "list.exr", streamed = fs::path(dir) / "streamed.exr";
  r = RunRig("fit --list " + list + " --config " + session_toml + " --out " + in_memory.string() +
             " --report " + dir + "/report.md");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("near lamp 300 mm, surface at z = -50 mm"), std::string::npos) << r.output;
  EXPECT_NE(testing::ReadText(dir + "/report.md").find("| order |"), std::string::npos);
  r = RunRig("fit --list " + list + " --config " + session_toml + " --out " + streamed.string() +
             " --stream-above-mb 0");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("(streamed)"), std::string::npos) << r.output;
  auto header = ReadExr(in_memory.string());
  ASSERT_TRUE(header.ok()) << header.error().ToString();
  ASSERT_TRUE(header->attributes.count("near_lamp"));
  EXPECT_EQ(header->attributes.at("near_lamp"),
            ReadExr((s / "model" / "model.exr").string())->attributes.at("near_lamp"));
  // The same model as the session's, and in memory as streamed.
  EXPECT_EQ(CoefficientDifference(in_memory, streamed), 0.0);
  EXPECT_EQ(CoefficientDifference(in_memory, s / "model" / "model.exr"), 0.0);

  // The far assumption on the same maps: a configuration without the lamp's distance.
  Config far_config = config;
  far_config.light_frame.lamp_distance_mm = 0;
  far_config.light_frame.surface_depth_mm = 0;
  {
    std::ofstream f(fs::path(dir) / "far.toml");
    f << ToToml(far_config);
  }
  const fs::path far = fs::path(dir) / "far.exr";
  r = RunRig("fit --list " + list + " --config " + dir + "/far.toml --out " + far.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output.find("near lamp"), std::string::npos) << r.output;
  const double near_error = RelitError(in_memory, config), far_error = RelitError(far, config);
  std::printf("rig fit --list of the session's maps, 96x72: relit relative RMS far assumption "
              "%.4f, near lamp (surface_depth_mm = -50) %.4f\n", far_error, near_error);
  EXPECT_LT(near_error, 0.85 * far_error);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig
