// Test-only: the GRBL and Maestro emulators on a pseudo-terminal, sped up, and the motor
// configurations the drivers' tests use against them (capture/motor_drivers_test.cc,
// capture/grbl_bringup_test.cc).
#pragma once

#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "capture/daemon/daemon.h"
#include "config/config.h"
#include "sim/grbl_emulator.h"
#include "sim/maestro_emulator.h"
#include "tests/support/run_rig.h"

namespace rig::testing {

// Motion 200x faster than real time, the Arduino's reset after open shortened.
inline GrblEmulatorOptions FastGrbl() {
  GrblEmulatorOptions o;
  o.time_scale = 200;
  o.banner_delay_s = 0.05;
  o.replug_after_s = 0.2;
  return o;
}

inline MotorConfig GrblConfigFor(const std::string& port) {
  MotorConfig c;
  c.backend = "grbl";
  c.port = port;
  c.speed_deg_per_s = 30;
  c.accel_deg_per_s2 = 60;
  c.reply_timeout_s = 0.5;
  c.move_timeout_s = 1.5;
  c.retries = 2;
  c.retry_backoff_s = 0.05;
  c.grbl.banner_timeout_s = 0.5;
  return c;
}

// An emulator started (an empty pointer and a test failure when it cannot be).
inline std::unique_ptr<GrblEmulator> StartGrbl(GrblEmulatorOptions o, const std::string& link = "") {
  auto emu = StartGrblEmulator(o, link);
  EXPECT_TRUE(emu.ok()) << emu.error().ToString();
  return emu.ok() ? std::move(emu).value() : nullptr;
}

inline MaestroEmulatorOptions FastMaestro() {
  MaestroEmulatorOptions o;
  o.time_scale = 50;
  o.replug_after_s = 0.2;
  return o;
}

inline MotorConfig MaestroConfigFor(const std::string& port) {
  MotorConfig c;
  c.backend = "maestro";
  c.port = port;
  c.speed_deg_per_s = 60;
  c.accel_deg_per_s2 = 200;
  c.reply_timeout_s = 0.5;
  c.move_timeout_s = 1.5;
  c.retries = 1;
  c.retry_backoff_s = 0.05;
  c.maestro.h_us_at_zero = 1000;
  c.maestro.h_us_per_deg = 10;
  c.maestro.v_us_at_zero = 1100;
  c.maestro.v_us_per_deg = 8;
  c.maestro.poll_interval_s = 0.005;
  return c;
}

inline std::unique_ptr<MaestroEmulator> StartMaestro(MaestroEmulatorOptions o,
                                                     const std::string& link = "") {
  auto emu = StartMaestroEmulator(o, link);
  EXPECT_TRUE(emu.ok()) << emu.error().ToString();
  return emu.ok() ? std::move(emu).value() : nullptr;
}

// The simulated rig at 48x36, two exposures per pose, driving a GRBL controller on `port`.
inline Config SmallSimConfigWithGrbl(const std::string& port) {
  ConfigResult cr = LoadConfig(SourceDir() + "/config/sim.toml");
  EXPECT_TRUE(cr.ok());
  Config config = cr.config;
  config.sim.width = 48;
  config.sim.height = 36;
  config.bracket.count = 2;
  config.motor = GrblConfigFor(port);
  return config;
}

// A capture without settling waits or progress bars.
inline CaptureOptions Quiet() {
  CaptureOptions o;
  o.settle_scale = 0;
  o.progress = false;
  return o;
}

}  // namespace rig::testing
