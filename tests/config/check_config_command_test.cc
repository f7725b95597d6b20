// `rig check-config`: exit 0 on every shipped file, 2 on a broken one with every error listed.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/support/run_rig.h"

namespace {

using rig::testing::CommandResult;
using rig::testing::RunRig;

TEST(CheckConfigCommand, AcceptsEveryShippedConfig) {
  std::string dir = std::string(std::getenv("RIG_SOURCE_DIR")) + "/config";
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.path().extension() != ".toml") continue;
    CommandResult r = RunRig("check-config " + e.path().string());
    EXPECT_EQ(r.status, 0) << r.output;
    EXPECT_THAT(r.output, ::testing::HasSubstr(": ok: "));
  }
}

// The full-azimuth example: 12 azimuths x 5 elevations, inside its own pose limits; the same
// grid with the limits of a shorter arm is refused, naming both.
TEST(CheckConfigCommand, TheFullAzimuthExampleIsValidAndItsLimitsAreWhatHoldsItsGrid) {
  const std::string path = std::string(std::getenv("RIG_SOURCE_DIR")) + "/config/grbl-dome.toml";
  CommandResult r = RunRig("check-config " + path);
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, ::testing::HasSubstr(": ok: 60 poses"));
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string key = "h_limit_max_deg = 335";
  ASSERT_NE(text.find(key), std::string::npos);
  text.replace(text.find(key), key.size(), "h_limit_max_deg = 300");
  auto bad = std::filesystem::temp_directory_path() / "rig_check_config_dome_short.toml";
  std::ofstream(bad) << text;
  CommandResult b = RunRig("check-config " + bad.string());
  EXPECT_EQ(b.status, 2) << b.output;
  EXPECT_THAT(b.output, ::testing::HasSubstr("grid 0 .. 330 leaves the motor's soft limits 0 .. 300"));
  std::filesystem::remove(bad);
}

TEST(CheckConfigCommand, ListsEveryErrorWithLocationAndExitsTwo) {
  auto path = std::filesystem::temp_directory_path() / "rig_check_config_bad.toml";
  std::ofstream(path) << "[grid]\nh_step_deg = 7\n[bracket]\ncenter_s = 0.02\ncount = 3\n"
                         "[camera]\nbackend = \"sim\"\nretries = -1\n[motor]\nbackend = \"sim\"\n"
                         "[lamp]\nbackend = \"sim\"\nwarmup = 1\n";
  CommandResult r = RunRig("check-config " + path.string());
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, ::testing::HasSubstr(path.string() + ":2:14: grid.h_step_deg"));
  EXPECT_THAT(r.output, ::testing::HasSubstr(path.string() + ":8:11: camera.retries"));
  EXPECT_THAT(r.output, ::testing::HasSubstr("did you mean 'warmup_s'?"));
  EXPECT_THAT(r.output, ::testing::HasSubstr("3 errors"));
}

TEST(CheckConfigCommand, BadUsageExitsTwoAndHelpExitsZero) {
  EXPECT_EQ(RunRig("check-config").status, 2);
  EXPECT_EQ(RunRig("check-config --help").status, 0);
  EXPECT_EQ(RunRig("no-such-command").status, 2);
  CommandResult v = RunRig("--version");
  EXPECT_EQ(v.status, 0);
  EXPECT_THAT(v.output, ::testing::HasSubstr("sim-camera"));
}

}  // namespace
