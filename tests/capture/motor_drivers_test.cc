// The GRBL and Maestro drivers against their emulators through a real pseudo-terminal and
// libserialport: the normal path, and each of the devices' bad days.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "rig/backends.h"
#include "capture/daemon/daemon.h"
#include "capture/devices/grbl_motor.h"
#include "capture/plan/pose.h"
#include "capture/session/session_store.h"
#include "tests/support/run_rig.h"
#include "capture/devices/maestro_motor.h"
#include "capture/devices/signals.h"
#include "sim/grbl_emulator.h"
#include "sim/maestro_emulator.h"
#include "tests/support/motor_emulators.h"
#include "tests/support/pty_shim.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using rig::testing::FastGrbl;
using rig::testing::GrblConfigFor;
using rig::testing::StartGrbl;
using rig::testing::FastMaestro;
using rig::testing::MaestroConfigFor;
using rig::testing::StartMaestro;
using Clock = std::chrono::steady_clock;

// libserialport only accepts ports it finds in sysfs; a pseudo-terminal has none. The test
// support interposer answers those few libc calls for ptys, so the real library (and every
// byte of its I/O) runs against the emulators.
const bool kPtyShim = rig::testing::PtyShimLinked();

std::string LinkPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()))).string();
}

TEST(GrblMotor, HomesMovesAndReadsBackThePositionInDegrees) {
  auto emu = StartGrbl(FastGrbl());
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.grbl.units_per_degree = 2.0;  // two controller units per degree
  GrblMotor motor(c);
  Status st = motor.Open();
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_TRUE(kPtyShim);
  EXPECT_GT(rig::testing::PtyShimCalls(), 0);
  st = motor.Home();
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_EQ(emu->homings(), 1);
  st = motor.MoveTo({30, 10});
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  // The controller is Idle at the target when MoveTo returns (G4 P0 answered).
  EXPECT_EQ(emu->State(), "Idle");
  const auto p = emu->WorkPosition();
  EXPECT_NEAR(p[0], 60, 0.01);
  EXPECT_NEAR(p[1], 20, 0.01);
  auto where = motor.Position();
  ASSERT_TRUE(where.ok());
  EXPECT_NEAR(where->h_deg, 30, 0.01);
  EXPECT_NEAR(where->v_deg, 10, 0.01);
  motor.Close();
}

TEST(GrblMotor, VisitsEveryGridPoseAndIsIdleThereEachTime) {
  auto emu = StartGrbl(FastGrbl());
  ASSERT_TRUE(emu);
  GrblMotor motor(GrblConfigFor(emu->path()));
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.Home().ok());
  GridConfig grid;  // h 0..90, v 0..30, 10-degree steps
  const auto poses = PlanGrid(grid);
  ASSERT_EQ(poses.size(), 40u);
  for (const Pose& p : poses) {
    Status st = motor.MoveTo(p);
    ASSERT_TRUE(st.ok()) << st.error().ToString();
    ASSERT_EQ(emu->State(), "Idle") << p.Name();
    EXPECT_NEAR(emu->WorkPosition()[0], p.h_deg, 0.01) << p.Name();
    EXPECT_NEAR(emu->WorkPosition()[1], p.v_deg, 0.01) << p.Name();
  }
  // Every move took the time its trapezoid says (the emulator is not short-cutting).
  EXPECT_GE(emu->motion_times_s().size(), 39u);
}

TEST(GrblMotor, CompletionByPollingStatusUntilIdle) {
  auto emu = StartGrbl(FastGrbl());
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.grbl.completion = "poll";
  c.grbl.poll_interval_s = 0.01;
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.Home().ok());
  for (Pose p : {Pose{10, 0}, Pose{50, 20}, Pose{90, 30}}) {
    Status st = motor.MoveTo(p);
    ASSERT_TRUE(st.ok()) << st.error().ToString();
    EXPECT_EQ(emu->State(), "Idle");
    EXPECT_NEAR(emu->WorkPosition()[0], p.h_deg, 0.01);
  }
}

TEST(GrblMotor, NoBannerIsAClearErrorNamingThePort) {
  GrblEmulatorOptions o = FastGrbl();
  o.no_banner = true;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  GrblMotor motor(GrblConfigFor(emu->path()));
  const auto t0 = Clock::now();
  Status st = motor.Open();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr(emu->path()));
  EXPECT_THAT(st.error().ToString(), HasSubstr("banner"));
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 5.0);
}

TEST(GrblMotor, AHomingAlarmBeforeTheOkIsAFailureWithItsMeaning) {
  GrblEmulatorOptions o = FastGrbl();
  o.homing_fail_alarm = 9;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  GrblMotor motor(GrblConfigFor(emu->path()));
  ASSERT_TRUE(motor.Open().ok());
  Status st = motor.Home();
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("ALARM:9"));
  EXPECT_THAT(st.error().ToString(), HasSubstr(GrblAlarmMeaning(9)));
  EXPECT_EQ(emu->homings(), 0);
}

TEST(GrblMotor, AnErrorReplyNamesItsMeaningAndThePose) {
  GrblEmulatorOptions o = FastGrbl();
  o.error_at_move = 2;
  o.error_code = 20;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.retries = 0;
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.Home().ok());
  ASSERT_TRUE(motor.MoveTo({10, 0}).ok());
  Status st = motor.MoveTo({20, 10});
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("error:20"));
  EXPECT_THAT(st.error().ToString(), HasSubstr(GrblErrorMeaning(20)));
  EXPECT_THAT(st.error().ToString(), HasSubstr("h020_v10"));
}

TEST(GrblMotor, AnAlarmDuringAMoveStopsWithAFaultUntilHomedAgain) {
  GrblEmulatorOptions o = FastGrbl();
  o.alarm_at_move = 1;
  o.alarm_code = 1;  // hard limit
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  GrblMotor motor(GrblConfigFor(emu->path()));
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.Home().ok());
  Status st = motor.MoveTo({60, 20});
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("ALARM:1"));
  EXPECT_FALSE(motor.fault().empty());
  // A fault refuses further moves until homed.
  EXPECT_FALSE(motor.MoveTo({10, 0}).ok());
  emu->SetOptions(FastGrbl());
  Status home = motor.Home();
  ASSERT_TRUE(home.ok()) << home.error().ToString();
  EXPECT_TRUE(motor.fault().empty());
  EXPECT_TRUE(motor.MoveTo({10, 0}).ok());
}

TEST(GrblMotor, GarbageAndSplitLinesAreIgnored) {
  GrblEmulatorOptions o = FastGrbl();
  o.garbage_every = 3;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  GrblMotor motor(GrblConfigFor(emu->path()));
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.Home().ok());
  for (Pose p : {Pose{10, 0}, Pose{20, 10}, Pose{30, 20}, Pose{40, 30}}) {
    Status st = motor.MoveTo(p);
    ASSERT_TRUE(st.ok()) << st.error().ToString();
  }
  EXPECT_GT(motor.ignored_lines(), 0);
  EXPECT_NEAR(emu->WorkPosition()[0], 40, 0.01);
}

TEST(GrblMotor, AMoveThatNeverReachesIdleTimesOutNamingThePose) {
  GrblEmulatorOptions o = FastGrbl();
  o.stall_at_move = 1;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.move_timeout_s = 0.5;
  c.retries = 0;
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.Home().ok());
  const auto t0 = Clock::now();
  Status st = motor.MoveTo({80, 30});
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("h080_v30"));
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 4.0);
}

TEST(GrblMotor, ThePortVanishingMidSessionIsReconnectedAndReHomed) {
  GrblEmulatorOptions o = FastGrbl();
  o.disconnect_at_move = 2;
  const std::string link = LinkPath("rig_grbl_link");
  auto emu = StartGrbl(o, link);
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(link);
  c.after_reconnect = "home";
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.Home().ok());
  ASSERT_TRUE(motor.MoveTo({10, 0}).ok());
  Status st = motor.MoveTo({20, 10});  // the USB cable is pulled as this line arrives
  if (!st.ok()) {
    // What the capture daemon does with a failed move: reconnect, then try again.
    EXPECT_THAT(st.error().ToString(), HasSubstr(link));
    Status re = motor.Reconnect();
    ASSERT_TRUE(re.ok()) << re.error().ToString();
    st = motor.MoveTo({20, 10});
  }
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_GE(emu->plug_count(), 2);
  EXPECT_GE(motor.reconnects(), 1);
  EXPECT_EQ(emu->homings(), 2);  // homed again after the reconnect
  EXPECT_NEAR(emu->WorkPosition()[0], 20, 0.01);
}

TEST(GrblMotor, CtrlCDuringALongMoveReturnsPromptly) {
  GrblEmulatorOptions o = FastGrbl();
  o.time_scale = 1;  // real time: a 90-degree move at 5 deg/s takes 18 s
  o.homing_enabled = false;
  auto emu = StartGrbl(o);
  ASSERT_TRUE(emu);
  MotorConfig c = GrblConfigFor(emu->path());
  c.speed_deg_per_s = 5;
  c.move_timeout_s = 60;
  c.grbl.completion = "poll";
  GrblMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ClearStopForTesting();
  std::thread stopper([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    RequestStop(SIGINT);
  });
  const auto t0 = Clock::now();
  Status st = motor.MoveTo({90, 0});
  const double took = std::chrono::duration<double>(Clock::now() - t0).count();
  stopper.join();
  ClearStopForTesting();
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.error().code, ErrorCode::kInterrupted) << st.error().ToString();
  std::printf("stopped after %.2f s: %s\n", took, st.error().ToString().c_str());
  // The arm was really stopped (feed hold, then reset), part of the way, and unlocked.
  EXPECT_THAT(st.error().message, HasSubstr("the move was stopped"));
  for (int i = 0; i < 100 && emu->State() != "Idle"; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(emu->State(), "Idle");
  EXPECT_LT(emu->WorkPosition()[0], 45);
  EXPECT_LT(took, 3.0);
}

TEST(GrblMotor, ADryRunWithTheGrblEmulatorAsTheMotorCompletes) {
  // The simulated camera and lamp, the real GRBL driver on the emulator's pty.
  auto emu = StartGrbl(FastGrbl());
  ASSERT_TRUE(emu);
  ConfigResult cr = LoadConfig(testing::SourceDir() + "/config/sim.toml");
  ASSERT_TRUE(cr.ok());
  Config config = cr.config;
  config.sim.width = 64;
  config.sim.height = 48;
  config.bracket.count = 3;
  config.motor = GrblConfigFor(emu->path());
  const std::string dir = testing::FreshTempDir("grbl_dry_run");
  auto session = Session::Create(dir + "/S", config);
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  auto devices = MakeDevices(config);
  ASSERT_TRUE(devices.ok()) << devices.error().ToString();
  CaptureOptions options;
  options.settle_scale = 0;
  options.progress = false;
  CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, options);
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_EQ(summary.frames_captured, 40 * 3);
  EXPECT_EQ(summary.processing.merged, 40);
  EXPECT_EQ(emu->homings(), 1);
  EXPECT_GE(emu->moves(), 40);
  std::filesystem::remove_all(dir);
}

// ---- Maestro ------------------------------------------------------------------------------

TEST(MaestroMotor, AnglesBecomeCalibratedPulseWidthsAndTheServosGetThere) {
  auto emu = StartMaestro(FastMaestro());
  ASSERT_TRUE(emu);
  MaestroMotor motor(MaestroConfigFor(emu->path()));
  Status st = motor.Open();
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  ASSERT_TRUE(motor.Home().ok());
  st = motor.MoveTo({30, 10});
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  // 1000 us + 30 deg x 10 us/deg = 1300 us; 1100 + 10 x 8 = 1180 us; in quarter-microseconds.
  EXPECT_EQ(emu->target(0), 1300 * 4);
  EXPECT_EQ(emu->target(1), 1180 * 4);
  EXPECT_NEAR(emu->position(0), 1300 * 4, 4);
  EXPECT_NEAR(emu->position(1), 1180 * 4, 4);
  EXPECT_GT(emu->speed(0), 0);         // speed and acceleration limits were set
  EXPECT_GT(emu->acceleration(0), 0);
  auto where = motor.Position();
  ASSERT_TRUE(where.ok());
  EXPECT_NEAR(where->h_deg, 30, 0.1);
  EXPECT_NEAR(where->v_deg, 10, 0.1);
}

TEST(MaestroMotor, TheErrorRegisterIsReadAndDecoded) {
  MaestroEmulatorOptions o = FastMaestro();
  o.error_at_target = 3;
  o.error_bits = 0x0010;  // serial protocol error
  auto emu = StartMaestro(o);
  ASSERT_TRUE(emu);
  MotorConfig c = MaestroConfigFor(emu->path());
  c.retries = 0;
  MaestroMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.MoveTo({10, 0}).ok());
  Status st = motor.MoveTo({20, 10});
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr(DecodeMaestroErrors(0x0010)));
  EXPECT_THAT(st.error().ToString(), HasSubstr(emu->path()));
}

TEST(MaestroMotor, AServoThatNeverArrivesTimesOutNamingThePose) {
  MaestroEmulatorOptions o = FastMaestro();
  o.stall_at_target = 3;  // the second pose's horizontal servo (from "off" a servo jumps)
  auto emu = StartMaestro(o);
  ASSERT_TRUE(emu);
  MotorConfig c = MaestroConfigFor(emu->path());
  c.retries = 0;
  c.move_timeout_s = 0.4;
  MaestroMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.MoveTo({10, 0}).ok());
  Status st = motor.MoveTo({45, 20});
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("h045_v20"));
}

TEST(MaestroMotor, ThePortVanishingIsReconnectedAndTheMoveCompletes) {
  MaestroEmulatorOptions o = FastMaestro();
  o.disconnect_at_target = 3;
  const std::string link = LinkPath("rig_maestro_link");
  auto emu = StartMaestro(o, link);
  ASSERT_TRUE(emu);
  MotorConfig c = MaestroConfigFor(link);
  c.retries = 4;
  c.retry_backoff_s = 0.1;
  MaestroMotor motor(c);
  ASSERT_TRUE(motor.Open().ok());
  ASSERT_TRUE(motor.MoveTo({10, 0}).ok());
  Status st = motor.MoveTo({40, 20});
  if (!st.ok()) {
    EXPECT_THAT(st.error().ToString(), HasSubstr(link));
    Status re = motor.Reconnect();
    ASSERT_TRUE(re.ok()) << re.error().ToString();
    st = motor.MoveTo({40, 20});
  }
  ASSERT_TRUE(st.ok()) << st.error().ToString();
  EXPECT_GE(emu->plug_count(), 2);
  EXPECT_EQ(emu->target(0), 1400 * 4);
}

}  // namespace
}  // namespace rig
