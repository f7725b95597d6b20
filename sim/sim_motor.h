// The simulated lamp arm: two axes in degrees with trapezoidal motion, soft limits, homing,
// device latency and faults on demand.
//
// Motion: each axis follows a trapezoidal profile (speed_deg_per_s, accel_deg_per_s2 from
// [motor]); both axes start together and a move lasts as long as the slower axis. MoveTo()
// sleeps that time * sim.latency_scale (0: no waiting) with the world's `moving` flag set,
// and returns once the arm has arrived. The arm rests at (0, 0) when the object is made.
//
// Faults ([sim.motor]); move numbers count MoveTo() calls that start a motion (open, inside
// the soft limits, position known), from 1 over the object's life; Home() is not a move:
//   stall_at_move = [n, ...]  move n stops half way with kDevice "stalled"; the position is
//                             unknown (Position() and MoveTo() fail) until Home() or
//                             Reconnect() re-homes the axes
//   timeout_at_move = [n, ...]  move n gets no answer: kTimeout after reply_timeout_s *
//                             latency_scale; the arm has not left, its position stays known
//   fail_forever_after = K    moves K, K+1, ... fail with kDevice (Reconnect() succeeds, the
//                             moves keep failing)
// Every error's context is "sim motor". Thread-safe; Stop() may come from another thread and
// ends a move in progress (kInterrupted, the position where the arm stopped).
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <string>

#include "config/config.h"
#include "capture/devices/motor.h"
#include "sim/world.h"

namespace rig {

class SimMotor final : public Motor {
 public:
  // Uses config.motor (speed, acceleration, soft limits, after_reconnect, reply_timeout_s),
  // config.sim.motor (faults) and config.sim.latency_scale.
  SimMotor(const Config& config, std::shared_ptr<SimWorld> world);

  std::string Describe() const override;
  Status Open() override;
  void Close() override;
  Status Home() override;
  Status MoveTo(const Pose& pose) override;
  Result<Pose> Position() override;
  Status Stop() override;
  Status Reconnect() override;

  // The duration of a trapezoidal move of `distance_deg` (either sign) on one axis:
  // d / v + v / a when the axis reaches full speed (d >= v^2 / a), else 2 sqrt(d / a).
  static Seconds AxisMotionTime(double distance_deg, double speed_deg_per_s,
                                double accel_deg_per_s2);
  // The duration of a move of both axes from `from` to `to` (the slower axis).
  Seconds MotionTime(const Pose& from, const Pose& to) const;

  struct Stats {
    int64_t moves = 0;      // MoveTo motions started (the fault numbering)
    int64_t homings = 0;
    int64_t faults = 0;     // injected failures
    Seconds motion_time{0};  // simulated (unscaled) time the arm spent moving, homing included
  };
  Stats stats() const;

 private:
  // Moves the arm from its true position towards `to` for `fraction` of the motion time,
  // sleeping the scaled time; returns false when Stop() interrupted it.
  bool Run(const Pose& to, double fraction);
  double AxisPosition(double from, double to, double t_s) const;

  MotorConfig motor_;
  SimMotorConfig faults_;
  double latency_scale_;
  std::shared_ptr<SimWorld> world_;

  mutable std::mutex mu_;
  std::atomic<bool> stop_{false};
  bool open_ = false;
  bool known_ = true;  // false after a stall, until homed
  Stats stats_;
};

}  // namespace rig
