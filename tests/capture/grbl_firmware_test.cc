// What GRBL 1.1h's source says it does, on the emulator (a raw client on its pty), and the
// driver's answers to it: homing direction by $23, the stock Z-first cycle, negative machine
// space, the soft-limit alarm's silence; the grid checked against the firmware's travel at
// connect; a link lost mid-move that the session carries on from, or resumes after homing.
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
#include "capture/plan/pose.h"
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
using ::testing::Not;
using rig::testing::FastGrbl;
using rig::testing::GrblConfigFor;
using rig::testing::Quiet;
using rig::testing::SmallSimConfigWithGrbl;
using rig::testing::Mpos;
using rig::testing::RawPty;
using rig::testing::StartGrbl;

const bool kPtyShim = rig::testing::PtyShimLinked();

// A sped-up emulator with an arm's travel: X 100 units, Y 65, pull-off 1.
GrblEmulatorOptions Arm() {
  GrblEmulatorOptions o = FastGrbl();
  o.settings[130] = 100;
  o.settings[131] = 65;
  o.settings[27] = 1;
  return o;
}

// Opens the pty and reads the power-up banner and the alarm lock.
void Connect(RawPty& pty) {
  ASSERT_TRUE(pty.ok());
  ASSERT_THAT(pty.ReadUntil("to unlock"), HasSubstr("Grbl 1.1"));
}

// ---- The emulator -----------------------------------------------------------------------

// limits.c: an axis homes towards its negative end when its $23 bit is set, towards the
// positive end when clear; machine space after homing is negative (no HOMING_FORCE_SET_ORIGIN):
// -$13n + $27 homed towards negative, -$27 towards positive.
TEST(GrblFirmware, HomingDirectionFollowsDollar23AndMachineSpaceIsNegative) {
  for (int dir : {0b011, 0b000}) {
    GrblEmulatorOptions o = Arm();
    o.switches_at_negative_end = 0b011;  // switches at the 0-degree end
    o.settings[23] = dir;
    auto emu = StartGrbl(o);
    ASSERT_TRUE(emu);
    RawPty pty(emu->path());
    Connect(pty);
    pty.Write("$H\n");
    std::string reply = pty.ReadUntil("ok", 5.0);
    if (dir == 0) {
      // Bits clear: it searches towards the positive end, away from the switches, and alarms.
      EXPECT_THAT(reply, HasSubstr("ALARM:9"));
      EXPECT_EQ(emu->homings(), 0);
      continue;
    }
    EXPECT_THAT(reply, Not(HasSubstr("ALARM")));
    std::string idle = pty.WaitState("Idle");
    EXPECT_NEAR(Mpos(idle, 0), -o.settings[130] + o.settings[27], 1e-3) << idle;
    EXPECT_NEAR(Mpos(idle, 1), -o.settings[131] + o.settings[27], 1e-3) << idle;
    EXPECT_EQ(emu->homings(), 1);
  }
  // Switches at the positive end and the bits clear: homed, at -$27.
  GrblEmulatorOptions o = Arm();
  o.switches_at_negative_end = 0;
  o.settings[23] = 0;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  RawPty pty(emu->path());
  Connect(pty);
  pty.Write("$H\n");
  EXPECT_THAT(pty.ReadUntil("ok", 5.0), Not(HasSubstr("ALARM")));
  std::string idle = pty.WaitState("Idle");
  EXPECT_NEAR(Mpos(idle, 0), -o.settings[27], 1e-3) << idle;
  EXPECT_NEAR(Mpos(idle, 1), -o.settings[27], 1e-3) << idle;
}

// config.h's stock HOMING_CYCLE_0 is Z alone: an arm without a Z switch never finds it,
// ALARM:9, and X and Y never move.
TEST(GrblFirmware, TheStockBuildHomesZFirstAndEndsInAlarm9WithoutMovingXOrY) {
  GrblEmulatorOptions o = Arm();
  o.stock_homing_cycle = true;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  RawPty pty(emu->path());
  Connect(pty);
  const auto before = emu->Position();
  pty.Write("$H\n");
  std::string reply = pty.ReadUntil("to unlock", 5.0);
  EXPECT_THAT(reply, HasSubstr("ALARM:9"));
  EXPECT_EQ(emu->homings(), 0);
  EXPECT_EQ(emu->Position()[0], before[0]);
  EXPECT_EQ(emu->Position()[1], before[1]);
  EXPECT_EQ(emu->State(), "Alarm");
}

// limits_soft_check() then protocol.c's critical loop: ALARM:2, "Reset to continue", and
// nothing at all, not even a status report, until a reset; after it the alarm lock.
TEST(GrblFirmware, ASoftLimitAlarmAnswersNothingNotEvenAStatusReportUntilAReset) {
  GrblEmulatorOptions o = Arm();
  o.settings[20] = 1;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  RawPty pty(emu->path());
  Connect(pty);
  pty.Write("$H\n");
  ASSERT_THAT(pty.ReadUntil("ok", 5.0), Not(HasSubstr("ALARM")));
  // G54 is the homed position (-99, -64): work X5 is machine -94, inside; X150 is outside.
  pty.Write("G1 X5 F6000\n");
  ASSERT_THAT(pty.ReadUntil("ok"), HasSubstr("ok"));
  ASSERT_THAT(pty.WaitState("Idle"), HasSubstr("<Idle"));
  pty.Write("G1 X150 F6000\n");
  std::string alarm = pty.ReadUntil("Reset to continue");
  EXPECT_THAT(alarm, HasSubstr("ALARM:2"));
  EXPECT_THAT(alarm, Not(HasSubstr("ok")));
  pty.Write("?");
  EXPECT_EQ(pty.ReadUntil(">", 0.5), "");
  pty.Write("$X\n");
  EXPECT_EQ(pty.ReadUntil("ok", 0.5), "");
  pty.Write("\x18");
  EXPECT_THAT(pty.ReadUntil("to unlock"), HasSubstr("Grbl 1.1"));
  std::string report = pty.WaitState("Alarm");
  EXPECT_THAT(report, HasSubstr("<Alarm"));
  EXPECT_NEAR(Mpos(report, 0), -94, 1e-3);  // the position was kept
}

// ---- The driver at connect: the grid against the firmware's travel ----------------------

// The simulated grid runs h 0..90; $130=60 with the homed work offset allows h -1..59.
TEST(GrblFirmware, AGridOutsideTheFirmwaresTravelIsRefusedBeforeAnythingMoves) {
  GrblEmulatorOptions o = Arm();
  o.settings[130] = 60;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  Config config = SmallSimConfigWithGrbl(emu->path());
  const std::string dir = testing::FreshTempDir("grbl_travel");
  auto session = Session::Create(dir + "/S", config);
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  auto devices = MakeDevices(config);
  ASSERT_TRUE(devices.ok());
  CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, Quiet());
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.error().code, ErrorCode::kInvalidInput);
  const std::string msg = st.error().ToString();
  EXPECT_THAT(msg, HasSubstr("$130=60"));             // the firmware's number
  EXPECT_THAT(msg, HasSubstr("h_limit_max_deg"));     // the rig's
  EXPECT_THAT(msg, HasSubstr("G54"));
  EXPECT_THAT(msg, HasSubstr("-1.000 .. 59.000 deg"));
  EXPECT_EQ(emu->moves(), 0);
  EXPECT_EQ(emu->homings(), 0);
  EXPECT_EQ(summary.frames_captured, 0);
  std::filesystem::remove_all(dir);
}

// config/grbl-dome.toml's grid on the firmware docs/rig-setup.md sets up for it ($130=340,
// $131=90), and on one whose X travel is left at 300: accepted, and refused before a move.
TEST(GrblFirmware, TheFullAzimuthExampleFitsTheFirmwareItsGuideSetsUpAndNoShorterOne) {
  ConfigResult cr = LoadConfig(testing::SourceDir() + "/config/grbl-dome.toml");
  ASSERT_TRUE(cr.ok());
  const std::vector<Pose> grid = PlanGrid(cr.config.grid);
  ASSERT_EQ(grid.size(), 60u);
  for (double x_travel : {340.0, 300.0}) {
    GrblEmulatorOptions o = Arm();
    o.settings[130] = x_travel;
    o.settings[131] = 90;
    o.settings[20] = 1;
    auto emu = StartGrbl(o);
    ASSERT_TRUE(emu);
    MotorConfig mc = cr.config.motor;
    const MotorConfig fast = GrblConfigFor(emu->path());
    mc.port = fast.port;
    mc.reply_timeout_s = fast.reply_timeout_s;
    mc.grbl.banner_timeout_s = fast.grbl.banner_timeout_s;
    GrblMotor motor(mc);
    ASSERT_TRUE(motor.Open().ok());
    Status st = motor.CheckReach(grid);
    if (x_travel == 340) {
      EXPECT_TRUE(st.ok()) << st.error().ToString();
    } else {
      ASSERT_FALSE(st.ok());
      EXPECT_THAT(st.error().ToString(), HasSubstr("$130=300"));
      EXPECT_THAT(st.error().ToString(), HasSubstr("of 60 poses"));
    }
    EXPECT_EQ(emu->moves(), 0);
  }
}

// A pose the rig's own limits allow (h -5) but GRBL's soft limits do not: refused with both
// numbers, nothing sent, and the firmware never enters its silent alarm.
TEST(GrblFirmware, AJogInsideTheRigsLimitsButOutsideTheFirmwaresIsRefusedWithBoth) {
  GrblEmulatorOptions o = Arm();
  o.settings[20] = 1;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  GrblMotor motor(GrblConfigFor(emu->path()));
  ASSERT_TRUE(motor.Open().ok());
  EXPECT_TRUE(kPtyShim);
  EXPECT_NEAR(motor.g54()[0], -99, 1e-3);
  ASSERT_TRUE(motor.Home().ok());
  ASSERT_TRUE(motor.MoveTo({30, 10}).ok());
  const int moves = emu->moves();
  Status st = motor.MoveTo({-5, 10});
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.error().code, ErrorCode::kInvalidInput);
  EXPECT_THAT(st.error().ToString(), HasSubstr("hm005_v10"));
  EXPECT_THAT(st.error().ToString(), HasSubstr("$130=100"));
  EXPECT_THAT(st.error().ToString(), HasSubstr("ALARM:2"));
  EXPECT_EQ(emu->moves(), moves);
  EXPECT_EQ(emu->State(), "Idle");
  ASSERT_TRUE(motor.MoveTo({0, 0}).ok());  // still answering
}

// A build with HOMING_FORCE_SET_ORIGIN ($I lists 'Z') is at machine 0 after homing towards
// its negative end and travels 0 .. $13n (system_check_travel_limits): the driver reads the
// option and checks poses on that side; the same work offset on a stock build is refused.
TEST(GrblFirmware, AForceSetOriginBuildTravelsOnThePositiveSideAndTheDriverKnows) {
  for (bool force : {true, false}) {
    GrblEmulatorOptions o = Arm();
    o.settings[20] = 1;
    o.homing_force_set_origin = force;
    o.g54 = std::array<double, 3>{0, 0, 0};  // work = machine
    auto emu = StartGrbl(o);
    ASSERT_TRUE(emu);
    GrblMotor motor(GrblConfigFor(emu->path()));
    ASSERT_TRUE(motor.Open().ok());
    ASSERT_TRUE(motor.Home().ok());
    if (force) {
      EXPECT_NEAR(emu->Position()[0], 0, 1e-3);
      ASSERT_TRUE(motor.MoveTo({30, 10}).ok());
      const int moves = emu->moves();
      Status st = motor.MoveTo({-5, 10});
      ASSERT_FALSE(st.ok());
      EXPECT_THAT(st.error().ToString(), HasSubstr("machine X0 .. 100 after homing (HOMING_FORCE_SET_ORIGIN"));
      EXPECT_EQ(emu->moves(), moves);
      EXPECT_EQ(emu->State(), "Idle");
    } else {
      Status st = motor.MoveTo({30, 10});
      ASSERT_FALSE(st.ok());
      EXPECT_THAT(st.error().ToString(), HasSubstr("machine X-100 .. 0 after homing,"));
      EXPECT_EQ(emu->moves(), 0);
    }
  }
}

// The emulator's own soft limit follows the build: machine X-5 alarms on the forced-origin
// build, X+5 on the stock one.
TEST(GrblFirmware, TheEmulatorsSoftLimitIsOnTheSideTheBuildSays) {
  for (bool force : {true, false}) {
    GrblEmulatorOptions o = Arm();
    o.settings[20] = 1;
    o.homing_force_set_origin = force;
    o.g54 = std::array<double, 3>{0, 0, 0};  // work = machine
    auto emu = StartGrbl(o);
    ASSERT_TRUE(emu);
    RawPty pty(emu->path());
    Connect(pty);
    pty.Write("$I\n");
    const std::string info = pty.ReadUntil("ok", 5.0);
    EXPECT_THAT(info, HasSubstr(force ? "[OPT:VZ," : "[OPT:V,"));
    pty.Write("$H\n");
    const std::string homed = pty.ReadUntil("ok", 5.0);
    ASSERT_THAT(homed, HasSubstr("ok"));
    ASSERT_THAT(homed, Not(HasSubstr("ALARM"))) << info;
    // Machine X+5. GRBL strips the spaces: "G0X5" is G0 with X5, not G5 ("0X5" is no hex).
    pty.Write("G0 X5\n");
    const std::string reply = pty.ReadUntil(force ? "ok" : "ALARM", 5.0);
    if (force) {
      EXPECT_THAT(reply, HasSubstr("ok")) << reply;
      EXPECT_THAT(reply, Not(HasSubstr("ALARM"))) << reply;
    } else {
      EXPECT_THAT(reply, HasSubstr("ALARM:2")) << reply;
    }
  }
}

// A slow controller: 10 deg/s braking at 5 deg/s^2 takes 2 s, four times the reply timeout.
// Ctrl-C waits the hold out (v/a from $110 and $120, plus a margin) before its reset, so
// GRBL raises no ALARM:3 and the position is kept.
TEST(GrblFirmware, CtrlCWaitsForTheBrakeTheControllersSpeedAndAccelerationNeed) {
  GrblEmulatorOptions o = Arm();
  o.time_scale = 1;
  o.homing_enabled = false;
  o.settings[120] = 5;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.speed_deg_per_s = 10;
  c.move_timeout_s = 60;
  c.reply_timeout_s = 0.5;
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ClearStopForTesting();
  std::thread stopper([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));  // at full speed
    RequestStop(SIGINT);
  });
  Status st = motor.MoveTo({90, 0});
  stopper.join();
  ClearStopForTesting();
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.error().code, ErrorCode::kInterrupted) << st.error().ToString();
  EXPECT_THAT(st.error().message, HasSubstr("the move was stopped"));
  EXPECT_EQ(motor.fault(), "") << motor.fault();
  EXPECT_EQ(emu->State(), "Idle");
  EXPECT_GT(emu->WorkPosition()[0], 10);  // it got under way, then braked to a stop
  EXPECT_LT(emu->WorkPosition()[0], 60);
}

// ---- A link lost mid-move ---------------------------------------------------------------

// The cable goes half way through the 5th move and comes back; the controller kept its power
// and is not reset by the reopen (no DTR auto-reset): Idle, no alarm, a position. The session
// carries on from it, homed once, and completes.
TEST(GrblFirmware, ALinkLostMidMoveToAControllerThatKeptRunningCarriesOnToACompleteSession) {
  GrblEmulatorOptions o = Arm();
  o.disconnect_mid_move = 5;
  o.reset_on_replug = false;
  o.reset_on_open = false;
  const std::string link = testing::FreshTempDir("grbl_link") + "/grbl";
  auto emu = StartGrbl(o, link);
  ASSERT_TRUE(emu);
  Config config = SmallSimConfigWithGrbl(link);
  config.motor.after_reconnect = "verify";
  config.motor.retries = 3;  // the board is back after 0.2 s: attempts at 0.1, 0.3, 0.7 s
  config.motor.retry_backoff_s = 0.1;
  const std::string dir = testing::FreshTempDir("grbl_link_session");
  auto session = Session::Create(dir + "/S", config);
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  auto devices = MakeDevices(config);
  ASSERT_TRUE(devices.ok());
  CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, Quiet());
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_GE(emu->plug_count(), 2);
  EXPECT_EQ(emu->homings(), 1);
  EXPECT_EQ(summary.frames_captured, 40 * 2);
  EXPECT_EQ(summary.processing.merged, 40);
  std::filesystem::remove_all(dir);
}

// The same loss on an Arduino that resets when the port is reopened (DTR): the driver says
// homing is needed and why, the run stops with a fault, and `rig resume` (a new run on the
// session) homes and completes it, keeping every frame already stored.
TEST(GrblFirmware, ALinkLostMidMoveToAResetControllerSaysHomingIsNeededAndTheResumeCompletes) {
  GrblEmulatorOptions o = Arm();
  o.disconnect_mid_move = 5;
  o.reset_on_replug = false;
  o.reset_on_open = true;
  const std::string link = testing::FreshTempDir("grbl_link_reset") + "/grbl";
  auto emu = StartGrbl(o, link);
  ASSERT_TRUE(emu);
  Config config = SmallSimConfigWithGrbl(link);
  config.motor.after_reconnect = "verify";
  config.motor.retries = 3;
  config.motor.retry_backoff_s = 0.1;
  const std::string dir = testing::FreshTempDir("grbl_link_reset_session");
  int stored = 0;
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
    EXPECT_THAT(st.error().ToString(), HasSubstr("reset when the link came back"));
    EXPECT_THAT(st.error().ToString(), HasSubstr("home it"));
    // Each context once: "pose P: grbl on PORT: message", not the pose and port again.
    const std::string text = st.error().ToString();
    EXPECT_EQ(text.find("pose h"), text.rfind("pose h")) << text;
    EXPECT_EQ(text.find(link), text.rfind(link)) << text;
    stored = summary.frames_captured;
    EXPECT_GT(stored, 0);
  }
  auto session = Session::OpenExisting(dir + "/S");
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  auto devices = MakeDevices(config);
  ASSERT_TRUE(devices.ok());
  CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, Quiet());
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_EQ(summary.frames_verified, stored);
  EXPECT_EQ(summary.frames_captured, 40 * 2 - stored);
  EXPECT_EQ(emu->homings(), 2);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rig
