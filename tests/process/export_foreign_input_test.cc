// Foreign web-format folders that are truncated, of an unknown variant, or inconsistent: each
// refused by LoadAnyModel (what rig render, rig export and rig view read through) with the file
// and the field named, and by `rig view` with exit code 2. (.ptm / .rti: export_test.cc.)
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "process/export/load_any.h"
#include "process/export/relight_files.h"
#include "process/io/json_file.h"
#include "process/model/light_direction.h"
#include "process/model/pca/pca.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

RelightCoefficients SmallPtm() {
  RelightCoefficients c;
  c.type = RelightType::kPtm;
  c.terms = 6;
  c.width = 16;
  c.height = 8;
  for (int j = 0; j < 6; ++j) c.planes.push_back(cv::Mat(8, 16, CV_32FC3, cv::Scalar(10.0 * j, 20, 30)));
  return c;
}

// A copy of a good ptm web folder with info.json edited by `edit`.
std::string Edited(const std::string& good, const std::string& name,
                   const std::function<void(nlohmann::ordered_json&)>& edit) {
  const std::string dir = fs::path(good).parent_path() / name;
  fs::copy(good, dir, fs::copy_options::recursive);
  std::ifstream f(dir + "/info.json");
  auto info = nlohmann::ordered_json::parse(f);
  edit(info);
  std::ofstream(dir + "/info.json") << info.dump();
  return dir;
}

void ExpectRefused(const std::string& path, const std::string& file, const std::string& field,
                   const std::string& view_args = "") {
  auto m = LoadAnyModel(path);
  ASSERT_FALSE(m.ok()) << path;
  EXPECT_THAT(m.error().ToString(), HasSubstr(file));
  EXPECT_THAT(m.error().ToString(), HasSubstr(field));
  const auto r = testing::RunRig("view " + path + " --out " + path + "-view " + view_args);
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr(file));
  EXPECT_THAT(r.output, HasSubstr(field));
  EXPECT_FALSE(fs::exists(path + "-view")) << "nothing written for a refused model";
}

TEST(ExportForeignInput, WebFoldersTruncatedUnknownOrInconsistentAreRefusedNamingFileAndField) {
  const std::string root = testing::FreshTempDir("foreign");
  const std::string good = root + "/good";
  ASSERT_TRUE(WriteRelightWeb(good, SmallPtm(), WebWriteOptions{}).ok());
  ASSERT_TRUE(LoadAnyModel(good).ok());

  // truncated: info.json cut in half; a plane JPEG cut short
  {
    const std::string dir = root + "/cut-info";
    fs::copy(good, dir, fs::copy_options::recursive);
    fs::resize_file(dir + "/info.json", fs::file_size(dir + "/info.json") / 2);
    ExpectRefused(dir, dir + "/info.json", "not JSON");
  }
  {
    const std::string dir = root + "/cut-plane";
    fs::copy(good, dir, fs::copy_options::recursive);
    fs::resize_file(dir + "/plane_3.jpg", fs::file_size(dir + "/plane_3.jpg") / 2);
    ExpectRefused(dir, dir + "/plane_3.jpg", "");
    // tiled: the planes are not loaded whole; the tiler refuses the damaged one
    const auto r = testing::RunRig("view " + dir + " --tiles on --out " + dir + "-tiled");
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_THAT(r.output, HasSubstr(dir + "/plane_3.jpg"));
    EXPECT_FALSE(fs::exists(dir + "-tiled")) << "a failed rig view leaves nothing";
  }
  // unknown variants
  ExpectRefused(Edited(good, "ycc", [](auto& i) { i["colorspace"] = "ycc"; }), "info.json", "colorspace");
  ExpectRefused(Edited(good, "dmd", [](auto& i) { i["type"] = "dmd"; i["colorspace"] = "mrgb"; }),
                "info.json", "type 'dmd'");
  // relight's rbf is read now: one without its sigma (or its basis) is refused naming it
  ExpectRefused(Edited(good, "rbf", [](auto& i) { i["type"] = "rbf"; i["colorspace"] = "mrgb"; }),
                "info.json", "sigma");
  ExpectRefused(Edited(good, "png", [](auto& i) { i["format"] = "png"; }), "info.json", "format");
  // inconsistent: plane count against the type, scale/bias against nplanes, sizes against the planes
  ExpectRefused(Edited(good, "nplanes", [](auto& i) { i["nplanes"] = 27; }), "info.json", "nplanes");
  ExpectRefused(Edited(good, "scale", [](auto& i) { i["materials"][0]["scale"].erase(0); }), "info.json",
                "materials[0].scale");
  ExpectRefused(Edited(good, "width", [](auto& i) { i["width"] = 32; }), "plane_0.jpg", "info.json says 32x8");
  ExpectRefused(Edited(good, "lights", [](auto& i) { i["lights"] = {0.1, 0.2}; }), "info.json", "lights");
  {
    const std::string dir = root + "/missing-plane";
    fs::copy(good, dir, fs::copy_options::recursive);
    fs::remove(dir + "/plane_5.jpg");
    ExpectRefused(dir, dir + "/plane_5.jpg", "");
  }
}

TEST(ExportForeignInput, BilinearFoldersWithInconsistentBasisOrMaterialsAreRefused) {
  const std::string root = testing::FreshTempDir("foreign-pca");
  // A small PCA model, fitted to a synthetic capture.
  LightSamples s;
  s.width = 12;
  s.height = 8;
  for (double v = 10; v <= 70; v += 30)
    for (double h = 0; h < 360; h += 45) s.directions.push_back(LightDirection(h, v));
  s.values.resize(s.pixels() * s.directions.size() * 3);
  for (size_t i = 0; i < s.values.size(); ++i) s.values[i] = static_cast<uint8_t>(40 + (i * 37) % 180);
  PcaOptions o;
  o.components = 3;
  o.grid_resolution = 4;
  auto m = FitPca(s, o);
  ASSERT_TRUE(m.ok()) << m.error().ToString();
  const std::string good = root + "/good";
  ASSERT_TRUE(m->Save(good).ok());
  ASSERT_TRUE(LoadAnyModel(good).ok());
  ExpectRefused(Edited(good, "basis", [](auto& i) { i["basis"].erase(0); }), "info.json", "'basis'");
  ExpectRefused(Edited(good, "range", [](auto& i) { i["materials"][0]["range"].erase(0); }), "info.json",
                "materials");
  ExpectRefused(Edited(good, "resolution", [](auto& i) { i.erase("resolution"); }), "info.json", "resolution");
  // mycc is read now (ybilinear, yrbf): without its yccplanes it is refused naming them
  ExpectRefused(Edited(good, "mycc", [](auto& i) { i["colorspace"] = "mycc"; }), "info.json", "yccplanes");
}

TEST(ExportForeignInput, AnInfoJsonThatIsAFifoOrHugeIsRefusedAtOnceNotRead) {
  const std::string root = testing::FreshTempDir("foreign-fifo");
  const std::string good = root + "/good";
  ASSERT_TRUE(WriteRelightWeb(good, SmallPtm(), WebWriteOptions{}).ok());
  // A FIFO named info.json: a reader that opened it blocking would wait for a writer forever.
  const std::string fifo = root + "/fifo";
  fs::copy(good, fifo, fs::copy_options::recursive);
  fs::remove(fifo + "/info.json");
  ASSERT_EQ(::mkfifo((fifo + "/info.json").c_str(), 0644), 0);
  const auto t0 = std::chrono::steady_clock::now();
  auto m = LoadAnyModel(fifo);
  ASSERT_FALSE(m.ok());
  EXPECT_THAT(m.error().ToString(), HasSubstr("info.json"));
  EXPECT_THAT(m.error().ToString(), HasSubstr("not a regular file"));
  auto declared = DeclaredWebFiles(fifo);
  ASSERT_FALSE(declared.ok());
  EXPECT_THAT(declared.error().ToString(), HasSubstr("not a regular file"));
  EXPECT_EQ(RelightWebType(fifo), "");
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
  // One larger than any model's info.json: refused on its size, before it is read.
  const std::string huge = root + "/huge";
  fs::copy(good, huge, fs::copy_options::recursive);
  fs::resize_file(huge + "/info.json", kMaxJsonFileBytes + 1);
  auto h = LoadAnyModel(huge);
  ASSERT_FALSE(h.ok());
  EXPECT_THAT(h.error().ToString(), HasSubstr("larger than"));
}

}  // namespace
}  // namespace rig
