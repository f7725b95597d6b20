// The adaptive grid ([grid] mode = "adaptive") run by the capture daemon, through
// `rig capture --dry-run` and `rig resume` on the simulated rig: every pose is chosen and its
// choice journaled with the reason before any frame of it, the seed first; the session stops
// at max_poses or at the target and says which; the model is fitted from the poses taken; a
// session killed (SIGKILL, placed by progress) and resumed makes the same choices and stores
// the same bytes as an uninterrupted one; a resume under another grid mode is refused.
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <set>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "capture/daemon/adaptive_grid.h"
#include "capture/plan/pose.h"
#include "capture/session/session_store.h"
#include "config/config.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

// The default 40-pose grid allowed, a 3-frame bracket, small frames.
std::string Config(const std::string& dir, const std::string& grid_extra) {
  fs::create_directories(dir);
  return testing::WriteSimConfig(dir, "[sim]\nwidth = 96\nheight = 72\n[bracket]\ncount = 3\n"
                                      "[grid]\nmode = \"adaptive\"\n" + grid_extra);
}

std::vector<nlohmann::json> Records(const fs::path& session) {
  auto c = Journal::Read(session / "journal.jsonl");
  EXPECT_TRUE(c.ok());
  return c.ok() ? c->records : std::vector<nlohmann::json>{};
}

std::vector<nlohmann::json> Events(const fs::path& session, const std::string& event) {
  std::vector<nlohmann::json> out;
  for (const auto& r : Records(session))
    if (r["event"] == event) out.push_back(r);
  return out;
}

// Every file under frames/ (without moved-aside copies), relative path -> bytes.
std::map<std::string, std::vector<uint8_t>> Frames(const fs::path& session) {
  std::map<std::string, std::vector<uint8_t>> out;
  for (const auto& e : fs::recursive_directory_iterator(session / "frames")) {
    if (!e.is_regular_file()) continue;
    const std::string rel = fs::relative(e.path(), session).string();
    if (rel.find("/.") != std::string::npos) continue;
    auto bytes = ReadFileBytes(e.path());
    if (bytes.ok()) out[rel] = *bytes;
  }
  return out;
}

int FramesJournaled(const fs::path& session) {
  std::ifstream in(session / "journal.jsonl");
  std::string line;
  int n = 0;
  while (std::getline(in, line)) n += line.find("\"event\":\"frame\"") != std::string::npos;
  return n;
}

int Maps(const fs::path& session) {
  int maps = 0;
  for (const auto& e : fs::directory_iterator(session / "hdr")) maps += e.path().extension() == ".exr";
  return maps;
}

TEST(AdaptiveGrid, JournalsEveryChoiceBeforeItsPosesFramesAndStopsAtMaxPoses) {
  const std::string dir = testing::FreshTempDir("adaptive_grid_max");
  const std::string cfg = Config(dir, "max_poses = 14\ntarget = 0\n");
  const fs::path S = fs::path(dir) / "S";
  auto r = RunRig("capture --config " + cfg + " --out " + S.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;

  std::vector<std::string> chosen;
  std::set<std::string> framed;
  int seeds = 0, done = 0;
  bool seeds_first = true;
  for (const auto& rec : Records(S)) {
    const std::string ev = rec["event"];
    if (ev == "plan") {
      EXPECT_EQ(rec["grid_mode"], "adaptive");
      EXPECT_EQ(rec["max_poses"], 14);
      EXPECT_EQ(rec["poses"].size(), 40u);  // the poses allowed
    } else if (ev == "pose_chosen") {
      const std::string pose = rec["pose"];
      EXPECT_EQ(framed.count(pose), 0u) << pose << " was chosen after its frames";
      EXPECT_EQ(std::count(chosen.begin(), chosen.end(), pose), 0) << pose << " chosen twice";
      chosen.push_back(pose);
      EXPECT_EQ(rec["choice"], chosen.size());
      EXPECT_FALSE(rec["reason"].get<std::string>().empty());
      if (rec["seed"].get<bool>()) {
        ++seeds;
        seeds_first = seeds_first && seeds == static_cast<int>(chosen.size());
      } else {
        // The model's choice: its prediction and the predicted error over the grid's span.
        EXPECT_THAT(rec["reason"].get<std::string>(), HasSubstr("per second of the rig's time"));
        EXPECT_GT(rec["predicted_rms"].get<double>(), 0);
        EXPECT_GE(rec["region_rms"].get<double>(), rec["floor_rms"].get<double>());
      }
    } else if (ev == "frame") {
      const std::string pose = rec["pose"];
      EXPECT_NE(std::find(chosen.begin(), chosen.end(), pose), chosen.end())
          << "a frame of " << pose << " before it was chosen";
      framed.insert(pose);
    } else if (ev == "grid_done") {
      ++done;
      EXPECT_EQ(rec["poses"], 14);
      EXPECT_THAT(rec["reason"].get<std::string>(), HasSubstr("max_poses: 14 of the grid's 40"));
    }
  }
  EXPECT_EQ(chosen.size(), 14u);
  EXPECT_EQ(seeds, 8);
  EXPECT_TRUE(seeds_first);
  EXPECT_EQ(done, 1);
  EXPECT_EQ(framed.size(), 14u);
  EXPECT_EQ(Maps(S), 14);
  EXPECT_THAT(r.output, HasSubstr("fitted from the 14 poses taken of 40 allowed"));
  EXPECT_THAT(r.output, HasSubstr("poses 14  frames 42"));
  EXPECT_TRUE(fs::exists(S / "model" / "model.exr"));
}

TEST(AdaptiveGrid, TheTargetStopsBeforeMaxPosesAndSaysSo) {
  const std::string dir = testing::FreshTempDir("adaptive_grid_target");
  // A loose target: the predicted error within 100% of what every pose would leave.
  const std::string cfg = Config(dir, "max_poses = 40\ntarget = 1.0\n");
  const fs::path S = fs::path(dir) / "S";
  auto r = RunRig("capture --config " + cfg + " --out " + S.string() + " --dry-run --no-progress --no-process");
  ASSERT_EQ(r.status, 0) << r.output;
  const auto done = Events(S, "grid_done");
  ASSERT_EQ(done.size(), 1u);
  const int poses = done[0]["poses"];
  EXPECT_LT(poses, 40);
  EXPECT_GT(poses, 8);
  EXPECT_THAT(done[0]["reason"].get<std::string>(), HasSubstr("the target"));
  EXPECT_EQ(Events(S, "pose_chosen").size(), static_cast<size_t>(poses));
  EXPECT_EQ(Maps(S), 0);  // --no-process
  // The stop is where the last choice's predicted error was already near the floor.
  auto p = RunRig("process " + S.string());
  ASSERT_EQ(p.status, 0) << p.output;
  EXPECT_EQ(Maps(S), poses);
}

TEST(AdaptiveGrid, SigkillPlacedByProgressThenResumeMakesTheSameChoicesAndTheSameBytes) {
  const std::string dir = testing::FreshTempDir("adaptive_grid_kill");
  const std::string cfg = Config(dir, "max_poses = 16\n");
  const fs::path S = fs::path(dir) / "S", C = fs::path(dir) / "clean";
  const std::string log = dir + "/log.txt";
  auto ref = RunRig("capture --config " + cfg + " --out " + C.string() + " --dry-run --no-progress");
  ASSERT_EQ(ref.status, 0) << ref.output;
  const int total = FramesJournaled(C);
  std::mt19937 rng(23);
  int kills = 0;
  bool first = true;
  // Each round lets the journal grow by 1..5 frames, then kills within about a frame's time:
  // after a choice before its frames, mid-bracket, between a pose's last frame and the next
  // choice.
  for (int round = 0; round < 60; ++round) {
    std::vector<std::string> args =
        first ? std::vector<std::string>{"capture", "--config", cfg, "--out", S.string(),
                                         "--dry-run", "--no-progress", "--no-process"}
              : std::vector<std::string>{"resume", S.string(), "--no-progress", "--no-process"};
    const int target =
        std::min(total, FramesJournaled(S) + std::uniform_int_distribution<int>(1, 5)(rng));
    const auto t0 = std::chrono::steady_clock::now();
    pid_t pid = testing::SpawnRig(args, log);
    while (FramesJournaled(S) < target &&
           std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30))
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    std::this_thread::sleep_for(
        std::chrono::microseconds(std::uniform_int_distribution<int>(0, 3000)(rng)));
    const int killed = kill(pid, SIGKILL) == 0;
    const int status = testing::WaitRig(pid);
    if (fs::exists(S / "session.toml")) first = false;
    if (status == 0) break;
    ASSERT_EQ(status, 128 + SIGKILL) << "round " << round;
    kills += killed;
  }
  auto last = RunRig("resume " + S.string() + " --no-progress");
  ASSERT_EQ(last.status, 0) << last.output;
  EXPECT_GE(kills, 4);

  // The same choices in the same order with the same reasons, each journaled once.
  const auto choices = Events(S, "pose_chosen"), clean = Events(C, "pose_chosen");
  ASSERT_EQ(choices.size(), clean.size());
  ASSERT_EQ(choices.size(), 16u);
  for (size_t i = 0; i < clean.size(); ++i) {
    EXPECT_EQ(choices[i]["pose"], clean[i]["pose"]) << "choice " << i + 1;
    EXPECT_EQ(choices[i]["reason"], clean[i]["reason"]) << "choice " << i + 1;
  }
  EXPECT_EQ(Events(S, "grid_done").size(), 1u);
  const auto frames = Frames(S), clean_frames = Frames(C);
  EXPECT_EQ(frames.size(), clean_frames.size());
  int differ = 0;
  for (const auto& [rel, bytes] : clean_frames) differ += frames.count(rel) == 0 || frames.at(rel) != bytes;
  EXPECT_EQ(differ, 0) << "of " << clean_frames.size() << " frames";
  EXPECT_EQ(Maps(S), 16);
}

TEST(AdaptiveGrid, AResumeUnderAnotherGridModeIsRefusedAndTouchesNothingThenCompletesTheChoice) {
  const std::string dir = testing::FreshTempDir("adaptive_grid_mode");
  const std::string cfg = Config(dir, "max_poses = 10\n");
  const fs::path S = fs::path(dir) / "S";
  auto r = RunRig("capture --config " + cfg + " --out " + S.string() + " --dry-run --no-progress --no-process");
  ASSERT_EQ(r.status, 0) << r.output;
  // Cut the journal after the fifth choice's frames, so that the resume has poses to take.
  std::vector<std::string> lines;
  {
    std::ifstream in(S / "journal.jsonl");
    std::string line;
    int chosen = 0;
    while (std::getline(in, line)) {
      auto j = nlohmann::json::parse(line);
      if (j["event"] == "pose_chosen" && ++chosen == 6) break;
      lines.push_back(line);
    }
  }
  {
    std::ofstream out(S / "journal.jsonl", std::ios::trunc);
    for (const auto& l : lines) out << l << "\n";
  }
  const auto before = Frames(S);
  // Asked for on the command line: the grid is no device setting.
  auto res = RunRig("resume " + S.string() + " --no-progress --set grid.mode=full");
  EXPECT_NE(res.status, 0) << res.output;
  EXPECT_THAT(res.output, HasSubstr("--set grid.mode"));
  EXPECT_THAT(res.output, HasSubstr("the grid"));
  // Written into session.toml by hand: refused, naming the key and both modes.
  const fs::path toml = S / "session.toml";
  std::string text;
  {
    std::ifstream in(toml);
    text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  const std::string original = text;
  const size_t at = text.find("mode = 'adaptive'");
  ASSERT_NE(at, std::string::npos) << text;
  text.replace(at, 17, "mode = 'full'");
  { std::ofstream(toml, std::ios::trunc) << text; }
  auto edited = RunRig("resume " + S.string() + " --no-progress");
  EXPECT_NE(edited.status, 0) << edited.output;
  EXPECT_THAT(edited.output, HasSubstr("grid.mode ('adaptive' -> 'full')"));
  EXPECT_EQ(Frames(S), before);
  { std::ofstream(toml, std::ios::trunc) << original; }
  // Under its own mode it completes the choice from where the journal ends.
  auto ok = RunRig("resume " + S.string() + " --no-progress");
  ASSERT_EQ(ok.status, 0) << ok.output;
  EXPECT_EQ(Events(S, "pose_chosen").size(), 10u);
  EXPECT_EQ(Maps(S), 10);
}

TEST(AdaptiveGrid, AnUnknownGridModeIsRefusedNamingTheKey) {
  const std::string dir = testing::FreshTempDir("adaptive_grid_unknown");
  fs::create_directories(dir);
  const std::string cfg = testing::WriteSimConfig(dir, "[grid]\nmode = \"smart\"\n");
  auto r = RunRig("check-config " + cfg);
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("mode"));
  EXPECT_THAT(r.output, HasSubstr("adaptive"));
}

// The motion time the choice weighs: a trapezoid per axis (a triangle when too short to reach
// the speed), both axes at once; and a pose's own cost from the configuration.
TEST(AdaptiveGrid, MoveSecondsAndPoseCostHaveTheirKnownAnswers) {
  MotorConfig m;
  m.speed_deg_per_s = 45;
  m.accel_deg_per_s2 = 90;
  Pose a{0, 0}, b{10, 0}, c{90, 0}, d{90, 30};
  EXPECT_NEAR(MoveSeconds(m, a, b), 2 * std::sqrt(10.0 / 90), 1e-9);  // never at speed
  EXPECT_NEAR(MoveSeconds(m, a, c), 90.0 / 45 + 45.0 / 90, 1e-9);     // 2 s cruising + ramps
  EXPECT_NEAR(MoveSeconds(m, a, d), MoveSeconds(m, a, c), 1e-9);      // the longer axis counts
  EXPECT_NEAR(MoveSeconds(m, d, a), MoveSeconds(m, a, d), 1e-9);
  EXPECT_EQ(MoveSeconds(m, a, a), 0);
  struct Config cfg;  // (the struct: Config above is this file's helper)
  cfg.motor.settle_time_s = 0.2;
  cfg.lamp.warmup_s = 0.3;
  EXPECT_NEAR(AdaptivePoseCost(cfg, {0.01, 0.04, 0.16}), 0.2 + 0.3 + 0.21 + 3 * kTransferSecondsPerFrame, 1e-9);
  cfg.grid.pose_cost_s = 4;
  EXPECT_EQ(AdaptivePoseCost(cfg, {0.01, 0.04, 0.16}), 4);
  EXPECT_EQ(AdaptiveMaxPoses(cfg.grid, 40), 20);
  EXPECT_EQ(AdaptiveMaxPoses(cfg.grid, 41), 21);
  cfg.grid.max_poses = 100;
  EXPECT_EQ(AdaptiveMaxPoses(cfg.grid, 40), 40);
}

}  // namespace
}  // namespace rig
