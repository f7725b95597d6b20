// Every output written safely (issue 30, items 8-11), through the real `rig` binary: links
// planted in --out and at temporary-like names never lead a write outside; `rig fit --lp`
// killed over an earlier model leaves the old model or the new one, never a mix; rig view and
// rig export copy only the planes a model declares and refuse a linked one; overflowing
// scale/bias and a declared size the files cannot hold are refused (exit 2, naming the field
// or file) before anything large is allocated.
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/support/lp_capture.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

std::set<std::string> Names(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.insert(e.path().filename().string());
  return names;
}

// One capture and one PCA model (48x36) for the whole suite.
class Outputs : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::FreshTempDir("outputs"));
    lp_ = new std::string(testing::WriteLpCapture(*dir_, 48, 36));
    auto r = RunRig("fit --lp " + *lp_ + " --max-bytes-per-pixel 40 --out " + *dir_ + "/model");
    ASSERT_EQ(r.status, 0) << r.output;
    r = RunRig("export " + *dir_ + "/model --format relight --basis hsh --out " + *dir_ + "/hsh");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    delete lp_;
  }
  // A copy of a suite model to damage.
  static fs::path CopyOf(const std::string& name, const std::string& as) {
    const fs::path to = fs::path(*dir_) / as;
    fs::remove_all(to);
    fs::copy(fs::path(*dir_) / name, to, fs::copy_options::recursive);
    return to;
  }
  static nlohmann::json Info(const fs::path& folder) {
    return nlohmann::json::parse(testing::ReadText((folder / "info.json").string()));
  }
  static void PutInfo(const fs::path& folder, const nlohmann::json& info) {
    std::ofstream(folder / "info.json") << info.dump();
  }
  static inline std::string* dir_ = nullptr;
  static inline std::string* lp_ = nullptr;
};

TEST_F(Outputs, LinksPlantedInTheOutputFolderAndAtTemporaryNamesLeadNowhere) {
  const fs::path d = fs::path(*dir_) / "planted";
  fs::create_directories(d);
  const fs::path outside = d / "someone-elses.txt";
  std::ofstream(outside) << "precious";
  // In an existing --out of rig fit: a plane and the old fixed temporary name as links.
  fs::create_directories(d / "m");
  fs::create_symlink(outside, d / "m" / "plane_0.jpg");
  fs::create_symlink(outside, d / "m" / ".info.json.tmp");
  auto r = RunRig("fit --lp " + *lp_ + " --out " + (d / "m").string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr((d / "m").string()));
  EXPECT_THAT(r.output, HasSubstr("refusing to replace"));
  // The export's old fixed temporary names, beside a .ptm and an .rti.
  for (const char* name : {"x.ptm.tmp", ".x.ptm.tmp", "x.rti.tmp", ".x.rti.tmp"})
    fs::create_symlink(outside, d / name);
  r = RunRig("export " + *dir_ + "/model --format ptm --out " + (d / "x.ptm").string());
  EXPECT_EQ(r.status, 0) << r.output;
  r = RunRig("export " + *dir_ + "/model --format rti --out " + (d / "x.rti").string());
  EXPECT_EQ(r.status, 0) << r.output;
  // --out of rig render as a link: refused (nothing is overwritten), never written through.
  fs::create_symlink(outside, d / "r.png");
  r = RunRig("render " + *dir_ + "/model --light 45,20 --out " + (d / "r.png").string());
  EXPECT_EQ(r.status, 2) << r.output;
  // rig hdr's --out as a link: replaced by the map, never followed.
  fs::create_symlink(outside, d / "h.exr");
  std::ofstream(d / "list.txt") << *dir_ << "/img0.jpg 0.01\n" << *dir_ << "/img1.jpg 0.04\n";
  r = RunRig("hdr --list " + (d / "list.txt").string() + " --out " + (d / "h.exr").string());
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_FALSE(fs::is_symlink(fs::symlink_status(d / "h.exr")));
  EXPECT_EQ(testing::ReadText(outside.string()), "precious");
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(d / "m" / "plane_0.jpg")));  // left as it was
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(d / "x.ptm.tmp")));  // never written through
}

TEST_F(Outputs, AnOutputFolderHoldingOtherFilesIsRefusedAndAModelFolderReplacedWhole) {
  const fs::path m = CopyOf("model", "whole");
  std::ofstream(m / "notes.txt") << "mine";
  auto r = RunRig("fit --lp " + *lp_ + " --max-bytes-per-pixel 10 --out " + m.string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("notes.txt"));
  EXPECT_EQ(testing::ReadText((m / "notes.txt").string()), "mine");
  fs::remove(m / "notes.txt");
  // An extra plane of an earlier, larger model: replaced with the rest.
  fs::copy_file(m / "plane_0.jpg", m / "plane_9.jpg");
  r = RunRig("fit --lp " + *lp_ + " --max-bytes-per-pixel 10 --out " + m.string());
  ASSERT_EQ(r.status, 0) << r.output;
  const int files = (Info(m)["nplanes"].get<int>() + 2) / 3;
  std::set<std::string> want = {"info.json"};
  for (int j = 0; j < files; ++j) want.insert("plane_" + std::to_string(j) + ".jpg");
  EXPECT_EQ(Names(m), want);
}

// SIGKILL at random moments of `rig fit --lp` over an earlier model: the folder always holds
// exactly the old model or exactly the new one, and rig render reads it.
TEST_F(Outputs, FitKilledOverAnEarlierModelLeavesTheOldOrTheNewNeverAMix) {
  const fs::path m = CopyOf("model", "killed");
  const std::string old_info = testing::ReadText((m / "info.json").string());
  const std::set<std::string> old_names = Names(m);
  const std::vector<std::string> args = {"fit", "--lp", *lp_, "--max-bytes-per-pixel", "10",
                                         "--out", m.string()};
  const std::string log = *dir_ + "/kill-log.txt";
  // How long a whole fit takes: the kills fall inside it.
  auto t0 = std::chrono::steady_clock::now();
  const fs::path fresh = fs::path(*dir_) / "fresh";
  auto r = RunRig("fit --lp " + *lp_ + " --max-bytes-per-pixel 10 --out " + fresh.string());
  ASSERT_EQ(r.status, 0) << r.output;
  const double whole_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::string new_info = testing::ReadText((fresh / "info.json").string());
  ASSERT_NE(old_info, new_info);
  const std::set<std::string> new_names = Names(fresh);
  std::mt19937 rng(30);
  int saw_old = 0, saw_new = 0;
  for (int round = 0; round < 6; ++round) {
    const pid_t pid = testing::SpawnRig(args, log);
    ASSERT_GT(pid, 0);
    std::this_thread::sleep_for(std::chrono::duration<double>(
        std::uniform_real_distribution<double>(0.1, 1.0)(rng) * whole_s));
    ::kill(pid, SIGKILL);
    testing::WaitRig(pid);
    const std::string info = testing::ReadText((m / "info.json").string());
    const std::set<std::string> names = Names(m);
    if (info == old_info) {
      EXPECT_EQ(names, old_names) << "round " << round;
      ++saw_old;
    } else {
      EXPECT_EQ(info, new_info) << "round " << round;
      EXPECT_EQ(names, new_names) << "round " << round;
      ++saw_new;
    }
    r = RunRig("render " + m.string() + " --light 45,20 --out " + *dir_ + "/kill-" +
               std::to_string(round) + ".png");
    EXPECT_EQ(r.status, 0) << "round " << round << ": " << r.output;
    r = RunRig("view " + m.string() + " --out " + *dir_ + "/kill-view");
    EXPECT_EQ(r.status, 0) << "round " << round << ": " << r.output;
    EXPECT_EQ(Names(fs::path(*dir_) / "kill-view").count("plane_" + std::to_string(names.size() - 1) + ".jpg"), 0u);
    fs::remove_all(fs::path(*dir_) / "kill-view");
    // Back to the old model for the next round.
    fs::remove_all(m);
    CopyOf("model", "killed");
  }
  EXPECT_EQ(saw_old + saw_new, 6);
  // A run to the end cleans what killed runs left beside the folder.
  r = RunRig("fit --lp " + *lp_ + " --max-bytes-per-pixel 10 --out " + m.string());
  ASSERT_EQ(r.status, 0) << r.output;
  for (const auto& n : Names(*dir_)) EXPECT_NE(n.rfind(".killed.", 0), 0u) << "left behind: " << n;
}

TEST_F(Outputs, ViewAndExportPublishOnlyTheDeclaredPlanesAndRefuseALinkedOne) {
  const fs::path m = CopyOf("model", "extra");
  const int files = (Info(m)["nplanes"].get<int>() + 2) / 3;
  const std::string extra = "plane_" + std::to_string(files) + ".jpg";
  fs::copy_file(m / "plane_0.jpg", m / extra);
  const fs::path v = fs::path(*dir_) / "extra-view", e = fs::path(*dir_) / "extra-export";
  auto r = RunRig("view " + m.string() + " --out " + v.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(fs::exists(v / "plane_0.jpg"));
  EXPECT_FALSE(fs::exists(v / extra));
  r = RunRig("export " + m.string() + " --format relight --out " + e.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(fs::exists(e / "plane_0.jpg"));
  EXPECT_FALSE(fs::exists(e / extra));
  // A declared plane that is a link (to a file of the same model, so it still reads).
  fs::rename(m / "plane_0.jpg", m / "elsewhere.jpg");
  fs::create_symlink(m / "elsewhere.jpg", m / "plane_0.jpg");
  r = RunRig("view " + m.string() + " --out " + v.string() + "2");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr((m / "plane_0.jpg").string()));
  EXPECT_THAT(r.output, HasSubstr("symbolic link"));
  EXPECT_FALSE(fs::exists(v.string() + "2"));
  r = RunRig("export " + m.string() + " --format relight --out " + e.string() + "2");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("symbolic link"));
}

TEST_F(Outputs, ScaleOrBiasAFloatCannotHoldIsRefusedNamingTheField) {
  for (const char* model : {"model", "hsh"}) {
    const fs::path m = CopyOf(model, std::string("overflow-") + model);
    nlohmann::json info = Info(m);
    info["materials"][0]["scale"][1] = 1e39;
    PutInfo(m, info);
    auto r = RunRig("render " + m.string() + " --light 45,20 --out " + *dir_ + "/o.png");
    EXPECT_EQ(r.status, 2) << model << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr("materials[0].scale[1]")) << model;
    info = Info(CopyOf(model, std::string("overflow-") + model));
    info["materials"][0]["bias"][2] = -3e36;  // finite, but 255·bias·scale is not a float
    info["materials"][0]["scale"][2] = 1e4;
    PutInfo(m, info);
    r = RunRig("render " + m.string() + " --light 45,20 --out " + *dir_ + "/o.png");
    EXPECT_EQ(r.status, 2) << model << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr("bias[2]")) << model;
  }
  // A .ptm whose scale line overflows a float.
  const fs::path ptm = fs::path(*dir_) / "o.ptm";
  auto r = RunRig("export " + *dir_ + "/model --format ptm --out " + ptm.string());
  ASSERT_EQ(r.status, 0) << r.output;
  std::string bytes = testing::ReadText(ptm.string());
  size_t line = 0;
  for (int i = 0; i < 4; ++i) line = bytes.find('\n', line) + 1;  // version, format, width, height
  const size_t end = bytes.find('\n', line);
  bytes.replace(line, end - line, "1e39 1 1 1 1 1");
  std::ofstream(ptm, std::ios::binary) << bytes;
  r = RunRig("render " + ptm.string() + " --light 45,20 --out " + *dir_ + "/o.png");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("scale 0"));
}

// 65000x4096 declared over 48x36 planes: refused at the plane headers under a 4 GB address
// space (the old reader reserved 27 GB of planes first, and failed there).
TEST_F(Outputs, AHugeDeclaredSizeIsRefusedBeforeAnythingIsAllocated) {
  for (const char* model : {"model", "hsh"}) {
    const fs::path m = CopyOf(model, std::string("huge-") + model);
    nlohmann::json info = Info(m);
    info["width"] = 65000;
    info["height"] = 4096;
    PutInfo(m, info);
    const auto t0 = std::chrono::steady_clock::now();
    auto r = RunRig("render " + m.string() + " --light 45,20 --out " + *dir_ + "/h-" + model + ".png");
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(r.status, 2) << model << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr("plane_0.jpg")) << model;
    EXPECT_LT(s, 5.0) << model;
    // The same under a 4 GB address space (inherited by the child through popen).
    struct rlimit old {};
    ASSERT_EQ(::getrlimit(RLIMIT_AS, &old), 0);
    struct rlimit small = old;
    small.rlim_cur = rlim_t{4} << 30;
    ASSERT_EQ(::setrlimit(RLIMIT_AS, &small), 0);
    r = RunRig("render " + m.string() + " --light 45,20 --out " + *dir_ + "/h4-" + model + ".png");
    ::setrlimit(RLIMIT_AS, &old);
    EXPECT_EQ(r.status, 2) << model << " under 4 GB: " << r.output;
  }
}

}  // namespace
}  // namespace rig
