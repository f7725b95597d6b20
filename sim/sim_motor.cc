// The simulated lamp arm.
#include "sim/sim_motor.h"

#include <algorithm>
#include <cmath>
#include <thread>

#include <fmt/format.h>

namespace rig {
namespace {

constexpr const char* kMotorDevice = "sim motor";

Error MotorError(ErrorCode code, const std::string& message) {
  return Error{code, message, kMotorDevice};
}

}  // namespace

SimMotor::SimMotor(const Config& config, std::shared_ptr<SimWorld> world)
    : motor_(config.motor),
      faults_(config.sim.motor),
      latency_scale_(config.sim.latency_scale),
      world_(std::move(world)) {
  RIG_CHECK(world_ != nullptr, "SimMotor needs a world");
}

std::string SimMotor::Describe() const { return "sim motor"; }

Status SimMotor::Open() {
  std::lock_guard<std::mutex> lock(mu_);
  open_ = true;
  return Ok();
}

void SimMotor::Close() {
  stop_ = true;
  std::lock_guard<std::mutex> lock(mu_);
  open_ = false;
}

Seconds SimMotor::AxisMotionTime(double distance_deg, double v, double a) {
  const double d = std::fabs(distance_deg);
  if (d == 0) return Seconds(0);
  if (d >= v * v / a) return Seconds(d / v + v / a);
  return Seconds(2 * std::sqrt(d / a));
}

Seconds SimMotor::MotionTime(const Pose& from, const Pose& to) const {
  const double v = motor_.speed_deg_per_s, a = motor_.accel_deg_per_s2;
  return std::max(AxisMotionTime(to.h_deg - from.h_deg, v, a),
                  AxisMotionTime(to.v_deg - from.v_deg, v, a));
}

double SimMotor::AxisPosition(double from, double to, double t) const {
  const double d = std::fabs(to - from), sign = to >= from ? 1 : -1;
  const double v = motor_.speed_deg_per_s, a = motor_.accel_deg_per_s2;
  const double total = AxisMotionTime(d, v, a).count();
  if (d == 0 || t >= total) return to;
  if (t <= 0) return from;
  // Peak speed: v, or less on a short move that never reaches it.
  const double vp = d >= v * v / a ? v : std::sqrt(d * a);
  const double ta = vp / a;
  double s;
  if (t < ta) s = 0.5 * a * t * t;
  else if (t < total - ta) s = 0.5 * a * ta * ta + vp * (t - ta);
  else s = d - 0.5 * a * (total - t) * (total - t);
  return from + sign * std::clamp(s, 0.0, d);
}

bool SimMotor::Run(const Pose& to, double fraction) {
  const SimWorldState st = world_->State();
  const Pose from{st.h_deg, st.v_deg};
  const double total = MotionTime(from, to).count();
  const double run = total * fraction;
  world_->CountMove();
  if (run <= 0) {
    world_->SetPose(fraction >= 1 ? to.h_deg : from.h_deg, fraction >= 1 ? to.v_deg : from.v_deg);
    return true;
  }
  world_->SetMoving(true);
  double done = run;  // simulated seconds moved
  bool stopped = false;
  if (latency_scale_ > 0) {
    const auto start = std::chrono::steady_clock::now();
    const auto end = start + std::chrono::duration_cast<std::chrono::nanoseconds>(
                                 Seconds(run * latency_scale_));
    // Sleep in slices so that Stop() ends the move promptly.
    while (std::chrono::steady_clock::now() < end) {
      if (stop_) {
        stopped = true;
        done = Seconds(std::chrono::steady_clock::now() - start).count() / latency_scale_;
        break;
      }
      std::this_thread::sleep_until(
          std::min(end, std::chrono::steady_clock::now() + std::chrono::milliseconds(10)));
    }
  } else if (stop_) {
    stopped = true;
    done = 0;
  }
  done = std::min(done, run);
  world_->SetPose(AxisPosition(from.h_deg, to.h_deg, done), AxisPosition(from.v_deg, to.v_deg, done));
  world_->SetMoving(false);
  stats_.motion_time += Seconds(done);
  return !stopped;
}

Status SimMotor::Home() {
  std::lock_guard<std::mutex> lock(mu_);
  if (!open_) return MotorError(ErrorCode::kDevice, "home before Open()");
  stop_ = false;
  ++stats_.homings;
  if (!Run(Pose{0, 0}, 1.0)) return MotorError(ErrorCode::kInterrupted, "homing stopped");
  known_ = true;
  return Ok();
}

Status SimMotor::MoveTo(const Pose& pose) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!open_) return MotorError(ErrorCode::kDevice, "move before Open()");
  const auto& m = motor_;
  if (const std::string why = SoftLimitViolation(m, pose); !why.empty())
    return MotorError(ErrorCode::kInvalidInput, fmt::format("pose {}: {}", pose.Name(), why));
  if (!known_)
    return MotorError(ErrorCode::kDevice,
                      fmt::format("move to pose {} refused: position unknown after a stall; "
                                  "home first", pose.Name()));
  stop_ = false;
  const int64_t n = ++stats_.moves;
  const auto in = [n](const std::vector<int>& v) {
    return std::find(v.begin(), v.end(), n) != v.end();
  };
  if (faults_.fail_forever_after > 0 && n >= faults_.fail_forever_after) {
    ++stats_.faults;
    return MotorError(ErrorCode::kDevice,
                      fmt::format("move {} to pose {} failed: controller not responding "
                                  "(simulated fault from move {} on)",
                                  n, pose.Name(), faults_.fail_forever_after));
  }
  if (in(faults_.stall_at_move)) {
    ++stats_.faults;
    Run(pose, 0.5);
    known_ = false;
    return MotorError(ErrorCode::kDevice,
                      fmt::format("move {} to pose {}: stalled (simulated); position unknown "
                                  "until homed", n, pose.Name()));
  }
  if (in(faults_.timeout_at_move)) {
    ++stats_.faults;
    if (latency_scale_ > 0)
      std::this_thread::sleep_for(Seconds(motor_.reply_timeout_s * latency_scale_));
    return MotorError(ErrorCode::kTimeout,
                      fmt::format("move {} to pose {}: no answer within {} s (simulated)", n,
                                  pose.Name(), motor_.reply_timeout_s));
  }
  if (!Run(pose, 1.0))
    return MotorError(ErrorCode::kInterrupted, fmt::format("move to pose {} stopped", pose.Name()));
  return Ok();
}

Result<Pose> SimMotor::Position() {
  std::lock_guard<std::mutex> lock(mu_);
  if (!open_) return MotorError(ErrorCode::kDevice, "position before Open()");
  if (!known_) return MotorError(ErrorCode::kDevice, "position unknown after a stall; home first");
  const SimWorldState st = world_->State();
  return Pose{st.h_deg, st.v_deg};
}

Status SimMotor::Stop() {
  // No lock: a move in progress holds it; the flag ends the move's sleep.
  stop_ = true;
  return Ok();
}

Status SimMotor::Reconnect() {
  Close();
  RIG_TRY(Open());
  bool home;
  {
    std::lock_guard<std::mutex> lock(mu_);
    home = motor_.after_reconnect == "home" || !known_;
  }
  if (home) return Home();
  return Ok();
}

SimMotor::Stats SimMotor::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

}  // namespace rig
