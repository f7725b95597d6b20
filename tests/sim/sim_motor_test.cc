// The simulated lamp arm and lamp: trapezoidal timing, soft limits, homing, faults, warm-up.
#include "sim/sim_motor.h"

#include <cmath>
#include <thread>

#include <gtest/gtest.h>

#include "sim/sim_lamp.h"

namespace rig {
namespace {

Config MotorConfig45() {
  Config c;
  c.motor.speed_deg_per_s = 45;
  c.motor.accel_deg_per_s2 = 90;
  return c;
}

struct Arm {
  std::shared_ptr<SimWorld> world = std::make_shared<SimWorld>();
  std::unique_ptr<SimMotor> motor;
  explicit Arm(const Config& c) : motor(std::make_unique<SimMotor>(c, world)) {
    EXPECT_TRUE(motor->Open().ok());
  }
};

TEST(SimMotor, AxisTimeFollowsTheTrapezoidFormula) {
  // v = 45 deg/s, a = 90 deg/s^2: full speed is reached on moves of v^2/a = 22.5 deg or more.
  EXPECT_DOUBLE_EQ(SimMotor::AxisMotionTime(90, 45, 90).count(), 90.0 / 45 + 45.0 / 90);
  EXPECT_DOUBLE_EQ(SimMotor::AxisMotionTime(-30, 45, 90).count(), 30.0 / 45 + 0.5);
  EXPECT_DOUBLE_EQ(SimMotor::AxisMotionTime(22.5, 45, 90).count(), 1.0);  // both formulas agree
  EXPECT_DOUBLE_EQ(SimMotor::AxisMotionTime(10, 45, 90).count(), 2 * std::sqrt(10.0 / 90));
  EXPECT_DOUBLE_EQ(SimMotor::AxisMotionTime(0, 45, 90).count(), 0.0);
}

TEST(SimMotor, MovesBothAxesTogetherAndAccountsTheMotionTime) {
  Arm arm(MotorConfig45());
  ASSERT_TRUE(arm.motor->Home().ok());
  ASSERT_TRUE(arm.motor->MoveTo({90, 30}).ok());  // h: 2.5 s, v: 1.1667 s -> 2.5 s
  ASSERT_TRUE(arm.motor->MoveTo({80, 30}).ok());  // 10 deg: 2 sqrt(10/90) s
  ASSERT_TRUE(arm.motor->MoveTo({80, 0}).ok());   // 30 deg: 30/45 + 0.5 s
  ASSERT_TRUE(arm.motor->Home().ok());            // h 80: 80/45 + 0.5 s
  const double want = 2.5 + 2 * std::sqrt(10.0 / 90) + (30.0 / 45 + 0.5) + (80.0 / 45 + 0.5);
  const auto stats = arm.motor->stats();
  EXPECT_NEAR(stats.motion_time.count(), want, 1e-12);
  EXPECT_EQ(stats.moves, 3);
  EXPECT_EQ(stats.homings, 2);
  auto pos = arm.motor->Position();
  ASSERT_TRUE(pos.ok());
  EXPECT_EQ(*pos, (Pose{0, 0}));
  EXPECT_FALSE(arm.world->State().moving);
  EXPECT_EQ(arm.world->State().moves, 5);
}

TEST(SimMotor, PoseOutsideTheSoftLimitsIsRefusedNamingThePose) {
  Arm arm(MotorConfig45());
  for (Pose p : {Pose{100, 0}, Pose{-6, 0}, Pose{10, 61}, Pose{10, -5.5}}) {
    Status s = arm.motor->MoveTo(p);
    ASSERT_FALSE(s.ok());
    EXPECT_EQ(s.error().code, ErrorCode::kInvalidInput);
    EXPECT_NE(s.error().ToString().find(p.Name()), std::string::npos) << s.error().ToString();
  }
  EXPECT_EQ(arm.motor->stats().moves, 0);
  EXPECT_TRUE(arm.motor->MoveTo({95, 60}).ok());  // the limits themselves are inside
}

TEST(SimMotor, StallLosesThePositionUntilHomed) {
  Config c = MotorConfig45();
  c.sim.motor.stall_at_move = {2};
  Arm arm(c);
  ASSERT_TRUE(arm.motor->MoveTo({10, 0}).ok());
  Status s = arm.motor->MoveTo({90, 0});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
  EXPECT_NE(s.error().message.find("stalled"), std::string::npos);
  EXPECT_EQ(s.error().context, "sim motor");
  // The arm stopped between the two poses.
  const double h = arm.world->State().h_deg;
  EXPECT_GT(h, 10);
  EXPECT_LT(h, 90);
  EXPECT_FALSE(arm.motor->Position().ok());
  EXPECT_FALSE(arm.motor->MoveTo({90, 0}).ok());
  EXPECT_EQ(arm.motor->stats().moves, 2);  // refused moves are not counted
  ASSERT_TRUE(arm.motor->Home().ok());
  ASSERT_TRUE(arm.motor->MoveTo({90, 0}).ok());  // move 3: no fault
  EXPECT_EQ(*arm.motor->Position(), (Pose{90, 0}));
  EXPECT_EQ(arm.motor->stats().faults, 1);
}

TEST(SimMotor, TimeoutLeavesTheArmWhereItWas) {
  Config c = MotorConfig45();
  c.sim.motor.timeout_at_move = {2, 4};
  Arm arm(c);
  std::vector<int> failed;
  const Pose poses[] = {{10, 0}, {20, 0}, {20, 0}, {30, 0}, {30, 0}, {40, 10}};
  for (int k = 0; k < 6; ++k) {
    Pose before = *arm.motor->Position();
    Status s = arm.motor->MoveTo(poses[k]);
    if (!s.ok()) {
      failed.push_back(k + 1);
      EXPECT_EQ(s.error().code, ErrorCode::kTimeout);
      EXPECT_EQ(*arm.motor->Position(), before);
    } else {
      EXPECT_EQ(*arm.motor->Position(), poses[k]);
    }
  }
  EXPECT_EQ(failed, (std::vector<int>{2, 4}));
}

TEST(SimMotor, FailForeverAfterKeepsFailingThroughReconnect) {
  Config c = MotorConfig45();
  c.sim.motor.fail_forever_after = 3;
  Arm arm(c);
  EXPECT_TRUE(arm.motor->MoveTo({10, 0}).ok());
  EXPECT_TRUE(arm.motor->MoveTo({20, 0}).ok());
  EXPECT_FALSE(arm.motor->MoveTo({30, 0}).ok());
  EXPECT_TRUE(arm.motor->Reconnect().ok());
  Status s = arm.motor->MoveTo({30, 0});
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
}

TEST(SimMotor, ReconnectHomesOrVerifiesAsConfigured) {
  Config c = MotorConfig45();
  Arm homing(c);
  ASSERT_TRUE(homing.motor->MoveTo({40, 20}).ok());
  ASSERT_TRUE(homing.motor->Reconnect().ok());
  EXPECT_EQ(*homing.motor->Position(), (Pose{0, 0}));
  c.motor.after_reconnect = "verify";
  Arm verify(c);
  ASSERT_TRUE(verify.motor->MoveTo({40, 20}).ok());
  ASSERT_TRUE(verify.motor->Reconnect().ok());
  EXPECT_EQ(*verify.motor->Position(), (Pose{40, 20}));
  verify.motor->Close();
  EXPECT_FALSE(verify.motor->MoveTo({10, 10}).ok());
}

TEST(SimMotor, StopEndsAMoveInProgress) {
  Config c = MotorConfig45();
  c.motor.speed_deg_per_s = 1;  // a 90-second move at latency_scale 1
  c.sim.latency_scale = 1;
  Arm arm(c);
  std::thread stopper([&] {
    while (!arm.world->State().moving) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
    EXPECT_TRUE(arm.motor->Stop().ok());
  });
  Status s = arm.motor->MoveTo({90, 0});
  stopper.join();
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInterrupted);
  EXPECT_FALSE(arm.world->State().moving);
  auto pos = arm.motor->Position();
  ASSERT_TRUE(pos.ok());
  EXPECT_GT(pos->h_deg, 0);
  EXPECT_LT(pos->h_deg, 90);
  EXPECT_LT(arm.motor->stats().motion_time.count(), 90);
}

TEST(SimLamp, SwitchesTheWorldsLampAndAccountsTheWarmup) {
  Config c;
  c.lamp.warmup_s = 0.2;
  auto world = std::make_shared<SimWorld>();
  SimLamp lamp(c, world);
  EXPECT_FALSE(lamp.On().ok());  // before Open()
  ASSERT_TRUE(lamp.Open().ok());
  ASSERT_TRUE(lamp.On().ok());
  EXPECT_TRUE(world->State().lamp_on);
  EXPECT_TRUE(world->State().lamp_ready);
  ASSERT_TRUE(lamp.Off().ok());
  EXPECT_FALSE(world->State().lamp_on);
  ASSERT_TRUE(lamp.On().ok());
  lamp.Close();
  EXPECT_FALSE(world->State().lamp_on);
  EXPECT_NEAR(lamp.stats().warmup_time.count(), 0.4, 1e-12);
  EXPECT_EQ(lamp.stats().switchings, 3);  // the failed one before Open() is not a switching
}

TEST(SimLamp, ConfiguredSwitchingsFailOnceAndLeaveTheLampAsItWas) {
  Config c;
  c.sim.lamp.fail_switch_at = {2, 3};
  auto world = std::make_shared<SimWorld>();
  SimLamp lamp(c, world);
  ASSERT_TRUE(lamp.Open().ok());
  ASSERT_TRUE(lamp.On().ok());  // 1
  Status s = lamp.Off();        // 2
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kDevice);
  EXPECT_EQ(s.error().context, "sim lamp");
  EXPECT_TRUE(world->State().lamp_on);
  EXPECT_FALSE(lamp.Off().ok());  // 3
  EXPECT_TRUE(lamp.Off().ok());   // 4
  EXPECT_FALSE(world->State().lamp_on);
  EXPECT_TRUE(lamp.On().ok());    // 5
  EXPECT_EQ(lamp.stats().faults, 2);
}

}  // namespace
}  // namespace rig
