// The built-in simulated rig: config/sim.toml compiled in, found from any working folder.
#include <unistd.h>

#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/builtin_config.h"
#include "sim/evaluation.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

TEST(BuiltInConfig, IsTheRepositorysSimTomlAndIsFoundFromAnyFolder) {
  ConfigResult file = LoadConfig(testing::SourceDir() + "/config/sim.toml");
  ASSERT_TRUE(file.ok());
  const auto cwd = std::filesystem::current_path();
  const std::string elsewhere = testing::FreshTempDir("builtin_config");
  std::filesystem::current_path(elsewhere);  // no config/ folder here
  ConfigResult built_in = LoadConfigOrBuiltIn("");
  ConfigResult relative = LoadConfig("config/sim.toml");
  std::filesystem::current_path(cwd);
  ASSERT_TRUE(built_in.ok()) << built_in.AsError().ToString();
  EXPECT_FALSE(relative.ok());  // what `rig evaluate --dry-run` used to read
  EXPECT_EQ(ToToml(built_in.config), ToToml(file.config));
  EXPECT_EQ(built_in.config.source, kBuiltInSimConfigName);
  // The evaluation's default is the built-in configuration, not a path.
  EXPECT_TRUE(EvaluationRequest{}.config_path.empty());
  std::filesystem::remove_all(elsewhere);
}

}  // namespace
}  // namespace rig
