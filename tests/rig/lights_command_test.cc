// `rig lights` as a user runs it: on a small synthetic .lp capture it writes SUB.lp (the chosen
// images, readable by `rig fit --lp`) and the report; bad input exits 2 naming the option or
// the file; --help describes the command.
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "process/model/lp.h"
#include "tests/support/lp_capture.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

TEST(LightsCommand, WritesTheChosenLightsAndTheReportAndTheSubsetFits) {
  const std::string dir = testing::FreshTempDir("lights-command");
  const std::string lp = testing::WriteLpCapture(dir, 48, 40);
  auto r = RunRig("lights --lp " + lp + " --choose 12 --out " + dir + "/sub/dirs.lp --report " +
                  dir + "/sub/lights.md");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("12 lights"));
  auto sub = ReadLp(dir + "/sub/dirs.lp");
  ASSERT_TRUE(sub.ok()) << sub.error().ToString();
  EXPECT_EQ(sub->size(), 12u);
  for (const auto& e : *sub) EXPECT_TRUE(fs::exists(e.image)) << e.image;
  const std::string report = testing::ReadText(dir + "/sub/lights.md");
  EXPECT_THAT(report, HasSubstr("seed: the highest light"));
  EXPECT_THAT(report, HasSubstr("largest predicted reduction"));
  r = RunRig("fit --lp " + dir + "/sub/dirs.lp --max-bytes-per-pixel 40 --out " + dir + "/model");
  EXPECT_EQ(r.status, 0) << r.output;
}

TEST(LightsCommand, RefusesBadInputNamingTheOptionOrTheFile) {
  const std::string dir = testing::FreshTempDir("lights-command-bad");
  const std::string lp = testing::WriteLpCapture(dir, 24, 20);
  auto r = RunRig("lights --lp " + lp + " --choose 40 --out " + dir + "/sub.lp");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("--choose"));
  r = RunRig("lights --lp " + dir + "/none.lp --choose 4 --out " + dir + "/sub.lp");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("none.lp"));
  EXPECT_FALSE(fs::exists(dir + "/sub.lp"));
  r = RunRig("lights --help");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("never an image not yet chosen"));
}

}  // namespace
}  // namespace rig
