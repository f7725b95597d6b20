// `rig capture --set KEY=VALUE`: a setting of the configuration overridden for one session, as
// `rig resume --set` changes a device setting; the session's session.toml records the result.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using testing::RunRig;

std::string Slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string Cfg() { return testing::SourceDir() + "/config/sim.toml"; }

TEST(CaptureSet, OverridesTheCameraAndTheGridForThisSessionAndRecordsThem) {
  const std::string dir = testing::FreshTempDir("capture_set");
  auto r = RunRig("capture --config " + Cfg() + " --out " + dir +
                  "/S --dry-run --no-progress --no-process --set camera.iso=200 --set grid.h_max_deg=20 "
                  "--set grid.v_max_deg=10 --set bracket.count=2 --set sim.width=48 --set sim.height=36");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("setting camera.iso: "));
  EXPECT_THAT(r.output, HasSubstr("setting camera.iso: unset -> '200'"));
  EXPECT_THAT(r.output, HasSubstr("poses 6  frames 12"));  // h 0,10,20 x v 0,10, 2 exposures
  const std::string stored = Slurp(std::filesystem::path(dir) / "S" / "session.toml");
  EXPECT_THAT(stored, HasSubstr("iso = '200'"));
  EXPECT_THAT(stored, HasSubstr("h_max_deg = 20.0"));
  std::filesystem::remove_all(dir);
}

TEST(CaptureSet, AnUnknownKeyOrAValueOfTheWrongTypeIsRefusedBeforeASessionIsMade) {
  const std::string dir = testing::FreshTempDir("capture_set_bad");
  auto unknown = RunRig("capture --config " + Cfg() + " --out " + dir + "/S --dry-run --set camera.isso=200");
  EXPECT_EQ(unknown.status, 2) << unknown.output;
  EXPECT_THAT(unknown.output, HasSubstr("camera.isso"));
  EXPECT_THAT(unknown.output, HasSubstr("unknown key"));
  EXPECT_THAT(unknown.output, HasSubstr("did you mean 'iso'?"));
  auto wrong = RunRig("capture --config " + Cfg() + " --out " + dir + "/S --dry-run --set grid.h_step_deg=ten");
  EXPECT_EQ(wrong.status, 2) << wrong.output;
  EXPECT_THAT(wrong.output, HasSubstr("'ten' is not a finite number"));
  auto invalid = RunRig("capture --config " + Cfg() + " --out " + dir + "/S --dry-run --set grid.h_step_deg=7");
  EXPECT_EQ(invalid.status, 2) << invalid.output;
  EXPECT_THAT(invalid.output, HasSubstr("grid.h_step_deg"));
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::path(dir) / "S"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rig
