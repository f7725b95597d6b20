// The capture summary after a fault: a clock that ran, parts no bigger than their whole, and
// errors with their unit.
#include <filesystem>
#include <regex>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "capture/daemon/daemon.h"
#include "capture/session/session_store.h"
#include "config/config.h"
#include "rig/backends.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

double NumberAfter(const std::string& text, const std::string& label) {
  std::smatch m;
  std::regex re(label + " ([0-9.]+)");
  if (!std::regex_search(text, m, re)) return -1;
  return std::stod(m[1]);
}

TEST(CaptureSummary, AfterAFaultTheClockRanAndTheBracketsBeforeWereMerged) {
  ConfigResult cr = LoadConfig(testing::SourceDir() + "/config/sim.toml");
  ASSERT_TRUE(cr.ok());
  Config config = cr.config;
  config.sim.width = 48;
  config.sim.height = 36;
  config.bracket.count = 2;
  config.sim.camera.fail_forever_after = 9;
  config.camera.retries = 0;
  const std::string dir = testing::FreshTempDir("summary_after_fault");
  auto session = Session::Create(dir + "/S", config);
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  auto devices = MakeDevices(config);
  ASSERT_TRUE(devices.ok());
  CaptureOptions options;
  options.settle_scale = 0;
  options.progress = false;
  CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, options);
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(summary.faults, 1);
  EXPECT_EQ(summary.frames_captured, 8);
  EXPECT_GT(summary.total_s, 0);
  EXPECT_GE(summary.total_s + 1e-9, summary.motion_s + summary.settle_s + summary.lamp_s +
                                        summary.camera_s + summary.storage_s);
  EXPECT_EQ(summary.processing.merged, 4);  // the four poses stored before the fault

  const std::string text = summary.ToString();
  std::printf("%s\n", text.c_str());
  EXPECT_GT(NumberAfter(text, "time"), 0) << text;
  // The simulated camera does not wait out its shutter: the frames' exposures add up to more
  // than the camera's time, and the summary must not call them a part of it.
  ASSERT_GT(summary.exposure_s, summary.camera_s);
  EXPECT_THAT(text, Not(HasSubstr("of which")));
  EXPECT_THAT(text, HasSubstr("not waited"));
  std::filesystem::remove_all(dir);
}

TEST(CaptureSummary, WhenTheShutterIsWaitedForItIsAPartOfTheCameraTime) {
  CaptureSummary s;
  s.total_s = 10;
  s.camera_s = 4;
  s.exposure_s = 3;
  s.motion_s = 2;
  s.open_s = 1.5;  // a controller's start-up: the devices' time, not the rig's
  const std::string text = s.ToString();
  EXPECT_THAT(text, HasSubstr("camera 4.00 s (of which shutter 3.00 s)"));
  EXPECT_THAT(text, HasSubstr("opening the devices 1.50 s"));
  EXPECT_THAT(text, HasSubstr("own overhead 2.50 s"));
}

TEST(CaptureSummary, TheModelsLeaveOneOutErrorCarriesItsUnit) {
  const std::string dir = testing::FreshTempDir("summary_loo_unit");
  const std::string cfg = testing::WriteSimConfig(
      dir, "[sim]\nwidth = 48\nheight = 36\n[bracket]\ncount = 3\n[process]\nmodel_family = \"harmonic\"\n");
  auto r = testing::RunRig("capture --config " + cfg + " --out " + dir + "/S --no-progress 2>&1");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("leave-one-out RMS error"));
  EXPECT_THAT(r.output, HasSubstr("of reflectance (radiance / lamp radiance)"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rig
