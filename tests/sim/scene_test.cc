// The simulator's scene and ground truth: exact BRDF properties, determinism, truth files.
#include "sim/scene.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include <gtest/gtest.h>

#include "process/io/exr_io.h"
#include "process/model/light_direction.h"
#include "sim/truth.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

SimScene MakeScene(const std::string& kind, int seed = 1, int w = 160, int h = 120) {
  SimConfig sim;
  sim.scene = kind;
  sim.seed = seed;
  sim.width = w;
  sim.height = h;
  auto s = SimScene::Create(sim);
  EXPECT_TRUE(s.ok()) << s.error().ToString();
  return std::move(s).value();
}

double Dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

Vec3 NormalAt(const cv::Mat& normals, int i, int j) {
  const auto& n = normals.at<cv::Vec3f>(j, i);
  return {n[0], n[1], n[2]};
}

// Light directions on the rig's grid and off it (also behind the object: h up to 170).
std::vector<Vec3> SomeDirections() {
  std::vector<Vec3> dirs;
  for (double h = -40; h <= 170; h += 23)
    for (double v = -20; v <= 70; v += 17) dirs.push_back(LightDirection(h, v));
  return dirs;
}

TEST(SimScene, UnknownSceneIsRefusedNamingTheKey) {
  SimConfig sim;
  sim.scene = "shiny";
  auto s = SimScene::Create(sim);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidInput);
  EXPECT_NE(s.error().ToString().find("sim.scene"), std::string::npos);
}

TEST(SimScene, SameSeedGivesIdenticalBrdfAndAnotherSeedAnotherTexture) {
  const Vec3 l = LightDirection(30, 10);
  cv::Mat a = MakeScene("full", 1).Brdf(l), b = MakeScene("full", 1).Brdf(l);
  cv::Mat c = MakeScene("full", 2).Brdf(l);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_L1) / cv::norm(a, cv::NORM_L1), 0.01);
}

TEST(SimScene, RadianceIsBrdfTimesLampRadiancePerChannel) {
  SimScene s = MakeScene("full");
  const Vec3 l = LightDirection(50, 20);
  cv::Mat rho = s.Brdf(l);
  cv::Mat rad = s.Radiance(l, {2.0, 0.5, 1.5});  // R, G, B
  const double lamp_bgr[3] = {1.5, 0.5, 2.0};
  double max_rel = 0;
  int lit = 0;
  for (int j = 0; j < rho.rows; ++j)
    for (int i = 0; i < rho.cols; ++i)
      for (int c = 0; c < 3; ++c) {
        double want = rho.at<cv::Vec3f>(j, i)[c] * lamp_bgr[c];
        double got = rad.at<cv::Vec3f>(j, i)[c];
        if (want == 0) {
          EXPECT_EQ(got, 0.0);
          continue;
        }
        ++lit;
        max_rel = std::max(max_rel, std::fabs(got / want - 1));
      }
  EXPECT_GT(lit, rho.rows * rho.cols);  // most pixels are lit from there
  EXPECT_LT(max_rel, 1e-6);
}

TEST(SimScene, ImageBrdfAgreesWithDoublePrecisionPixelBrdf) {
  SimScene s = MakeScene("full");
  for (const Vec3& l : SomeDirections()) {
    cv::Mat rho = s.Brdf(l);
    for (int j = 3; j < s.height(); j += 7)
      for (int i = 5; i < s.width(); i += 11) {
        auto want = s.BrdfAt(i, j, l);
        for (int c = 0; c < 3; ++c)
          ASSERT_NEAR(rho.at<cv::Vec3f>(j, i)[c], want[c], 1e-4 * want[c] + 1e-3)
              << i << "," << j;
      }
  }
}

TEST(SimScene, MatteSceneIsLambertianWithAttachedShadowsInEveryDirection) {
  SimScene s = MakeScene("matte");
  cv::Mat normals = s.Normals(), albedo = s.Albedo();
  int lit = 0, dark = 0;
  for (const Vec3& l : SomeDirections()) {
    cv::Mat rho = s.Brdf(l);
    for (int j = 0; j < s.height(); j += 3)
      for (int i = 0; i < s.width(); i += 3) {
        const double ndl = Dot(NormalAt(normals, i, j), l);
        for (int c = 0; c < 3; ++c) {
          const double r = rho.at<cv::Vec3f>(j, i)[c];
          if (ndl <= 0) {
            ASSERT_EQ(r, 0.0) << "attached shadow at " << i << "," << j;
            ++dark;
          } else if (ndl > 1e-3) {
            // rho / cos = the constant Lambertian BRDF scale * albedo / pi.
            const double f = s.radiance_scale() * albedo.at<cv::Vec3f>(j, i)[c] / std::numbers::pi;
            ASSERT_NEAR(r / ndl, f, 1e-5 * f) << i << "," << j;
            ++lit;
          }
        }
      }
  }
  EXPECT_GT(lit, 10000);
  EXPECT_GT(dark, 1000);
}

TEST(SimScene, SharpGlossPeaksAtTheMirrorDirection) {
  SimScene s = MakeScene("sharp", 1, 320, 240);
  cv::Mat normals = s.Normals(), ids = s.MaterialIds(), albedo = s.Albedo();
  int checked = 0;
  // Sphere pixels whose normal leans 10 .. 35 degrees from the view direction.
  for (int j = 20; j < s.height(); j += 23) {
    for (int i = 20; i < s.width(); i += 19) {
      if (ids.at<uint8_t>(j, i) != static_cast<uint8_t>(SimMaterialId::kSphere)) continue;
      const Vec3 n = NormalAt(normals, i, j);
      if (n[2] > std::cos(10 * std::numbers::pi / 180) || n[2] < std::cos(35 * std::numbers::pi / 180))
        continue;
      const Vec3 mirror = {2 * n[2] * n[0], 2 * n[2] * n[1], 2 * n[2] * n[2] - 1};
      double mh, mv;
      DirectionToAngles(mirror, &mh, &mv);
      // Scan a 0.25-degree grid of directions +-20 degrees around the mirror direction.
      double best = -1, best_h = 0, best_v = 0;
      for (double dh = -20; dh <= 20; dh += 0.25)
        for (double dv = -20; dv <= 20; dv += 0.25) {
          double r = s.BrdfAt(i, j, LightDirection(mh + dh, mv + dv))[1];
          if (r > best) best = r, best_h = mh + dh, best_v = mv + dv;
        }
      const double angle_deg =
          std::acos(std::clamp(Dot(LightDirection(best_h, best_v), mirror), -1.0, 1.0)) * 180 /
          std::numbers::pi;
      EXPECT_LT(angle_deg, 1.5) << i << "," << j;
      // The glossy part alone (rho minus the Lambertian part): 20 degrees off the mirror
      // direction (10 degrees off the half vector) it has fallen by (cos 10)^300 ~ 1/100.
      auto lobe = [&](const Vec3& l) {
        const double lambert = s.radiance_scale() * albedo.at<cv::Vec3f>(j, i)[1] /
                               std::numbers::pi * std::max(0.0, Dot(n, l));
        return s.BrdfAt(i, j, l)[1] - lambert;
      };
      // 20 degrees away from the mirror direction, towards the view axis (so still lit).
      const Vec3 z = {0, 0, 1};
      Vec3 u = {z[0] - Dot(z, mirror) * mirror[0], z[1] - Dot(z, mirror) * mirror[1],
                z[2] - Dot(z, mirror) * mirror[2]};
      const double un = std::sqrt(Dot(u, u));
      for (double& c : u) c /= un;
      const double a = 20 * std::numbers::pi / 180;
      const Vec3 off = {std::cos(a) * mirror[0] + std::sin(a) * u[0],
                        std::cos(a) * mirror[1] + std::sin(a) * u[1],
                        std::cos(a) * mirror[2] + std::sin(a) * u[2]};
      EXPECT_GT(lobe(mirror), 50 * lobe(off)) << i << "," << j;
      // At the mirror direction N.H = 1: the lobe is scale * ks (n + 8) / (8 pi) * N.L.
      const nlohmann::json description = s.Describe();
      const auto& mat = description["materials"][1];
      const double ks = mat["ks"], shin = mat["shininess"];
      EXPECT_NEAR(lobe(mirror),
                  s.radiance_scale() * ks * (shin + 8) / (8 * std::numbers::pi) * n[2],
                  1e-4 * lobe(mirror));
      ++checked;
    }
  }
  EXPECT_GE(checked, 10);
}

TEST(SimScene, FullSceneCastsTheSphereShadowAndCarriesTheRelief) {
  const Vec3 l = LightDirection(40, 10);
  auto shadowed_facing = [&](const SimScene& s) {
    cv::Mat rho = s.Brdf(l), normals = s.Normals(), ids = s.MaterialIds();
    int n = 0;
    for (int j = 0; j < s.height(); ++j)
      for (int i = 0; i < s.width(); ++i)
        if (ids.at<uint8_t>(j, i) != static_cast<uint8_t>(SimMaterialId::kSphere) &&
            Dot(NormalAt(normals, i, j), l) > 0.2 && rho.at<cv::Vec3f>(j, i)[1] == 0)
          ++n;
    return n;
  };
  SimScene full = MakeScene("full"), gloss = MakeScene("gloss");
  EXPECT_GT(shadowed_facing(full), 500);
  EXPECT_EQ(shadowed_facing(gloss), 0);
  auto relief = [](const SimScene& s) {
    cv::Mat ids = s.MaterialIds();
    return cv::countNonZero(ids == static_cast<uint8_t>(SimMaterialId::kRelief));
  };
  EXPECT_GT(relief(full), 1000);
  EXPECT_EQ(relief(gloss), 0);
}

TEST(SimTruth, WritesResponseRadianceAndSceneAndLoadsTheSceneBack) {
  Config config;
  config.sim.width = 64;
  config.sim.height = 48;
  config.grid.h_max_deg = 20;
  config.grid.v_max_deg = 10;  // 3 x 2 poses
  config.lamp.radiance_rgb = {1.0, 2.0, 0.5};
  config.light_frame.h_offset_deg = 5;
  const std::string dir = testing::FreshTempDir("sim_truth") + "/truth";
  Status st = WriteTruth(dir, config);
  ASSERT_TRUE(st.ok()) << st.error().ToString();

  auto scene = SimScene::Create(config.sim);
  auto response = SimResponse::Create(config.sim.camera);
  ASSERT_TRUE(scene.ok() && response.ok());

  std::ifstream csv(dir + "/response.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "level,g_B,g_G,g_R");
  int rows = 0;
  while (std::getline(csv, line)) {
    int z;
    double g[3];
    ASSERT_EQ(std::sscanf(line.c_str(), "%d,%lf,%lf,%lf", &z, &g[0], &g[1], &g[2]), 4) << line;
    EXPECT_EQ(z, rows);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(g[c], response->LogExposure(c, z), 1e-7);
    ++rows;
  }
  EXPECT_EQ(rows, 256);

  int exrs = 0;
  for (const Pose& p : PlanGrid(config.grid)) {
    std::map<std::string, std::string> attrs;
    auto img = ReadRgbExr(dir + "/radiance/" + p.Name() + ".exr", &attrs);
    ASSERT_TRUE(img.ok()) << img.error().ToString();
    cv::Mat want = scene->Radiance(LightDirection(p.h_deg, p.v_deg, config.light_frame),
                                   config.lamp.radiance_rgb);
    EXPECT_EQ(cv::norm(*img, want, cv::NORM_INF), 0.0) << p.Name();
    EXPECT_EQ(attrs["pose"], p.Name());
    ++exrs;
  }
  EXPECT_EQ(exrs, 6);

  auto truth = LoadTruth(dir);
  ASSERT_TRUE(truth.ok()) << truth.error().ToString();
  EXPECT_EQ(truth->poses.size(), 6u);
  EXPECT_EQ(truth->lamp_radiance_rgb[1], 2.0);
  EXPECT_EQ(truth->light_frame.h_offset_deg, 5);
  // The exact BRDF at an off-grid direction, from the truth alone.
  cv::Mat got = truth->BrdfAtAngles(37.5, 21.25);
  cv::Mat want = scene->Brdf(LightDirection(37.5, 21.25, config.light_frame));
  EXPECT_EQ(cv::norm(got, want, cv::NORM_INF), 0.0);
  for (int z = 0; z < 256; z += 17)
    EXPECT_EQ(truth->response.LogExposure(2, z), response->LogExposure(2, z));
  auto only_scene = LoadTruthScene(dir);
  ASSERT_TRUE(only_scene.ok());
  EXPECT_EQ(only_scene->kind(), "full");
}

TEST(SimTruth, SceneJsonThatDoesNotMatchTheSimulatorIsCorrupt) {
  Config config;
  config.sim.width = 32;
  config.sim.height = 24;
  config.grid.h_max_deg = 0;
  config.grid.v_max_deg = 0;
  const std::string dir = testing::FreshTempDir("sim_truth_bad") + "/truth";
  ASSERT_TRUE(WriteTruth(dir, config).ok());
  std::ifstream in(dir + "/scene.json");
  std::stringstream ss;
  ss << in.rdbuf();
  auto j = nlohmann::json::parse(ss.str());
  j["scene"]["sphere"]["radius"] = 0.5;
  std::ofstream(dir + "/scene.json") << j.dump();
  auto truth = LoadTruth(dir);
  ASSERT_FALSE(truth.ok());
  EXPECT_EQ(truth.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(truth.error().ToString().find("scene.json"), std::string::npos);
  auto missing = LoadTruth(dir + "/nowhere");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
}

}  // namespace
}  // namespace rig
