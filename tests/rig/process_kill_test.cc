// `rig process` killed (SIGKILL) while it merges radiance maps and while it fits the model,
// and a full disk during capture and processing: afterwards every map and the model are
// there once, no temporary file is left, nothing stored is lost.
#include <signal.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <map>
#include <filesystem>
#include <fstream>
#include <random>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "capture/session/session_store.h"
#include "process/io/exr_io.h"
#include "process/model/any/load_model.h"
#include "tests/support/run_rig.h"
#include "tests/support/session_model.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing::CommandResult;
using testing::RunRig;

// A small, fast dry run: 160x120, 40 poses x 4 exposures.
const char* const kSmall = testing::kSmallDryRun;

int CountMaps(const fs::path& s) {
  int n = 0;
  std::error_code ec;
  for (auto it = fs::directory_iterator(s / "hdr", ec); !ec && it != fs::directory_iterator(); it.increment(ec))
    n += it->path().extension() == ".exr" && it->path().filename().string()[0] != '.';
  return n;
}

bool ModelTempPresent(const fs::path& s) {
  std::error_code ec;
  for (auto it = fs::directory_iterator(s / "model", ec); !ec && it != fs::directory_iterator(); it.increment(ec))
    if (it->path().filename().string().find(".tmp") != std::string::npos) return true;
  return false;
}

// Every map once, the model, no temporary anywhere.
void ExpectProcessedOnce(const fs::path& s) {
  int maps = 0;
  for (const auto& e : fs::directory_iterator(s / "hdr")) {
    const std::string name = e.path().filename().string();
    EXPECT_NE(name[0], '.') << "left behind: " << e.path();
    if (e.path().extension() != ".exr") continue;
    ++maps;
    auto img = ReadExr(e.path().string());
    EXPECT_TRUE(img.ok()) << e.path();
  }
  EXPECT_EQ(maps, 40);
  EXPECT_TRUE(testing::SessionHasModel(s));
  const fs::path exr = s / "model" / "model.exr";
  auto model = LoadReflectanceModel((fs::exists(exr) ? exr : s / "model" / "pca").string());
  EXPECT_TRUE(model.ok()) << model.error().ToString();
  for (const auto& e : fs::recursive_directory_iterator(s)) {
    const std::string name = e.path().filename().string();
    EXPECT_FALSE(name[0] == '.' && name.find(".tmp") != std::string::npos) << "left behind: " << e.path();
  }
}

TEST(ProcessKill, SigkillWhileMergingAndWhileFittingThenProcessCompletesOnce) {
  const std::string dir = testing::FreshTempDir("process_kill");
  const std::string cfg = testing::WriteSimConfig(dir, kSmall);
  const fs::path s = fs::path(dir) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress --no-process");
  ASSERT_EQ(r.status, 0) << r.output;
  std::mt19937 rng(11);
  const std::string log = dir + "/log.txt";
  int kills_merging = 0, kills_fitting = 0;
  // Kills by progress: each round lets a random 1..10 more maps appear, then kills; once
  // every map is there, kills as soon as the model's temporary file appears (the fit writes it).
  for (int round = 0; round < 40; ++round) {
    const int before = CountMaps(s);
    const int target = std::min(40, before + std::uniform_int_distribution<int>(1, 10)(rng));
    pid_t pid = testing::SpawnRig({"process", s.string()}, log);
    const auto t0 = std::chrono::steady_clock::now();
    bool fitting = false;
    while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
      if (before < 40 && CountMaps(s) >= target) break;
      if (before == 40 && ModelTempPresent(s)) {
        fitting = true;
        break;
      }
      if (waitpid(pid, nullptr, WNOHANG) == pid) {  // finished on its own
        pid = -1;
        break;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    }
    if (pid < 0) break;
    kill(pid, SIGKILL);
    const int status = testing::WaitRig(pid);
    if (status == 0) break;
    ASSERT_EQ(status, 128 + SIGKILL) << "round " << round;
    (fitting ? kills_fitting : kills_merging) += 1;
    if (kills_fitting >= 2) break;
  }
  EXPECT_GE(kills_merging, 2);
  EXPECT_GE(kills_fitting, 1);
  r = RunRig("process " + s.string());
  ASSERT_EQ(r.status, 0) << r.output;
  // Maps finished before a kill are kept, not merged again.
  EXPECT_THAT(r.output, HasSubstr("0 merged, 40 up to date, 0 failed")) << r.output;
  ExpectProcessedOnce(s);
  fs::remove_all(dir);
}

// A small tmpfs (we may be root in CI; skipped where mounting is not permitted).
class FullDisk : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::FreshTempDir("full_disk");
    mnt_ = dir_ + "/mnt";
    fs::create_directories(mnt_);
    if (::mount("tmpfs", mnt_.c_str(), "tmpfs", 0, "size=1200k") != 0)
      GTEST_SKIP() << "cannot mount a tmpfs here (" << std::strerror(errno) << "); full-disk test skipped";
    mounted_ = true;
  }
  void TearDown() override {
    if (mounted_) ::umount2(mnt_.c_str(), MNT_DETACH);
    fs::remove_all(dir_);
  }
  void Resize(const std::string& size) {
    ASSERT_EQ(::mount("tmpfs", mnt_.c_str(), "tmpfs", MS_REMOUNT, ("size=" + size).c_str()), 0)
        << std::strerror(errno);
  }
  std::string dir_, mnt_;
  bool mounted_ = false;
};

std::map<std::string, uint32_t> StoredCrcs(const fs::path& s) {
  std::map<std::string, uint32_t> out;
  auto c = Journal::Read(s / "journal.jsonl");
  EXPECT_TRUE(c.ok());
  if (!c.ok()) return out;
  for (const auto& r : c->records)
    if (r["event"] == "frame") out[r["file"].get<std::string>()] = r["crc32"];
  return out;
}

TEST_F(FullDisk, DuringCaptureAClearErrorNothingLostAndResumeCompletesOnceSpaceIsFreed) {
  const std::string cfg = testing::WriteSimConfig(dir_, kSmall);
  // Room for the simulator's truth (about 7.5 MB) and a part of the frames and maps.
  Resize("10500k");
  const fs::path s = fs::path(mnt_) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress");
  ASSERT_NE(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("No space left on device")) << r.output;
  // The summary says what failed (the frame that could not be stored, the maps that could
  // not be written), never a bare "0 failed" below failed writes.
  EXPECT_THAT(r.output, HasSubstr("storage failed:")) << r.output;
  EXPECT_THAT(r.output, Not(HasSubstr("processing: 0 radiance maps, 0 failed"))) << r.output;
  const auto stored = StoredCrcs(s);
  ASSERT_GT(stored.size(), 0u);
  ASSERT_LT(stored.size(), 160u);
  Resize("64m");
  r = RunRig("resume " + s.string() + " --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto after = StoredCrcs(s);
  EXPECT_EQ(after.size(), 160u);
  for (const auto& [file, crc] : stored) {  // every frame stored before the disk filled is kept
    ASSERT_TRUE(after.count(file)) << file;
    EXPECT_EQ(after.at(file), crc) << file;
    auto bytes = ReadFileBytes(s / file);
    ASSERT_TRUE(bytes.ok()) << file;
    EXPECT_EQ(Crc32(*bytes), crc) << file;
  }
  EXPECT_EQ(CountMaps(s), 40);
}

TEST_F(FullDisk, DuringProcessingAClearErrorAndProcessCompletesOnceSpaceIsFreed) {
  const std::string cfg = testing::WriteSimConfig(dir_, kSmall);
  Resize("12m");
  const fs::path s = fs::path(mnt_) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress --no-process");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto stored = StoredCrcs(s);
  ASSERT_EQ(stored.size(), 160u);
  // Room for the frames and a few maps only.
  std::error_code ec;
  const auto space = fs::space(mnt_, ec);
  ASSERT_FALSE(ec);
  const uint64_t used = space.capacity - space.available;
  Resize(std::to_string((used + 1200 * 1024) / 1024) + "k");
  r = RunRig("process " + s.string());
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("No space left on device")) << r.output;
  EXPECT_THAT(r.output, Not(HasSubstr(" 0 failed"))) << r.output;
  for (const auto& e : fs::recursive_directory_iterator(s)) {
    const std::string name = e.path().filename().string();
    EXPECT_FALSE(name[0] == '.' && name.find(".tmp") != std::string::npos) << "left behind: " << e.path();
  }
  EXPECT_EQ(StoredCrcs(s), stored);
  Resize("64m");
  r = RunRig("process " + s.string());
  ASSERT_EQ(r.status, 0) << r.output;
  ExpectProcessedOnce(s);
}

}  // namespace
}  // namespace rig
