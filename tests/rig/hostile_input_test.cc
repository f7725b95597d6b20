// Hostile and damaged input (issue 20): mutated journals, paths leaving the session, links
// inside it, edited configurations, oversized grids, fine grids, a failed start — each must
// end with a clear message (file:line where there is one) and exit 2, nothing outside the
// session touched and nothing captured lost.
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <limits>

#include <opencv2/imgcodecs.hpp>

#include "capture/plan/pose.h"
#include "process/io/exr_io.h"
#include "capture/session/session_store.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing::CommandResult;
using testing::RunRig;

// 8 poses x 2 exposures at 80x60: a whole dry run takes a fraction of a second.
const char* kTiny = R"([grid]
h_min_deg = 0
h_max_deg = 30
h_step_deg = 10
v_min_deg = 0
v_max_deg = 10
v_step_deg = 10
[sim]
width = 80
height = 60
[bracket]
center_s = 0.02
ev_step = 2
count = 2
)";

std::string ReadText(const fs::path& p) { return testing::ReadText(p.string()); }
void WriteText(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}
int CountLines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

// A complete tiny session captured without processing.
fs::path TinySession(const std::string& dir, const std::string& extra = "") {
  const std::string cfg = testing::WriteSimConfig(dir, std::string(kTiny) + extra);
  const fs::path s = fs::path(dir) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + s.string() +
                           " --dry-run --no-progress --no-process");
  EXPECT_EQ(r.status, 0) << r.output;
  return s;
}

TEST(HostileJournal, RecordsWithMissingKeysOrWrongTypesExit2NamingTheLine) {
  const std::string dir = testing::FreshTempDir("hostile_journal");
  const fs::path s = TinySession(dir);
  const fs::path journal = s / "journal.jsonl";
  const std::string good = ReadText(journal);
  const int line = CountLines(good) + 1;
  const std::string frame =
      R"({"event":"frame","index":0,"exposure_s":0.01,"file":"frames/h000_v00/0_0.01000.jpg","bytes":5)";
  for (const std::string& bad :
       {frame + R"(,"pose":5,"crc32":1})", frame + R"(,"pose":"h000_v00"})",
        std::string(R"({"event":7})"), std::string(R"({"event":"plan","poses":3,"exposures_s":[0.01]})")}) {
    WriteText(journal, good + bad + "\n");
    CommandResult r = RunRig("resume " + s.string() + " --no-progress --no-process");
    EXPECT_EQ(r.status, 2) << bad << "\n" << r.output;
    EXPECT_THAT(r.output, HasSubstr("journal.jsonl:" + std::to_string(line) + ":")) << bad;
    // `rig process` reads the same journal through the same reader.
    r = RunRig("process " + s.string() + " --hdr-only");
    EXPECT_EQ(r.status, 2) << bad << "\n" << r.output;
  }
  WriteText(journal, good);
  EXPECT_EQ(RunRig("resume " + s.string() + " --no-progress --no-process").status, 0);
  fs::remove_all(dir);
}

TEST(HostileJournal, AFilePathLeavingTheSessionIsRefusedAndTheOutsideFileUntouched) {
  const std::string dir = testing::FreshTempDir("hostile_outside");
  const fs::path s = TinySession(dir);
  const fs::path outside = fs::path(dir) / "precious.jpg";
  WriteText(outside, "not a frame of this session");
  const fs::path journal = s / "journal.jsonl";
  const std::string good = ReadText(journal);
  for (const std::string& file : {std::string("../precious.jpg"), std::string("frames/../../precious.jpg"),
                                 outside.string()}) {
    // A record of an existing pose whose size and CRC do not match: resume would move it aside.
    WriteText(journal, good + R"({"event":"frame","pose":"h000_v00","index":0,"exposure_s":0.01,"file":")" +
                           file + R"(","bytes":3,"crc32":7})" + "\n");
    CommandResult r = RunRig("resume " + s.string() + " --no-progress --no-process");
    EXPECT_EQ(r.status, 2) << file << "\n" << r.output;
    EXPECT_THAT(r.output, HasSubstr("'file'")) << r.output;
    EXPECT_EQ(ReadText(outside), "not a frame of this session");
    EXPECT_FALSE(fs::exists(fs::path(dir) / ".damaged"));
  }
  fs::remove_all(dir);
}

TEST(HostileSession, LinksInsideTheSessionAreRefusedAndTheirTargetsUntouched) {
  const std::string dir = testing::FreshTempDir("hostile_links");
  const fs::path s = TinySession(dir);
  const fs::path target = fs::path(dir) / "target.txt";
  auto expect_refused = [&](const std::string& cmd, const std::string& what) {
    WriteText(target, "keep me");
    CommandResult r = RunRig(cmd);
    EXPECT_EQ(r.status, 2) << what << "\n" << r.output;
    EXPECT_THAT(r.output, HasSubstr("symbolic link")) << what;
    EXPECT_EQ(ReadText(target), "keep me") << what;
  };
  const std::string resume = "resume " + s.string() + " --no-progress --no-process";
  // .lock: once truncated and overwritten with a pid.
  fs::remove(s / ".lock");
  fs::create_symlink(target, s / ".lock");
  expect_refused(resume, ".lock");
  fs::remove(s / ".lock");
  // journal.jsonl: once parsed, its tail cut and records appended to the target.
  fs::rename(s / "journal.jsonl", fs::path(dir) / "journal.real");
  fs::create_symlink(target, s / "journal.jsonl");
  expect_refused(resume, "journal.jsonl");
  fs::remove(s / "journal.jsonl");
  fs::rename(fs::path(dir) / "journal.real", s / "journal.jsonl");
  // log.txt
  fs::remove(s / "log.txt");
  fs::create_symlink(target, s / "log.txt");
  expect_refused(resume, "log.txt");
  fs::remove(s / "log.txt");
  // model/ and a pose folder: outputs would land outside.
  const fs::path elsewhere = fs::path(dir) / "elsewhere";
  fs::create_directories(elsewhere);
  fs::remove_all(s / "model");
  fs::create_directory_symlink(elsewhere, s / "model");
  expect_refused("process " + s.string(), "model/");
  EXPECT_TRUE(fs::is_empty(elsewhere));
  fs::remove(s / "model");
  fs::rename(s / "frames" / "h000_v00", elsewhere / "h000_v00");
  fs::create_directory_symlink(elsewhere / "h000_v00", s / "frames" / "h000_v00");
  expect_refused(resume, "frames/<pose>");
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(elsewhere / "h000_v00")) names.insert(e.path().filename());
  EXPECT_EQ(names.size(), 2u);  // nothing moved aside or added there
  fs::remove(s / "frames" / "h000_v00");
  fs::rename(elsewhere / "h000_v00", s / "frames" / "h000_v00");
  CommandResult r = RunRig(resume);
  EXPECT_EQ(r.status, 0) << r.output;
  fs::remove_all(dir);
}

TEST(HostileConfig, FineGridStepsGiveDistinctPoseNames) {
  GridConfig g;
  g.h_min_deg = 0, g.h_max_deg = 1, g.h_step_deg = 0.05;
  g.v_min_deg = 0, g.v_max_deg = 0.03, g.v_step_deg = 0.01;
  std::set<std::string> names;
  const auto poses = PlanGrid(g);
  for (const auto& p : poses) {
    names.insert(p.Name());
    auto back = ParsePoseName(p.Name());
    ASSERT_TRUE(back.ok()) << p.Name();
    EXPECT_NEAR(back->h_deg, p.h_deg, 1e-6);
    EXPECT_NEAR(back->v_deg, p.v_deg, 1e-6);
  }
  EXPECT_EQ(names.size(), poses.size());
  EXPECT_EQ((Pose{32.5, 10}).Name(), "h032.5_v10");  // names of coarser grids are unchanged
  EXPECT_EQ((Pose{0.05, 0}).Name(), "h000.05_v00");

  // End to end: three poses 0.05 degrees apart, each stored once and merged into its own map.
  const std::string dir = testing::FreshTempDir("hostile_finegrid");
  const std::string cfg = testing::WriteSimConfig(dir, R"([grid]
h_min_deg = 0
h_max_deg = 0.1
h_step_deg = 0.05
v_min_deg = 0
v_max_deg = 0
v_step_deg = 10
[sim]
width = 80
height = 60
[bracket]
center_s = 0.02
ev_step = 2
count = 2
)");
  const fs::path s = fs::path(dir) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress --no-process");
  ASSERT_EQ(r.status, 0) << r.output;
  int folders = 0;
  for (const auto& e : fs::directory_iterator(s / "frames")) folders += e.is_directory();
  EXPECT_EQ(folders, 3);
  r = RunRig("process " + s.string() + " --hdr-only");
  EXPECT_EQ(r.status, 0) << r.output;
  int maps = 0;
  for (const auto& e : fs::directory_iterator(s / "hdr")) maps += e.path().extension() == ".exr";
  EXPECT_EQ(maps, 3);
  fs::remove_all(dir);
}

TEST(HostileConfig, AnOversizedGridIsRefusedBeforeAllocatingIt) {
  const std::string dir = testing::FreshTempDir("hostile_biggrid");
  const std::string cfg = testing::WriteSimConfig(dir, R"([grid]
h_min_deg = 0
h_max_deg = 90
h_step_deg = 0.01
v_min_deg = 0
v_max_deg = 60
v_step_deg = 0.01
[motor]
h_limit_max_deg = 95
v_limit_max_deg = 60
)");
  CommandResult r = RunRig("check-config " + cfg);
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("grid.h_step_deg"));
  EXPECT_THAT(r.output, HasSubstr("at most 100000"));
  r = RunRig("capture --config " + cfg + " --out " + dir + "/S --dry-run --no-progress");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("at most 100000"));
  EXPECT_FALSE(fs::exists(fs::path(dir) / "S"));
  // Non-finite numbers in arrays are refused like any other out-of-range value.
  const std::string nan_cfg = testing::WriteSimConfig(dir, "[lamp]\nradiance_rgb = [1.0, nan, 1.0]\n");
  r = RunRig("check-config " + nan_cfg);
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("lamp.radiance_rgb"));
  fs::remove_all(dir);
}

std::vector<nlohmann::json> Records(const fs::path& s) {
  auto c = Journal::Read(s / "journal.jsonl");
  EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().ToString());
  return c.ok() ? c->records : std::vector<nlohmann::json>{};
}

TEST(HostileConfig, AnEditedSessionTomlIsRefusedOnResumeNamingTheSetting) {
  const std::string dir = testing::FreshTempDir("hostile_digest");
  const fs::path s = TinySession(dir);
  // The configuration's digest is journaled at the start.
  auto records = Records(s);
  ASSERT_FALSE(records.empty());
  EXPECT_EQ(records.front()["event"], "config");
  EXPECT_THAT(records.front()["digest"].get<std::string>(), HasSubstr("fnv1a64:"));
  EXPECT_EQ(records.front()["settings"]["sim.seed"], "1");
  // Another seed and one pose deleted: resume would mix two scenes.
  const std::string toml = ReadText(s / "session.toml");
  std::string edited = toml;
  const auto at = edited.find("seed = 1");
  ASSERT_NE(at, std::string::npos);
  edited.replace(at, 8, "seed = 2");
  WriteText(s / "session.toml", edited);
  fs::remove_all(s / "frames" / "h010_v00");
  CommandResult r = RunRig("resume " + s.string() + " --no-progress --no-process");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("sim.seed (1 -> 2)"));
  EXPECT_FALSE(fs::exists(s / "frames" / "h010_v00"));  // nothing captured with the new seed
  WriteText(s / "session.toml", toml);
  r = RunRig("resume " + s.string() + " --no-progress --no-process");
  EXPECT_EQ(r.status, 0) << r.output;
  fs::remove_all(dir);
}

TEST(HostileConfig, DeviceSettingsChangeOnlyThroughTheJournaledSet) {
  const std::string dir = testing::FreshTempDir("hostile_set");
  const fs::path s = TinySession(dir);
  const std::string toml = ReadText(s / "session.toml");
  // Not a device setting: refused, nothing changed.
  CommandResult r = RunRig("resume " + s.string() + " --set grid.h_step_deg=5 --no-progress --no-process");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("not a device setting"));
  r = RunRig("resume " + s.string() + " --set motor.retries=many --no-progress --no-process");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("not an integer"));
  r = RunRig("resume " + s.string() + " --set motor.retries=100000 --no-progress --no-process");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("out of range"));
  EXPECT_EQ(ReadText(s / "session.toml"), toml);
  // A device setting: journaled with old and new value, session.toml rewritten.
  r = RunRig("resume " + s.string() + " --set camera.port=usb:001,004 --set motor.retries=5 --no-progress --no-process");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("setting camera.port: unset -> 'usb:001,004'"));
  EXPECT_THAT(ReadText(s / "session.toml"), HasSubstr("port = 'usb:001,004'"));
  bool journaled = false;
  for (const auto& rec : Records(s)) {
    if (rec["event"] != "settings_changed") continue;
    journaled = true;
    ASSERT_EQ(rec["changes"].size(), 2u);
    EXPECT_EQ(rec["changes"][0]["key"], "camera.port");
    EXPECT_EQ(rec["changes"][0]["old"], "");
    EXPECT_EQ(rec["changes"][1]["old"], "3");
    EXPECT_EQ(rec["changes"][1]["new"], "5");
    EXPECT_EQ(rec["settings"]["motor.retries"], "5");
  }
  EXPECT_TRUE(journaled);
  // The new configuration is the journal's now: resume accepts it; a hand edit is refused.
  r = RunRig("resume " + s.string() + " --no-progress --no-process");
  EXPECT_EQ(r.status, 0) << r.output;
  std::string edited = ReadText(s / "session.toml");
  edited.replace(edited.find("usb:001,004"), 11, "usb:001,005");
  WriteText(s / "session.toml", edited);
  r = RunRig("resume " + s.string() + " --no-progress --no-process");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("camera.port"));
  fs::remove_all(dir);
}

TEST(HostileSession, AFailedStartLeavesNoSessionBehind) {
  const std::string dir = testing::FreshTempDir("hostile_failstart");
  // A sim camera and lamp, a GRBL controller on a port that does not exist.
  const std::string cfg = testing::WriteSimConfig(dir, std::string(kTiny) + R"([motor]
backend = "grbl"
port = "/nonexistent/ttyRIG0"
retries = 0
)");
  const fs::path s = fs::path(dir) / "S";
  CommandResult r = RunRig("capture --config " + cfg + " --out " + s.string() + " --no-progress");
  if (r.output.find("not built") != std::string::npos) GTEST_SKIP() << "no serial backend: " << r.output;
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("nothing was captured"));
  EXPECT_FALSE(fs::exists(s)) << r.output;
  // A folder that existed before is kept (empty), and a new capture into it works.
  fs::create_directories(s);
  r = RunRig("capture --config " + cfg + " --out " + s.string() + " --no-progress");
  EXPECT_NE(r.status, 0) << r.output;
  ASSERT_TRUE(fs::exists(s));
  EXPECT_TRUE(fs::is_empty(s));
  r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress --no-process");
  EXPECT_EQ(r.status, 0) << r.output;
  fs::remove_all(dir);
}

TEST(HostileSession, ARemovedHdrFolderIsMadeAgainByProcess) {
  const std::string dir = testing::FreshTempDir("hostile_hdr");
  const fs::path s = TinySession(dir);
  fs::remove_all(s / "hdr");
  CommandResult r = RunRig("process " + s.string() + " --hdr-only");
  ASSERT_EQ(r.status, 0) << r.output;
  int maps = 0;
  for (const auto& e : fs::directory_iterator(s / "hdr")) maps += e.path().extension() == ".exr";
  EXPECT_EQ(maps, 8);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig

namespace rig {
namespace {

// Issue 20 item 11 and item 8: the smaller ones.
TEST(HostileFiles, SmallerOnesExit2WithAReason) {
  const std::string dir = testing::FreshTempDir("hostile_small");
  // A float TIFF frame: bad input (2), not a failure of the work (1).
  cv::Mat f(20, 30, CV_32FC3, cv::Scalar(0.5, 0.5, 0.5));
  ASSERT_TRUE(cv::imwrite(dir + "/f.tif", f));
  cv::Mat g(20, 30, CV_8UC3, cv::Scalar(100, 100, 100));
  ASSERT_TRUE(cv::imwrite(dir + "/g.png", g));
  WriteText(dir + "/b.txt", "f.tif 0.01\ng.png 0.02\n");
  CommandResult r = RunRig("hdr --list " + dir + "/b.txt --out " + dir + "/o.exr");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("f.tif"));
  // NaN and infinite pixels are refused by tonemap, not turned black silently.
  ExrImage img;
  img.width = 4, img.height = 2;
  for (const char* c : {"R", "G", "B"}) {
    img.channel_names.push_back(c);
    img.channels.push_back(cv::Mat(2, 4, CV_32F, cv::Scalar(1.0)));
  }
  img.channels[1].at<float>(1, 2) = std::numeric_limits<float>::quiet_NaN();
  img.channels[0].at<float>(0, 1) = std::numeric_limits<float>::infinity();
  ASSERT_TRUE(WriteExr(dir + "/nan.exr", img).ok());
  r = RunRig("tonemap " + dir + "/nan.exr --out " + dir + "/nan.png");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("1 sample(s) are NaN and 1 infinite"));
  EXPECT_FALSE(fs::exists(dir + "/nan.png"));
  // An EXR whose data window claims huge dimensions: refused as damaged input (2).
  {
    std::ifstream in(dir + "/nan.exr", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string key = std::string("dataWindow") + '\0' + "box2i" + '\0';
    const auto at = bytes.find(key);
    ASSERT_NE(at, std::string::npos);
    const size_t box = at + key.size() + 4;  // after the attribute's size
    const int32_t huge[4] = {-2000000000, -2000000000, 2000000000, 2000000000};
    bytes.replace(box, 16, reinterpret_cast<const char*>(huge), 16);
    std::ofstream(dir + "/huge.exr", std::ios::binary) << bytes;
  }
  r = RunRig("tonemap " + dir + "/huge.exr --out " + dir + "/huge.png");
  EXPECT_EQ(r.status, 2) << r.output;
  fs::remove_all(dir);
}

TEST(HostileFiles, RenderIntoAMissingFolderSaysSo) {
  const std::string dir = testing::FreshTempDir("hostile_render_out");
  auto r = RunRig("render " + dir + "/none.exr --light 0,45 --out " + dir + "/missing_dir/x.png");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("missing_dir"));
  EXPECT_THAT(r.output, HasSubstr("does not exist"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig

namespace rig {
namespace {

// Item 8 (already fixed on main, kept by this test): an image smaller than --downsample is
// refused with exit 2, and no OpenCV warning reaches the terminal.
TEST(HostileFiles, FitLpRefusesImagesSmallerThanTheDownsampleFactor) {
  const std::string dir = testing::FreshTempDir("hostile_lp_small");
  std::ofstream lp(dir + "/s.lp");
  lp << "12\n";
  for (int i = 0; i < 12; ++i) {
    const double az = i * 2 * M_PI / 12, e = 0.6;
    cv::Mat img(3, 4, CV_8UC3, cv::Scalar(40 + 10 * i, 80, 120));
    cv::imwrite(dir + "/i" + std::to_string(i) + ".jpg", img);
    lp << "i" << i << ".jpg " << std::cos(e) * std::cos(az) << " " << std::cos(e) * std::sin(az)
       << " " << std::sin(e) << "\n";
  }
  lp.close();
  auto r = RunRig("fit --lp " + dir + "/s.lp --downsample 8 --out " + dir + "/m");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("downsample"));
  EXPECT_THAT(r.output, Not(HasSubstr("[ WARN")));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig
