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
    EXPECT_THAT(r.output, ::testing::HasSubstr(": ok: 40 poses"));
  }
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
