// The shared state of the simulated rig: where the lamp arm is, whether it moves, whether
// the lamp is lit, and the counters that tell a dry run broke the capture rules.
#pragma once

#include <chrono>
#include <cstdint>
#include <mutex>

namespace rig {

// A snapshot of the simulated rig. Angles are the commanded rig angles (degrees); the
// camera turns them into a light direction through LightDirection() and [light_frame].
struct SimWorldState {
  double h_deg = 0, v_deg = 0;  // where the lamp arm physically is
  bool moving = false;          // the arm is in motion
  bool lamp_on = false;
  bool lamp_ready = false;      // on and its warm-up is over
  std::chrono::steady_clock::time_point lamp_since{};  // last switching on or off

  int64_t captures = 0;                // captures that exposed the sensor
  int64_t captures_while_moving = 0;   // violations: the camera fired during motion ...
  int64_t captures_lamp_off = 0;       // ... with the lamp off ...
  int64_t captures_during_warmup = 0;  // ... or before the lamp had warmed up
  int64_t moves = 0;                   // completed or attempted MoveTo/Home motions
  int64_t lamp_switches = 0;           // successful switchings

  // Captures that broke a rule of the session (a daemon's tests assert zero).
  int64_t violations() const {
    return captures_while_moving + captures_lamp_off + captures_during_warmup;
  }
};

// Thread-safe: every member takes the one mutex. SimMotor, SimLamp and SimCamera of one
// simulated rig share one SimWorld (through a std::shared_ptr).
class SimWorld {
 public:
  SimWorldState State() const;

  void SetPose(double h_deg, double v_deg);
  void SetMoving(bool moving);
  // Switching on starts the warm-up (lamp_ready false until SetLampReady()).
  void SetLamp(bool on);
  void SetLampReady();
  void CountMove();

  // Records that the shutter opened now; counts the violations it commits and returns the
  // state the exposure sees.
  SimWorldState RecordCapture();

 private:
  mutable std::mutex mu_;
  SimWorldState s_;
};

}  // namespace rig
