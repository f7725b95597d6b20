// `rig process SESSION` on a simulated dry-run session: every pose merged through one stored
// response, up-to-date maps skipped unless --force, a damaged frame fails its own pose only and
// the summary names it, --new-response keeps the old curve, bad sessions exit 2.
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <ImfCompression.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

#include "process/io/exr_io.h"
#include "tests/support/run_rig.h"
#include "tests/support/session_model.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

class ProcessCommand : public ::testing::Test {
 protected:
  // One captured session (frames only, no processing), copied by each test.
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::FreshTempDir("process_command"));
    const std::string cfg = testing::WriteSimConfig(*dir_, "[sim]\nwidth = 96\nheight = 72\n");
    auto r = RunRig("capture --config " + cfg + " --out " + *dir_ + "/S --dry-run --no-progress --no-process");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static fs::path Copy(const std::string& name) {
    const fs::path copy = fs::path(*dir_) / name;
    fs::remove_all(copy);
    fs::copy(fs::path(*dir_) / "S", copy, fs::copy_options::recursive);
    fs::remove(copy / ".lock");
    return copy;
  }
  static int CountExr(const fs::path& session) {
    int n = 0;
    if (!fs::exists(session / "hdr")) return 0;
    for (const auto& e : fs::directory_iterator(session / "hdr")) n += e.path().extension() == ".exr";
    return n;
  }
  static std::string* dir_;
};
std::string* ProcessCommand::dir_ = nullptr;

// [process] hdr_compression reaches the session's maps: ZIP by default, the one asked for
// after an edit (the pixels are the same: every choice is lossless).
TEST_F(ProcessCommand, HdrCompressionOfTheSessionIsTheMapsCompression) {
  auto stored = [](const fs::path& path) {
    Imf::InputFile in(path.c_str());
    return in.header().compression();
  };
  const fs::path s = Copy("compression");
  auto first = RunRig("process " + s.string() + " --hdr-only");
  ASSERT_EQ(first.status, 0) << first.output;
  const fs::path map = s / "hdr" / "h020_v10.exr";
  EXPECT_EQ(stored(map), Imf::ZIP_COMPRESSION);
  auto zip_pixels = ReadExr(map.string());
  ASSERT_TRUE(zip_pixels.ok());
  {
    std::ifstream in(s / "session.toml");
    std::stringstream text;
    text << in.rdbuf();
    std::string toml = text.str();
    const std::string was = "hdr_compression = 'zip'";
    const size_t at = toml.find(was);
    ASSERT_NE(at, std::string::npos) << toml;
    toml.replace(at, was.size(), "hdr_compression = 'none'");
    std::ofstream(s / "session.toml") << toml;
  }
  auto again = RunRig("process " + s.string() + " --hdr-only --force");
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_EQ(stored(map), Imf::NO_COMPRESSION);
  auto none_pixels = ReadExr(map.string());
  ASSERT_TRUE(none_pixels.ok());
  ASSERT_EQ(none_pixels->channels.size(), zip_pixels->channels.size());
  for (size_t i = 0; i < none_pixels->channels.size(); ++i) {
    EXPECT_EQ(cv::norm(none_pixels->channels[i], zip_pixels->channels[i], cv::NORM_INF), 0.0);
  }
}

TEST_F(ProcessCommand, MergesEveryPoseThroughOneStoredResponseAndFitsTheModel) {
  const fs::path s = Copy("all");
  ASSERT_EQ(CountExr(s), 0);
  auto r = RunRig("process " + s.string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("40 merged, 0 up to date, 0 failed"));
  EXPECT_EQ(CountExr(s), 40);
  EXPECT_TRUE(fs::exists(s / "calib" / "response.csv"));
  EXPECT_TRUE(testing::SessionHasModel(s));
  // Every map names the same response, its pose and its exposures.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.output, m, std::regex("response (g-[0-9a-f]+)"))) << r.output;
  for (const char* pose : {"h000_v00", "h020_v10", "h090_v30"}) {
    auto img = ReadExr((s / "hdr" / (std::string(pose) + ".exr")).string());
    ASSERT_TRUE(img.ok()) << img.error().ToString();
    std::map<std::string, std::string> a(img->attributes.begin(), img->attributes.end());
    bool id = false, exposures = false;
    for (const auto& [k, v] : a) {
      id = id || v.find(m[1].str()) != std::string::npos;
      exposures = exposures || k.find("exposure") != std::string::npos;
    }
    EXPECT_TRUE(id) << pose;
    EXPECT_TRUE(exposures) << pose;
    EXPECT_EQ(a["pose"], pose);
  }
}

TEST_F(ProcessCommand, UpToDateMapsAreSkippedUnlessForced) {
  const fs::path s = Copy("skip");
  ASSERT_EQ(RunRig("process " + s.string() + " --hdr-only").status, 0);
  auto again = RunRig("process " + s.string() + " --hdr-only");
  ASSERT_EQ(again.status, 0) << again.output;
  EXPECT_THAT(again.output, HasSubstr("0 merged, 40 up to date"));
  // One map gone: only that pose is merged again.
  fs::remove(s / "hdr" / "h020_v10.exr");
  auto one = RunRig("process " + s.string() + " --hdr-only");
  ASSERT_EQ(one.status, 0) << one.output;
  EXPECT_THAT(one.output, HasSubstr("1 merged, 39 up to date"));
  EXPECT_TRUE(fs::exists(s / "hdr" / "h020_v10.exr"));
  // Another merge weighting in session.toml: every map is stale, and records the new one.
  {
    std::ifstream in(s / "session.toml");
    std::stringstream text;
    text << in.rdbuf();
    std::string toml = text.str();
    const size_t at = toml.find("merge_weighting = 'noise'");
    ASSERT_NE(at, std::string::npos) << toml;
    toml.replace(at, std::string("merge_weighting = 'noise'").size(), "merge_weighting = 'hat'");
    std::ofstream(s / "session.toml") << toml;
  }
  auto reweighted = RunRig("process " + s.string() + " --hdr-only");
  ASSERT_EQ(reweighted.status, 0) << reweighted.output;
  EXPECT_THAT(reweighted.output, HasSubstr("40 merged, 0 up to date"));
  auto header = ReadExrAttributes((s / "hdr" / "h020_v10.exr").string());
  ASSERT_TRUE(header.ok());
  EXPECT_EQ(header->at("merge_weighting_option"), "hat");
  EXPECT_EQ(header->at("merge_weighting"), "hat");
  auto forced = RunRig("process " + s.string() + " --hdr-only --force");
  ASSERT_EQ(forced.status, 0) << forced.output;
  EXPECT_THAT(forced.output, HasSubstr("40 merged, 0 up to date"));
  // --new-response: the curve is recovered again; the old one is kept beside it.
  auto fresh = RunRig("process " + s.string() + " --hdr-only --new-response");
  ASSERT_EQ(fresh.status, 0) << fresh.output;
  EXPECT_THAT(fresh.output, HasSubstr("40 merged"));
  EXPECT_TRUE(fs::exists(s / "calib" / "response.previous.csv"));
  EXPECT_TRUE(fs::exists(s / "calib" / "response.csv"));
}

TEST_F(ProcessCommand, ADamagedFrameFailsItsPoseOnlyAndTheSummaryNamesIt) {
  const fs::path s = Copy("damaged");
  ASSERT_EQ(RunRig("process " + s.string() + " --hdr-only").status, 0);
  const fs::path victim = s / "frames" / "h020_v10" / "2_0.01000.jpg";
  ASSERT_TRUE(fs::exists(victim));
  const fs::path kept = s.parent_path() / "kept.jpg";
  fs::copy_file(victim, kept, fs::copy_options::overwrite_existing);
  fs::resize_file(victim, fs::file_size(victim) / 3);
  const auto before = fs::last_write_time(s / "hdr" / "h000_v00.exr");
  auto r = RunRig("process " + s.string() + " --force --hdr-only");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("39 merged, 0 up to date, 1 failed"));
  EXPECT_THAT(r.output, HasSubstr("pose h020_v10"));
  EXPECT_THAT(r.output, HasSubstr(victim.string()));
  EXPECT_THAT(r.output, HasSubstr("damaged since capture"));
  EXPECT_GT(fs::last_write_time(s / "hdr" / "h000_v00.exr"), before);  // the others merged again
  // The frame itself is never touched.
  EXPECT_EQ(fs::file_size(victim), fs::file_size(kept) / 3);
  // A second run without --force retries the failed pose (its frame is newer than its map)
  // and keeps the others: still failing, still listed.
  auto retry = RunRig("process " + s.string() + " --hdr-only");
  EXPECT_EQ(retry.status, 1) << retry.output;
  EXPECT_THAT(retry.output, HasSubstr("0 merged, 39 up to date, 1 failed"));
  EXPECT_THAT(retry.output, HasSubstr("pose h020_v10"));
  // Repaired (the captured bytes back): merged again, nothing fails.
  fs::copy_file(kept, victim, fs::copy_options::overwrite_existing);
  auto repaired = RunRig("process " + s.string() + " --hdr-only");
  EXPECT_EQ(repaired.status, 0) << repaired.output;
  EXPECT_THAT(repaired.output, HasSubstr("1 merged, 39 up to date, 0 failed"));
}

TEST_F(ProcessCommand, AFolderThatIsNoSessionIsBadInput) {
  const fs::path empty = fs::path(*dir_) / "not_a_session";
  fs::create_directories(empty);
  auto r = RunRig("process " + empty.string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr(empty.string()));
  auto missing = RunRig("process");
  EXPECT_EQ(missing.status, 2) << missing.output;
}

}  // namespace
}  // namespace rig
