// Faults found bringing the rig up on real GRBL 1.1h: resuming without homing, a controller
// alarm-locked at start, and the emulator's reset after a completed feed hold.
#include <fcntl.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "capture/daemon/daemon.h"
#include "capture/devices/grbl_motor.h"
#include "capture/devices/signals.h"
#include "capture/session/session_store.h"
#include "config/config.h"
#include "rig/backends.h"
#include "sim/grbl_emulator.h"
#include "tests/support/motor_emulators.h"
#include "tests/support/pty_shim.h"
#include "tests/support/raw_pty.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using rig::testing::FastGrbl;
using rig::testing::GrblConfigFor;
using rig::testing::Quiet;
using rig::testing::SmallSimConfigWithGrbl;
using rig::testing::StartGrbl;
using ::testing::Not;
using rig::testing::MposX;
using rig::testing::RawPty;
using Clock = std::chrono::steady_clock;

const bool kPtyShim = rig::testing::PtyShimLinked();

// A machine without limit switches ($22=0, home_on_start = false): a session stopped by a
// fault is resumed without homing, on the real driver, and completes.
TEST(GrblBringUp, ResumeWithoutHomingCompletesOnTheEmulator) {
  GrblEmulatorOptions o = FastGrbl();
  o.homing_enabled = false;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  Config config = SmallSimConfigWithGrbl(emu->path());
  config.motor.home_on_start = false;
  config.sim.camera.fail_forever_after = 9;  // the camera dies at its 9th capture
  config.camera.retries = 0;
  const std::string dir = testing::FreshTempDir("grbl_resume_no_home");
  {
    auto session = Session::Create(dir + "/S", config);
    ASSERT_TRUE(session.ok()) << session.error().ToString();
    auto devices = MakeDevices(config);
    ASSERT_TRUE(devices.ok());
    CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, Quiet());
    CaptureSummary summary;
    Status st = daemon.Run(&summary);
    ASSERT_FALSE(st.ok());
    EXPECT_EQ(st.error().code, ErrorCode::kFault);
    EXPECT_EQ(summary.frames_captured, 8);
  }
  config.sim.camera.fail_forever_after = 0;  // the camera is replaced
  auto session = Session::OpenExisting(dir + "/S");
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  EXPECT_FALSE(session->config().motor.home_on_start);
  auto devices = MakeDevices(config);
  ASSERT_TRUE(devices.ok());
  CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, Quiet());
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_EQ(summary.frames_verified, 8);
  EXPECT_EQ(summary.frames_captured, 40 * 2 - 8);
  EXPECT_EQ(emu->homings(), 0);
  EXPECT_GE(emu->moves(), 36);
  std::filesystem::remove_all(dir);
}

// Homing disabled on the controller and home_on_start already false: the message of an
// explicit homing does not tell the user to set what is set.
TEST(GrblBringUp, HomingRefusedWithoutSwitchesDoesNotAdviseWhatIsAlreadySet) {
  GrblEmulatorOptions o = FastGrbl();
  o.homing_enabled = false;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.home_on_start = false;
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  Status st = motor.Home();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("$22=0"));
  EXPECT_THAT(st.error().ToString(), Not(HasSubstr("set motor.home_on_start = false")));
  motor.Close();
  c.home_on_start = true;
  GrblMotor motor2(c);
  ASSERT_TRUE(motor2.Open().ok());
  st = motor2.Home();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("home_on_start = false"));
}

// Power-up with homing enabled: GRBL is alarm-locked ("[MSG:'$H'|'$X' to unlock]"). A move
// is refused at once (no retries, no reconnect) with what to do, naming the port.
TEST(GrblBringUp, AControllerAlarmLockedAtStartIsAClearNonRetryableError) {
  auto emu = StartGrbl(FastGrbl());
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.home_on_start = false;
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  EXPECT_EQ(motor.state(), "Alarm");
  Status st = motor.MoveTo({10, 0});
  ASSERT_FALSE(st.ok());
  const std::string text = st.error().ToString();
  EXPECT_NE(st.error().code, ErrorCode::kDevice);  // not retryable
  EXPECT_NE(st.error().code, ErrorCode::kTimeout);
  EXPECT_NE(st.error().code, ErrorCode::kIo);
  EXPECT_THAT(text, HasSubstr("$X"));
  EXPECT_THAT(text, HasSubstr("$H"));
  EXPECT_THAT(text, HasSubstr(emu->path()));
  EXPECT_EQ(motor.reconnects(), 0);
  EXPECT_EQ(emu->moves(), 0);
  motor.Close();

  // Through the daemon: one fault, no retries, the journal's fault record names $X.
  Config config = SmallSimConfigWithGrbl(emu->path());
  config.motor.home_on_start = false;
  const std::string dir = testing::FreshTempDir("grbl_alarm_locked");
  auto session = Session::Create(dir + "/S", config);
  ASSERT_TRUE(session.ok());
  auto devices = MakeDevices(config);
  ASSERT_TRUE(devices.ok());
  CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, Quiet());
  CaptureSummary summary;
  Status run = daemon.Run(&summary);
  ASSERT_FALSE(run.ok());
  EXPECT_EQ(summary.retries, 0) << run.error().ToString();
  EXPECT_THAT(run.error().ToString(), HasSubstr("$X"));
  EXPECT_THAT(run.error().ToString(), Not(HasSubstr("position unknown after reconnect")));
  std::filesystem::remove_all(dir);
}

// ---- The emulator against GRBL 1.1h's mc_reset(): a raw client on the pty ----------------

GrblEmulatorOptions RealTimeNoHoming() {
  GrblEmulatorOptions o;
  o.time_scale = 1;
  o.banner_delay_s = 0.02;
  o.homing_enabled = false;
  o.settings[120] = 50;  // X acceleration units/s^2
  return o;
}

// 1.1h's mc_reset() raises ALARM:3 only in a motion state (cycle, homing, jog) or while a
// hold is still decelerating; once "Hold:0" is reported the reset keeps the position.
TEST(GrblEmulator, AResetAfterACompletedFeedHoldRaisesNoAlarmAndKeepsThePosition) {
  auto emu = StartGrbl(RealTimeNoHoming());
  ASSERT_TRUE(emu);
  RawPty pty(emu->path());
  ASSERT_TRUE(pty.ok());
  ASSERT_THAT(pty.ReadUntil("['$' for help]"), HasSubstr("Grbl 1.1"));
  pty.Write("G1 X100 F600\n");  // 10 units/s: 10 s of motion
  ASSERT_THAT(pty.ReadUntil("ok"), HasSubstr("ok"));
  ASSERT_THAT(pty.WaitState("Run"), HasSubstr("<Run"));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  pty.Write("!");
  std::string held = pty.WaitState("Hold:0");
  ASSERT_THAT(held, HasSubstr("<Hold:0"));
  const double x_held = MposX(held);
  EXPECT_GT(x_held, 1.0);
  pty.Write("\x18");
  std::string after = pty.ReadUntil("['$' for help]");
  EXPECT_THAT(after, HasSubstr("Grbl 1.1"));
  EXPECT_THAT(after, Not(HasSubstr("ALARM")));
  EXPECT_THAT(after, Not(HasSubstr("to unlock")));
  std::string idle = pty.WaitState("Idle");
  ASSERT_THAT(idle, HasSubstr("<Idle"));
  EXPECT_NEAR(MposX(idle), x_held, 1e-3);
  EXPECT_EQ(emu->State(), "Idle");
}

// ... while a reset during the deceleration (Hold:1) or the cycle itself still raises it.
TEST(GrblEmulator, AResetDuringMotionOrADeceleratingHoldRaisesAlarm3) {
  GrblEmulatorOptions o = RealTimeNoHoming();
  o.settings[120] = 2;  // a 5 s deceleration from 10 units/s
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  RawPty pty(emu->path());
  ASSERT_TRUE(pty.ok());
  ASSERT_THAT(pty.ReadUntil("['$' for help]"), HasSubstr("Grbl 1.1"));
  pty.Write("G1 X100 F600\n");
  ASSERT_THAT(pty.ReadUntil("ok"), HasSubstr("ok"));
  ASSERT_THAT(pty.WaitState("Run"), HasSubstr("<Run"));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  pty.Write("!");
  ASSERT_THAT(pty.WaitState("Hold:1"), HasSubstr("<Hold:1"));
  pty.Write("\x18");
  std::string after = pty.ReadUntil("to unlock");
  EXPECT_THAT(after, HasSubstr("ALARM:3"));
  EXPECT_EQ(emu->State(), "Alarm");
}

// The driver's Ctrl-C path on 1.1h: feed hold, wait for Hold:0, reset; nothing to unlock, so
// no "$X" is sent and the position is kept.
TEST(GrblBringUp, CtrlCStopsWithAHoldAndAResetAndNeedsNoUnlock) {
  GrblEmulatorOptions o = RealTimeNoHoming();
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.speed_deg_per_s = 5;
  c.move_timeout_s = 60;
  c.grbl.completion = "poll";
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  const int lines_before = emu->lines();
  ClearStopForTesting();
  std::thread stopper([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
    RequestStop(SIGINT);
  });
  Status st = motor.MoveTo({90, 0});
  stopper.join();
  ClearStopForTesting();
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.error().code, ErrorCode::kInterrupted);
  for (int i = 0; i < 100 && emu->State() != "Idle"; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(emu->State(), "Idle");
  EXPECT_TRUE(motor.fault().empty()) << motor.fault();
  auto where = motor.Position();
  ASSERT_TRUE(where.ok());
  EXPECT_GT(where->h_deg, 0.1);
  EXPECT_EQ(emu->lines(), lines_before + 1);  // the move's line only: no "$X"
}

}  // namespace
}  // namespace rig
