// Configuration: every class of bad input gives its own message at its own location.
#include "config/config.h"
#include "process/io/exr_io.h"  // the writer's compression names

#include <cstdlib>
#include <filesystem>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace rig {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

const char* kMinimal = R"([bracket]
center_s = 0.02
count = 5

[camera]
backend = "sim"

[motor]
backend = "sim"

[lamp]
backend = "sim"
)";

// Finds the one diagnostic for `key_path`; fails the test if there is not exactly one.
ConfigDiagnostic Only(const ConfigResult& r, const std::string& key_path) {
  std::vector<ConfigDiagnostic> found;
  for (const auto& d : r.diagnostics)
    if (d.key_path == key_path) found.push_back(d);
  EXPECT_EQ(found.size(), 1u) << "diagnostics for " << key_path;
  return found.empty() ? ConfigDiagnostic{} : found[0];
}

TEST(Config, MinimalConfigIsValidAndFillsDefaults) {
  ConfigResult r = ParseConfig(kMinimal, "min.toml");
  ASSERT_TRUE(r.ok()) << r.AsError().ToString();
  EXPECT_EQ(r.config.grid.h_max_deg, 90);
  EXPECT_EQ(r.config.grid.v_step_deg, 10);
  EXPECT_EQ(r.config.bracket.count, 5);
  EXPECT_EQ(r.config.process.order, -1);  // auto
}

TEST(Config, SyntaxErrorHasLineAndColumn) {
  ConfigResult r = ParseConfig("[camera]\nbackend = \"sim\n", "syn.toml");
  ASSERT_EQ(r.diagnostics.size(), 1u);
  EXPECT_EQ(r.diagnostics[0].file, "syn.toml");
  EXPECT_EQ(r.diagnostics[0].line, 2);
  EXPECT_GT(r.diagnostics[0].column, 0);
}

TEST(Config, WrongTypeNamesKeyAndPosition) {
  std::string text = std::string(kMinimal) + "\n[grid]\nh_step_deg = \"ten\"\n";
  ConfigResult r = ParseConfig(text, "t.toml");
  auto d = Only(r, "grid.h_step_deg");
  EXPECT_THAT(d.message, HasSubstr("expected a number"));
  EXPECT_EQ(d.line, 15);
  EXPECT_EQ(d.column, 14);
}

// A lamp inside the field it lights is a mistake, refused naming the key; 300 mm over a
// 100 mm field is a near lamp and accepted.
TEST(Config, ALampInsideTheFieldItLightsIsRefused) {
  std::string text = std::string(kMinimal) +
                     "\n[light_frame]\nlamp_distance_mm = 30\nfield_height_mm = 100\n";
  auto d = Only(ParseConfig(text, "t.toml"), "light_frame.lamp_distance_mm");
  EXPECT_THAT(d.message, HasSubstr("inside the field it lights"));
  std::string near = std::string(kMinimal) +
                     "\n[light_frame]\nlamp_distance_mm = 300\nfield_height_mm = 100\n";
  EXPECT_TRUE(ParseConfig(near, "t.toml").ok());
}

// The surface's depth relative to the arm's centre: read, written back (only when set, so a
// session without it keeps its resolved text), and refused naming the key when it leaves the
// lamp no farther from the surface than the field is tall, or is not a finite number.
TEST(Config, TheSurfaceDepthIsReadWrittenAndRefusedWhereTheLampCannotBeFarther) {
  const std::string head = std::string(kMinimal) +
                           "\n[light_frame]\nlamp_distance_mm = 300\nfield_height_mm = 100\n";
  auto ok = ParseConfig(head + "surface_depth_mm = -50\n", "t.toml");
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(ok.config.light_frame.surface_depth_mm, -50);
  const std::string text = ToToml(ok.config);
  EXPECT_THAT(text, HasSubstr("surface_depth_mm = -50"));
  auto back = ParseConfig(text, "back.toml");
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back.config.light_frame.surface_depth_mm, -50);
  auto unset = ParseConfig(head, "t.toml");
  ASSERT_TRUE(unset.ok());
  EXPECT_EQ(unset.config.light_frame.surface_depth_mm, 0);
  EXPECT_THAT(ToToml(unset.config), Not(HasSubstr("surface_depth_mm")));
  // 300 mm from the centre, a surface 250 mm behind it in a 100 mm field: refused.
  for (const char* z : {"-250", "200.5"}) {
    auto d = Only(ParseConfig(head + "surface_depth_mm = " + z + "\n", "t.toml"),
                  "light_frame.surface_depth_mm");
    EXPECT_THAT(d.message, HasSubstr("|surface_depth_mm| + field_height_mm must stay below"));
  }
  auto d = Only(ParseConfig(head + "surface_depth_mm = nan\n", "t.toml"),
                "light_frame.surface_depth_mm");
  EXPECT_THAT(d.message, HasSubstr("out of range"));
  // A far lamp ignores it.
  EXPECT_TRUE(ParseConfig(std::string(kMinimal) + "\n[light_frame]\nsurface_depth_mm = -500\n",
                          "t.toml").ok());
}

TEST(Config, OutOfRangeNamesTheRange) {
  std::string text = std::string(kMinimal) + "\n[process]\nthreads = 0\n";
  auto d = Only(ParseConfig(text, "t.toml"), "process.threads");
  EXPECT_THAT(d.message, HasSubstr("out of range [1, 256]"));
  EXPECT_EQ(d.line, 15);
}

TEST(Config, GridStepThatDoesNotDivideSpanIsInconsistent) {
  std::string text = std::string(kMinimal) + "\n[grid]\nh_step_deg = 7\n";
  auto d = Only(ParseConfig(text, "t.toml"), "grid.h_step_deg");
  EXPECT_THAT(d.message, HasSubstr("does not divide the span"));
  EXPECT_EQ(d.line, 15);
}

TEST(Config, NonIncreasingExposuresAreInconsistent) {
  ConfigResult r = ParseConfig(R"([bracket]
exposure_times_s = [0.01, 0.01, 0.04]
[camera]
backend = "sim"
[motor]
backend = "sim"
[lamp]
backend = "sim"
)", "t.toml");
  auto d = Only(r, "bracket.exposure_times_s");
  EXPECT_THAT(d.message, HasSubstr("strictly increasing"));
  EXPECT_EQ(d.line, 2);
}

TEST(Config, UnknownKeySuggestsTheNearestKnownOne) {
  std::string text = std::string(kMinimal) + "\n[camera.x]\n";
  text = R"([bracket]
exposure_time = [0.01, 0.02]
exposure_times_s = [0.01, 0.02]
[camera]
backend = "sim"
[motor]
backend = "sim"
setle_time_s = 1
[lamp]
backend = "sim"
)";
  ConfigResult r = ParseConfig(text, "t.toml");
  auto d = Only(r, "bracket.exposure_time");
  EXPECT_THAT(d.message, HasSubstr("unknown key 'exposure_time' in [bracket]"));
  EXPECT_THAT(d.message, HasSubstr("did you mean 'exposure_times_s'?"));
  EXPECT_EQ(d.line, 2);
  EXPECT_EQ(d.column, 1);
  auto d2 = Only(r, "motor.setle_time_s");
  EXPECT_THAT(d2.message, HasSubstr("did you mean 'settle_time_s'?"));
}

TEST(Config, UnknownTableIsAnError) {
  std::string text = std::string(kMinimal) + "\n[lamps]\nbackend = \"sim\"\n";
  auto d = Only(ParseConfig(text, "t.toml"), "lamps");
  EXPECT_THAT(d.message, HasSubstr("did you mean 'lamp'?"));
}

TEST(Config, MissingRequiredKeyAndTableAreReported) {
  ConfigResult r = ParseConfig(R"([bracket]
center_s = 0.02
count = 3
[camera]
iso = "100"
[lamp]
backend = "sim"
)", "t.toml");
  auto d = Only(r, "camera.backend");
  EXPECT_THAT(d.message, HasSubstr("missing required key"));
  EXPECT_EQ(d.line, 4);  // points at the [camera] table
  auto m = Only(r, "motor");
  EXPECT_THAT(m.message, HasSubstr("missing required table"));
}

TEST(Config, InvalidChoiceListsChoicesAndSuggests) {
  std::string text = kMinimal;
  text.replace(text.find("backend = \"sim\""), 15, "backend = \"gphoto\"");
  auto d = Only(ParseConfig(text, "t.toml"), "camera.backend");
  EXPECT_THAT(d.message, HasSubstr("not one of: sim, gphoto2"));
  EXPECT_THAT(d.message, HasSubstr("did you mean 'gphoto2'?"));
}

// The session's EXR compressions (radiance maps, model): config (below process) keeps its own
// list of names; every name the writer knows is accepted, and nothing else.
TEST(Config, HdrAndModelCompressionAcceptExactlyTheWritersNames) {
  // Radiance maps are kept losslessly; a model file may also be written with the lossy DWA.
  for (const std::string key : {"hdr_compression", "model_compression"}) {
    const auto& names = key == "hdr_compression" ? ExrCompressionNames() : ExrModelCompressionNames();
    for (const std::string& name : names) {
      ConfigResult r = ParseConfig(std::string(kMinimal) + "\n[process]\n" + key + " = \"" +
                                       name + "\"\n", "t.toml");
      ASSERT_TRUE(r.ok()) << key << " " << name << ": " << r.AsError().ToString();
      EXPECT_EQ(key == "hdr_compression" ? r.config.process.hdr_compression
                                         : r.config.process.model_compression,
                name);
    }
    auto d = Only(ParseConfig(std::string(kMinimal) + "\n[process]\n" + key + " = \"lzw\"\n",
                              "t.toml"),
                  "process." + key);
    std::string listed;
    for (const std::string& name : names) listed += (listed.empty() ? "" : ", ") + name;
    EXPECT_THAT(d.message, HasSubstr("not one of: " + listed));
  }
  EXPECT_FALSE(
      ParseConfig(std::string(kMinimal) + "\n[process]\nhdr_compression = \"dwaa\"\n", "t.toml").ok());
  const Config defaults = ParseConfig(kMinimal, "t.toml").config;
  EXPECT_EQ(defaults.process.hdr_compression, "zip");
  EXPECT_EQ(defaults.process.model_compression, "none");
}

TEST(Config, AllErrorsAreReportedAtOnceInFileOrder) {
  ConfigResult r = ParseConfig(R"([grid]
h_step_deg = 7
v_max_deg = "thirty"
[bracket]
center_s = 0.02
count = 3
[camera]
backend = "sim"
retries = -1
[motor]
backend = "grbl"
[lamp]
backend = "sim"
radiance_rgb = [1, 2]
)", "t.toml");
  ASSERT_GE(r.diagnostics.size(), 5u);
  for (size_t i = 1; i < r.diagnostics.size(); ++i)
    EXPECT_LE(r.diagnostics[i - 1].line, r.diagnostics[i].line);
  Only(r, "grid.h_step_deg");
  Only(r, "grid.v_max_deg");
  Only(r, "camera.retries");
  Only(r, "lamp.radiance_rgb");
  EXPECT_THAT(Only(r, "motor.port").message, HasSubstr("needs port, usb_vid_pid or usb_serial"));
  EXPECT_THAT(r.AsError().ToString(), HasSubstr("t.toml:9:11: camera.retries"));
}

TEST(Config, OrderAcceptsAutoOrInteger) {
  std::string text = std::string(kMinimal) + "\n[process]\norder = 3\n";
  ConfigResult r = ParseConfig(text, "t.toml");
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r.config.process.order, 3);
  text = std::string(kMinimal) + "\n[process]\norder = \"three\"\n";
  EXPECT_THAT(Only(ParseConfig(text, "t.toml"), "process.order").message,
              HasSubstr("an integer or \"auto\""));
}

TEST(Config, ResolvedConfigRoundTripsThroughToml) {
  ConfigResult r = ParseConfig(kMinimal, "min.toml");
  ASSERT_TRUE(r.ok());
  r.config.grid.h_step_deg = 15;
  r.config.sim.camera.fail_capture_at = {3, 9};
  r.config.process.order = 4;
  std::string text = ToToml(r.config);
  ConfigResult back = ParseConfig(text, "resolved.toml");
  ASSERT_TRUE(back.ok()) << back.AsError().ToString() << "\n" << text;
  EXPECT_EQ(back.config.grid.h_step_deg, 15);
  EXPECT_EQ(back.config.sim.camera.fail_capture_at, (std::vector<int>{3, 9}));
  EXPECT_EQ(back.config.process.order, 4);
  EXPECT_EQ(ToToml(back.config), text);
}

TEST(Config, EveryShippedConfigIsValid) {
  const char* src = std::getenv("RIG_SOURCE_DIR");
  ASSERT_NE(src, nullptr);
  int n = 0;
  for (const auto& e : std::filesystem::directory_iterator(std::string(src) + "/config")) {
    if (e.path().extension() != ".toml") continue;
    ConfigResult r = LoadConfig(e.path().string());
    EXPECT_TRUE(r.ok()) << r.AsError().ToString();
    ++n;
  }
  EXPECT_GE(n, 3);
}

TEST(Config, MissingFileIsReported) {
  ConfigResult r = LoadConfig("/nonexistent/rig.toml");
  ASSERT_EQ(r.diagnostics.size(), 1u);
  EXPECT_THAT(r.diagnostics[0].ToString(), HasSubstr("/nonexistent/rig.toml"));
}

}  // namespace
}  // namespace rig
