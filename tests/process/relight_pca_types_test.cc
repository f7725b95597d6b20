// relight's PCA types read: rbf (its default), bilinear, and their mycc forms yrbf and ybilinear.
// Hand-made folders of known bases and planes, rendered as relight's renderer renders them
// (Rti::render, Rti::lightWeightsRbf/Bilinear, Color3::toRgb; the facts of
// ../shared/docs/rti-formats.md), the expected values written out here the way relight's
// renderer loops (per plane, per channel, weights then YCoCg), not the folded form the reader
// uses; `rig render` of the folders within 1 DN of that; refusals that list what is read.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "process/export/load_any.h"
#include "process/export/relight_files.h"
#include "process/io/jpeg_io.h"
#include "process/model/pca/pca.h"
#include "tests/support/relight_pca_folder.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string Temp(const std::string& name) {
  static const std::string dir = testing::FreshTempDir("relight-pca-types");
  return dir + "/" + name;
}

using testing::Folder;
using testing::kH;
using testing::kW;
using testing::RelightRender;

Folder MakeFolder(const std::string& name, bool rbf, bool ycc, uint32_t seed) {
  return testing::MakeRelightPcaFolder(Temp(name), rbf, ycc, seed);
}

std::vector<Vec3> Directions() {
  return {{0, 0, 1}, {0.3, -0.2, 0.93}, {-0.6, 0.5, 0.62}, {0.85, 0.1, 0.5}, {0.05, -0.9, 0.43}};
}

TEST(RelightPcaTypes, EachTypeRendersAsRelightsRenderer) {
  uint32_t seed = 7;
  for (bool rbf : {true, false})
    for (bool ycc : {false, true}) {
      const std::string type = std::string(ycc ? "y" : "") + (rbf ? "rbf" : "bilinear");
      const Folder f = MakeFolder(type, rbf, ycc, seed++);
      auto m = PcaModel::Load(f.dir);
      ASSERT_TRUE(m.ok()) << type << ": " << m.error().ToString();
      EXPECT_EQ(m->relight_type(), type);
      EXPECT_EQ(m->components(), f.nplanes);
      double worst = 0;
      for (const Vec3& d : Directions()) {
        const cv::Mat v = m->Render(d);  // B, G, R in code / 255
        for (int y : {0, 7, 15})
          for (int x : {0, 11, 23}) {
            const cv::Vec3d want = RelightRender(f, d, x, y);
            for (int k = 0; k < 3; ++k)
              worst = std::max(worst, std::abs(255.0 * v.at<cv::Vec3f>(y, x)[2 - k] - want[k]));
          }
      }
      // float sums of ~10 terms in 0..255 units against the same sums in double
      EXPECT_LT(worst, 1e-2) << type;
    }
}

// The family's mycc interleaving matters: the same folder read as mrgb renders differently.
TEST(RelightPcaTypes, MyccIsNotMrgb) {
  Folder f = MakeFolder("mycc-vs-mrgb", true, true, 40);
  auto ycc = PcaModel::Load(f.dir);
  ASSERT_TRUE(ycc.ok()) << ycc.error().ToString();
  nlohmann::json as_mrgb = f.info;
  as_mrgb["colorspace"] = "mrgb";
  as_mrgb.erase("yccplanes");
  as_mrgb["nplanes"] = f.nplanes;
  std::ofstream(f.dir + "/info.json") << as_mrgb.dump();
  auto mrgb = PcaModel::Load(f.dir);
  ASSERT_TRUE(mrgb.ok()) << mrgb.error().ToString();
  const cv::Mat a = ycc->Render({0.3, -0.2, 0.93}), b = mrgb->Render({0.3, -0.2, 0.93});
  EXPECT_GT(cv::norm(a, b, cv::NORM_INF), 5.0 / 255);
}

// Saved again, each type is written as itself and reads back to the same renders.
TEST(RelightPcaTypes, SavedAsItsOwnType) {
  Folder f = MakeFolder("save-yrbf", true, true, 50);
  auto m = PcaModel::Load(f.dir);
  ASSERT_TRUE(m.ok()) << m.error().ToString();
  const std::string out = Temp("save-yrbf-again");
  ASSERT_TRUE(m->Save(out).ok());
  const auto info = nlohmann::json::parse(testing::ReadText(out + "/info.json"));
  EXPECT_EQ(info["type"], "rbf");
  EXPECT_EQ(info["colorspace"], "mycc");
  EXPECT_EQ(info["yccplanes"], f.info["yccplanes"]);
  EXPECT_EQ(info["sigma"], 0.35);
  EXPECT_FALSE(info.contains("nplanes"));
  auto back = PcaModel::Load(out);
  ASSERT_TRUE(back.ok()) << back.error().ToString();
  // The planes were JPEG-encoded a second time: within a few codes, not bit for bit.
  EXPECT_LT(cv::norm(m->Render({0.2, 0.1, 0.97}), back->Render({0.2, 0.1, 0.97}), cv::NORM_INF), 4.0 / 255);
  EXPECT_EQ(back->basis().rbf_lights.size(), f.lights.size());
  auto names = DeclaredWebFiles(out);
  ASSERT_TRUE(names.ok()) << names.error().ToString();
  EXPECT_EQ(names->size(), 1u + (f.nplanes + 2) / 3);
}

// `rig render` of each folder: the PNG within 1 DN of relight's render (which truncates to
// an int and clips to 0..255).
TEST(RelightPcaTypes, RigRenderMatchesRelightWithinOneCode) {
  uint32_t seed = 60;
  for (bool rbf : {true, false})
    for (bool ycc : {false, true}) {
      const std::string type = std::string(ycc ? "y" : "") + (rbf ? "rbf" : "bilinear");
      const Folder f = MakeFolder("render-" + type, rbf, ycc, seed++);
      const Vec3 d{-0.6, 0.5, 0.62};
      const std::string png = Temp("render-" + type + ".png");
      auto r = testing::RunRig("render " + f.dir + " --light dir=-0.6,0.5,0.62 --out " + png);
      ASSERT_EQ(r.status, 0) << r.output;
      const cv::Mat img = cv::imread(png, cv::IMREAD_UNCHANGED);
      ASSERT_EQ(img.type(), CV_8UC3) << type;
      int worst = 0;
      for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
          const cv::Vec3d want = RelightRender(f, d, x, y);
          for (int k = 0; k < 3; ++k) {
            const int relight = std::clamp(static_cast<int>(want[k]), 0, 255);
            worst = std::max(worst, std::abs(img.at<cv::Vec3b>(y, x)[2 - k] - relight));
          }
        }
      EXPECT_LE(worst, 1) << type << "\n" << r.output;
    }
}

TEST(RelightPcaTypes, RefusalsNameTheFieldAndListWhatIsRead) {
  Folder f = MakeFolder("refusals", true, true, 70);
  auto write = [&](const nlohmann::json& j) { std::ofstream(f.dir + "/info.json") << j.dump(); };
  nlohmann::json j = f.info;
  j["type"] = "dmd";
  write(j);
  auto m = LoadAnyModel(f.dir);
  ASSERT_FALSE(m.ok());
  EXPECT_THAT(m.error().ToString(), HasSubstr("info.json"));
  EXPECT_THAT(m.error().ToString(), HasSubstr("'dmd'"));
  EXPECT_THAT(m.error().ToString(), HasSubstr(kRelightTypesRead));
  j = f.info;
  j["sigma"] = "wide";
  write(j);
  m = LoadAnyModel(f.dir);
  ASSERT_FALSE(m.ok());
  EXPECT_THAT(m.error().ToString(), HasSubstr("sigma"));
  j = f.info;
  j["yccplanes"] = {4, 2, 1};
  write(j);
  m = LoadAnyModel(f.dir);
  ASSERT_FALSE(m.ok());
  EXPECT_THAT(m.error().ToString(), HasSubstr("yccplanes"));
  j = f.info;
  j["lights"] = {0.1, 0.2};
  write(j);
  m = LoadAnyModel(f.dir);
  ASSERT_FALSE(m.ok());
  EXPECT_THAT(m.error().ToString(), HasSubstr("lights"));
  j = f.info;
  j["basis"].erase(j["basis"].size() - 1);
  write(j);
  m = LoadAnyModel(f.dir);
  ASSERT_FALSE(m.ok());
  EXPECT_THAT(m.error().ToString(), HasSubstr("'basis'"));
}

}  // namespace
}  // namespace rig
