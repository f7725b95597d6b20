// End-to-end dry runs of `rig capture` / `rig resume` on the simulated rig: a complete
// session, SIGKILL at random moments then resume, every configured fault, Ctrl-C.
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "capture/session/session_store.h"
#include "tests/support/run_rig.h"
#include "tests/support/session_model.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using testing::CommandResult;
using testing::RunRig;

// A small, fast dry run: 160x120, 40 poses x 4 exposures.
const char* const kSmall = testing::kSmallDryRun;

std::vector<nlohmann::json> Records(const fs::path& session) {
  auto c = Journal::Read(session / "journal.jsonl");
  EXPECT_TRUE(c.ok());
  return c.ok() ? c->records : std::vector<nlohmann::json>{};
}

// Every planned frame is stored exactly once under frames/, and matches its latest record.
void ExpectCompleteAndConsistent(const fs::path& session, int poses, int exposures) {
  auto records = Records(session);
  std::map<std::pair<std::string, int>, nlohmann::json> latest;
  std::map<std::pair<std::string, int>, int> count;
  std::set<std::pair<std::string, int>> damaged;
  for (const auto& r : records) {
    if (r["event"] == "frame_damaged") damaged.insert({r["pose"], r["index"]});
    if (r["event"] != "frame") continue;
    auto key = std::make_pair(r["pose"].get<std::string>(), r["index"].get<int>());
    latest[key] = r;
    ++count[key];
  }
  ASSERT_EQ(static_cast<int>(latest.size()), poses * exposures);
  for (const auto& [key, n] : count) {
    // A frame is journaled twice only when the first copy was found damaged.
    EXPECT_TRUE(n == 1 || damaged.count(key)) << key.first << " " << key.second << " x" << n;
  }
  int files = 0;
  for (const auto& e : fs::recursive_directory_iterator(session / "frames")) {
    if (!e.is_regular_file()) continue;
    std::string parent = e.path().parent_path().filename().string();
    if (parent[0] == '.' || e.path().filename().string()[0] == '.') continue;  // moved aside
    ++files;
  }
  EXPECT_EQ(files, poses * exposures);
  for (const auto& [key, r] : latest) {
    auto bytes = ReadFileBytes(session / r["file"].get<std::string>());
    ASSERT_TRUE(bytes.ok()) << r.dump();
    EXPECT_EQ(bytes->size(), r["bytes"].get<size_t>());
    EXPECT_EQ(Crc32(*bytes), r["crc32"].get<uint32_t>()) << r.dump();
  }
  bool done = false;
  for (const auto& r : records) done = done || r["event"] == "capture_done";
  EXPECT_TRUE(done);
}

int FramesJournaled(const fs::path& session) {
  std::ifstream in(session / "journal.jsonl");
  std::string line;
  int n = 0;
  while (std::getline(in, line)) n += line.find("\"event\":\"frame\"") != std::string::npos;
  return n;
}

// pose/index -> CRC-32 of the stored frame, from the latest journal records.
std::map<std::pair<std::string, int>, uint32_t> FrameCrcs(const fs::path& session) {
  std::map<std::pair<std::string, int>, uint32_t> out;
  for (const auto& r : Records(session))
    if (r["event"] == "frame") out[{r["pose"].get<std::string>(), r["index"].get<int>()}] = r["crc32"];
  return out;
}

// Every file under `sub` (frames/ without the moved-aside copies, hdr/), relative path -> bytes.
std::map<std::string, std::vector<uint8_t>> Files(const fs::path& session, const std::string& sub) {
  std::map<std::string, std::vector<uint8_t>> out;
  for (const auto& e : fs::recursive_directory_iterator(session / sub)) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), session).string();
    if (rel.find("/.") != std::string::npos) continue;
    auto bytes = ReadFileBytes(e.path());
    if (bytes.ok()) out[rel] = *bytes;
  }
  return out;
}

TEST(CaptureSession, DryRunStoresJournalsFramesTruthRadianceMapsAndModel) {
  std::string dir = testing::FreshTempDir("capture_full");
  std::string cfg = testing::WriteSimConfig(dir, kSmall);
  fs::path session = fs::path(dir) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + session.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  ExpectCompleteAndConsistent(session, 40, 4);
  auto records = Records(session);
  ASSERT_FALSE(records.empty());
  int pose_done = 0;
  std::vector<double> plan;
  for (const auto& r2 : records) {
    if (r2["event"] == "pose_done") ++pose_done;
    if (r2["event"] == "plan") plan = r2["exposures_s"].get<std::vector<double>>();
  }
  EXPECT_EQ(pose_done, 40);
  ASSERT_EQ(plan.size(), 4u);
  for (size_t i = 1; i < plan.size(); ++i) EXPECT_GT(plan[i], plan[i - 1]);
  EXPECT_TRUE(fs::exists(session / "session.toml"));
  EXPECT_TRUE(fs::exists(session / "log.txt"));
  EXPECT_TRUE(fs::exists(session / "truth" / "scene.json"));
  EXPECT_TRUE(fs::exists(session / "calib" / "response.csv"));
  int hdr = 0;
  for (const auto& e : fs::directory_iterator(session / "hdr")) hdr += e.path().extension() == ".exr";
  EXPECT_EQ(hdr, 40);
  EXPECT_TRUE(testing::SessionHasModel(session));
  EXPECT_THAT(r.output, HasSubstr("frames 160"));
  // A second capture into the same folder is refused; nothing is overwritten.
  CommandResult again = RunRig("capture --config " + cfg + " --out " + session.string() + " --dry-run --no-progress");
  EXPECT_EQ(again.status, 2);
  EXPECT_THAT(again.output, HasSubstr("already holds a session"));
}

TEST(CaptureSession, SigkillAtRandomMomentsThenResumeGivesEveryFrameExactlyOnce) {
  std::string dir = testing::FreshTempDir("capture_kill");
  std::string cfg = testing::WriteSimConfig(dir, kSmall);
  fs::path session = fs::path(dir) / "S";
  std::string log = dir + "/log.txt";
  std::mt19937 rng(7);
  // Kills are placed by progress, not by the clock (a loaded machine can spend longer starting
  // than a fixed window lasts, and an idle one can finish inside it): each round lets the
  // journal grow by a random 1..20 frames, then kills at a random moment within about one
  // frame's time after that.
  auto frames_journaled = [&] {
    std::ifstream in(session / "journal.jsonl");
    std::string line;
    int n = 0;
    while (std::getline(in, line)) n += line.find("\"event\":\"frame\"") != std::string::npos;
    return n;
  };
  int kills = 0;
  bool first = true;
  for (int round = 0; round < 60; ++round) {
    std::vector<std::string> args =
        first ? std::vector<std::string>{"capture", "--config", cfg, "--out", session.string(),
                                         "--dry-run", "--no-progress", "--no-process"}
              : std::vector<std::string>{"resume", session.string(), "--no-progress", "--no-process"};
    const int target = frames_journaled() + std::uniform_int_distribution<int>(1, 20)(rng);
    const auto t0 = std::chrono::steady_clock::now();
    pid_t pid = testing::SpawnRig(args, log);
    while (frames_journaled() < std::min(target, 160) &&
           std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30))
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    std::this_thread::sleep_for(std::chrono::microseconds(std::uniform_int_distribution<int>(0, 3000)(rng)));
    int killed = kill(pid, SIGKILL) == 0;
    int status = testing::WaitRig(pid);
    if (fs::exists(session / "session.toml")) first = false;
    if (status == 0) break;
    ASSERT_EQ(status, 128 + SIGKILL) << "round " << round;
    kills += killed;
  }
  // Finish whatever is left.
  CommandResult last = RunRig("resume " + session.string() + " --no-progress");
  ASSERT_EQ(last.status, 0) << last.output;
  EXPECT_GE(kills, 4);
  // No temporaries of the killed writers are left behind.
  for (const auto& e : fs::recursive_directory_iterator(session)) {
    const std::string name = e.path().filename().string();
    EXPECT_FALSE(name[0] == '.' && name.find(".tmp") != std::string::npos) << e.path();
  }
  ExpectCompleteAndConsistent(session, 40, 4);
  // The same session as an uninterrupted run, byte for byte: every frame (each frame's noise
  // comes from seed, pose and exposure, not from how many captures a process made) and every
  // radiance map.
  fs::path clean = fs::path(dir) / "clean";
  CommandResult ref = RunRig("capture --config " + cfg + " --out " + clean.string() +
                             " --dry-run --no-progress");
  ASSERT_EQ(ref.status, 0) << ref.output;
  EXPECT_EQ(FrameCrcs(session), FrameCrcs(clean));
  const auto frames = Files(session, "frames"), clean_frames = Files(clean, "frames");
  EXPECT_EQ(frames.size(), 160u);
  int differ = 0;
  for (const auto& [rel, bytes] : clean_frames) differ += frames.count(rel) == 0 || frames.at(rel) != bytes;
  EXPECT_EQ(differ, 0) << "of " << clean_frames.size() << " frames";
  const auto maps = Files(session, "hdr"), clean_maps = Files(clean, "hdr");
  EXPECT_EQ(maps.size(), 40u);
  differ = 0;
  for (const auto& [rel, bytes] : clean_maps) differ += maps.count(rel) == 0 || maps.at(rel) != bytes;
  EXPECT_EQ(differ, 0) << "of " << clean_maps.size() << " radiance maps";
}

TEST(CaptureSession, TransientCameraMotorAndLampFaultsAreRetried) {
  std::string dir = testing::FreshTempDir("capture_retry");
  std::string cfg = testing::WriteSimConfig(dir, std::string(kSmall) + R"([sim.camera]
fail_capture_at = [5, 77]
disconnect_at = 30
disconnect_captures = 2
[sim.motor]
stall_at_move = [3]
timeout_at_move = [11]
[sim.lamp]
fail_switch_at = [4]
[camera]
retry_backoff_s = 0.001
[motor]
retry_backoff_s = 0.001
)");
  fs::path session = fs::path(dir) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + session.string() + " --dry-run --no-progress --no-process");
  ASSERT_EQ(r.status, 0) << r.output;
  ExpectCompleteAndConsistent(session, 40, 4);
  EXPECT_THAT(r.output, HasSubstr("retries 7"));
  EXPECT_THAT(r.output, HasSubstr("faults 0"));
}

TEST(CaptureSession, PersistentCameraFaultStopsInFaultStateThenResumeCompletes) {
  std::string dir = testing::FreshTempDir("capture_fault");
  std::string cfg = testing::WriteSimConfig(dir, std::string(kSmall) + R"([sim.camera]
fail_forever_after = 50
[camera]
retries = 2
retry_backoff_s = 0.001
)");
  fs::path session = fs::path(dir) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + session.string() + " --dry-run --no-progress --no-process");
  ASSERT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("sim camera"));
  EXPECT_THAT(r.output, HasSubstr("pose h"));
  auto records = Records(session);
  ASSERT_FALSE(records.empty());
  EXPECT_EQ(records.back()["event"], "fault");
  int frames = 0;
  for (const auto& rec : records) frames += rec["event"] == "frame";
  EXPECT_EQ(frames, 49);
  // The simulated body "is fixed" each time it is reopened: every resume gets 49 more frames.
  for (int round = 0; round < 6; ++round) {
    CommandResult res = RunRig("resume " + session.string() + " --no-progress --no-process");
    if (res.status == 0) break;
    ASSERT_EQ(res.status, 1) << res.output;
  }
  ExpectCompleteAndConsistent(session, 40, 4);
}

TEST(CaptureSession, SigintFinishesTheFrameParksAndResumeCompletes) {
  std::string dir = testing::FreshTempDir("capture_sigint");
  // Real-time device latencies scaled down so that the run lasts a couple of seconds.
  std::string cfg = testing::WriteSimConfig(dir, std::string(kSmall) + "[sim]\nlatency_scale = 0.05\n");
  fs::path session = fs::path(dir) / "S";
  pid_t pid = testing::SpawnRig({"capture", "--config", cfg, "--out", session.string(), "--dry-run",
                                 "--no-progress", "--no-process"}, dir + "/log.txt");
  // By progress, not by the clock (a sanitizer build can spend longer starting than any fixed
  // window): the signal goes once ten frames are journaled.
  const auto t0 = std::chrono::steady_clock::now();
  while (FramesJournaled(session) < 10 &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60))
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  kill(pid, SIGINT);
  ASSERT_EQ(testing::WaitRig(pid), 128 + SIGINT);
  auto records = Records(session);
  ASSERT_FALSE(records.empty());
  EXPECT_EQ(records.back()["event"], "interrupted");
  std::ifstream in(dir + "/log.txt");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(text, HasSubstr("rig resume"));
  CommandResult res = RunRig("resume " + session.string() + " --no-progress --no-process");
  ASSERT_EQ(res.status, 0) << res.output;
  ExpectCompleteAndConsistent(session, 40, 4);
}

TEST(CaptureSession, SecondProcessOnTheSameSessionIsRefused) {
  std::string dir = testing::FreshTempDir("capture_lock");
  std::string cfg = testing::WriteSimConfig(dir, std::string(kSmall) + "[sim]\nlatency_scale = 0.05\n");
  fs::path session = fs::path(dir) / "S";
  pid_t pid = testing::SpawnRig({"capture", "--config", cfg, "--out", session.string(), "--dry-run",
                                 "--no-progress", "--no-process"}, dir + "/log.txt");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  CommandResult second = RunRig("resume " + session.string() + " --no-progress");
  kill(pid, SIGTERM);
  EXPECT_EQ(testing::WaitRig(pid), 128 + SIGTERM);
  EXPECT_EQ(second.status, 1);
  EXPECT_THAT(second.output, HasSubstr("in use by another rig process"));
}

}  // namespace
}  // namespace rig
