// The serial protocols' own cost per pose: for every pose of the default grid, the time from
// the move request to "done" minus the motion time the emulator spent (its trapezoid), for
// GRBL (completion by G4 P0, and by '?' polling) and the Maestro (moving-state polling).
// Runs against the emulators on a real pty through libserialport (with the test-only pty
// interposer linked in).
//
//   build/bench/motor_bench [--time-scale 10]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <string>
#include <vector>

#include "config/log.h"
#include "capture/devices/grbl_motor.h"
#include "capture/devices/maestro_motor.h"
#include "capture/plan/pose.h"
#include "sim/grbl_emulator.h"
#include "sim/maestro_emulator.h"
#include "tests/support/pty_shim.h"

using Clock = std::chrono::steady_clock;

namespace {

struct Stats {
  double median_ms = 0, max_ms = 0, mean_ms = 0;
};

Stats Summarise(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  Stats s;
  if (v.empty()) return s;
  s.median_ms = v[v.size() / 2] * 1e3;
  s.max_ms = v.back() * 1e3;
  s.mean_ms = std::accumulate(v.begin(), v.end(), 0.0) / v.size() * 1e3;
  return s;
}

rig::MotorConfig BaseConfig(const std::string& backend, const std::string& port) {
  rig::MotorConfig c;
  c.backend = backend;
  c.port = port;
  c.reply_timeout_s = 1;
  c.move_timeout_s = 30;
  c.grbl.banner_timeout_s = 1;
  c.grbl.poll_interval_s = 0.2;  // GRBL's recommended maximum of 5 Hz
  c.maestro.poll_interval_s = 0.02;
  return c;
}

// Runs every grid pose; returns per-pose (wall - emulated motion / time_scale).
template <typename Motor, typename Emulator>
std::vector<double> Run(Motor& motor, Emulator& emu, double time_scale, bool home) {
  std::vector<double> overhead;
  if (!motor.Open().ok() || (home && !motor.Home().ok())) {
    std::fprintf(stderr, "cannot open/home %s\n", motor.Describe().c_str());
    std::exit(1);
  }
  rig::GridConfig grid;
  for (const rig::Pose& p : rig::PlanGrid(grid)) {
    const size_t before = emu.motion_times_s().size();
    const auto t0 = Clock::now();
    rig::Status st = motor.MoveTo(p);
    const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
    if (!st.ok()) {
      std::fprintf(stderr, "%s\n", st.error().ToString().c_str());
      std::exit(1);
    }
    const auto times = emu.motion_times_s();
    double motion = 0;
    for (size_t i = before; i < times.size(); ++i) motion += times[i] / time_scale;
    overhead.push_back(wall - motion);
  }
  motor.Close();
  return overhead;
}

}  // namespace

int main(int argc, char** argv) {
  double time_scale = 10;
  for (int i = 1; i + 1 < argc; i += 2)
    if (std::string(argv[i]) == "--time-scale") time_scale = std::atof(argv[i + 1]);
  rig::SetLogLevel("warn");
  if (!rig::testing::PtyShimLinked()) return 1;

  std::printf("per-pose protocol overhead: move request to done, minus the emulator's motion time\n"
              "(40 poses of the default grid, emulated motion %.0fx faster than real time)\n",
              time_scale);
  std::printf("  %-40s %10s %10s %10s\n", "", "median ms", "mean ms", "max ms");
  for (const char* completion : {"dwell", "poll"}) {
    rig::GrblEmulatorOptions o;
    o.time_scale = time_scale;
    o.banner_delay_s = 0.05;
    auto emu = rig::StartGrblEmulator(o);
    if (!emu.ok()) return 1;
    rig::MotorConfig c = BaseConfig("grbl", (*emu)->path());
    c.grbl.completion = completion;
    rig::GrblMotor motor(c);
    const Stats s = Summarise(Run(motor, **emu, time_scale, true));
    std::printf("  %-40s %10.2f %10.2f %10.2f\n",
                (std::string("GRBL, completion ") + (std::string(completion) == "dwell" ? "G4 P0" : "'?' at 5 Hz")).c_str(),
                s.median_ms, s.mean_ms, s.max_ms);
  }
  {
    rig::MaestroEmulatorOptions o;
    o.time_scale = time_scale;
    auto emu = rig::StartMaestroEmulator(o);
    if (!emu.ok()) return 1;
    rig::MaestroMotor motor(BaseConfig("maestro", (*emu)->path()));
    const Stats s = Summarise(Run(motor, **emu, time_scale, false));
    std::printf("  %-40s %10.2f %10.2f %10.2f\n", "Maestro, moving-state polling at 50 Hz", s.median_ms,
                s.mean_ms, s.max_ms);
  }
  return 0;
}
