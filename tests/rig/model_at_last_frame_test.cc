// The model at the last frame: `rig capture --dry-run` fits its model from the radiance maps it
// kept in memory while it merged them (no map is read back), and that model equals the one
// fitted from the map files value for value; `rig resume` of the finished session reads the
// stored maps into memory while it verifies, and fits the same model again.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "capture/session/session_store.h"
#include "process/io/exr_io.h"
#include "capture/daemon/session_model.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using testing::RunRig;

std::string ReadText(const fs::path& p) { return testing::ReadText(p.string()); }

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

void ExpectSameModel(const fs::path& a_path, const fs::path& b_path) {
  auto a = ReadExr(a_path.string()), b = ReadExr(b_path.string());
  ASSERT_TRUE(a.ok()) << a.error().ToString();
  ASSERT_TRUE(b.ok()) << b.error().ToString();
  ASSERT_EQ(a->channel_names, b->channel_names);
  ASSERT_GE(a->channel_names.size(), 3u);
  for (size_t c = 0; c < a->channels.size(); ++c) {
    EXPECT_EQ(cv::norm(a->channels[c], b->channels[c], cv::NORM_INF), 0.0) << a->channel_names[c];
  }
  EXPECT_EQ(a->attributes.at("order"), b->attributes.at("order"));
}

TEST(ModelAtLastFrame, TheCapturedModelComesFromMemoryAndEqualsTheModelFromTheFiles) {
  const std::string dir = testing::FreshTempDir("model_at_last_frame");
  // The harmonic family's model (the PCA family's from memory and from files: pca_session_test).
  const std::string cfg = testing::WriteSimConfig(
      dir, "[sim]\nwidth = 96\nheight = 72\n[process]\nmodel_family = \"harmonic\"\n");
  const fs::path s = fs::path(dir) / "S";
  auto r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string log = ReadText(s / "log.txt");
  EXPECT_EQ(Count(log, "model fitted from the maps in memory"), 1) << log;
  EXPECT_EQ(Count(log, "model fitted from the radiance map files"), 0) << log;
  // Its order and λ were chosen from the Gram matrix accumulated as the maps arrived.
  EXPECT_EQ(Count(log, "accumulated as the maps arrived"), 1) << log;
  fs::copy_file(s / "model" / "model.exr", fs::path(dir) / "from_memory.exr");

  {
    // The batch fit from the files, into the session's model/ (as `rig process` without
    // maps in memory would).
    auto session = Session::OpenExisting(s);
    ASSERT_TRUE(session.ok()) << session.error().ToString();
    Status st = FitSessionModel(*session, nullptr);
    ASSERT_TRUE(st.ok()) << st.error().ToString();
  }
  ExpectSameModel(fs::path(dir) / "from_memory.exr", s / "model" / "model.exr");

  // Resuming the finished session: the stored maps are read into memory, the model refitted.
  r = RunRig("resume " + s.string() + " --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(Count(ReadText(s / "log.txt"), "model fitted from the maps in memory"), 2);
  EXPECT_EQ(Count(ReadText(s / "log.txt"), "accumulated as the maps arrived"), 2);
  ExpectSameModel(fs::path(dir) / "from_memory.exr", s / "model" / "model.exr");
  fs::remove_all(dir);
}

// With the lamp's radiance taken from a reference patch (known only once every map is in),
// nothing is accumulated ahead: the fit computes its Gram matrix from the maps in memory, and
// the model still equals the one from the files.
TEST(ModelAtLastFrame, AReferencePatchLeavesTheGramToTheFitAndTheSameModel) {
  const std::string dir = testing::FreshTempDir("model_at_last_frame_patch");
  const std::string cfg = testing::WriteSimConfig(
      dir, "[sim]\nwidth = 96\nheight = 72\n\n[process]\nreference_patch_px = [40, 30, 8, 6]\n"
           "model_family = \"harmonic\"\n");
  const fs::path s = fs::path(dir) / "S";
  auto r = RunRig("capture --config " + cfg + " --out " + s.string() + " --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string log = ReadText(s / "log.txt");
  EXPECT_EQ(Count(log, "lamp radiance from the reference patch"), 1) << log;
  EXPECT_EQ(Count(log, "model fitted from the maps in memory"), 1) << log;
  EXPECT_EQ(Count(log, "accumulated as the maps arrived"), 0) << log;
  fs::copy_file(s / "model" / "model.exr", fs::path(dir) / "from_memory.exr");
  {
    auto session = Session::OpenExisting(s);
    ASSERT_TRUE(session.ok()) << session.error().ToString();
    Status st = FitSessionModel(*session, nullptr);
    ASSERT_TRUE(st.ok()) << st.error().ToString();
  }
  ExpectSameModel(fs::path(dir) / "from_memory.exr", s / "model" / "model.exr");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig
