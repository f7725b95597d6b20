// MaestroMotor: set target / speed / acceleration, poll the moving state, verify the
// position and read (and so clear) the error register after every move.
#include "capture/devices/maestro_motor.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <thread>

#include "config/log.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

Clock::time_point Deadline(Seconds s) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(s);
}

// Maestro time units: speed in 0.25 us per 10 ms, acceleration in that per 80 ms.
constexpr double kSpeedUnitUsPerS = 0.25 / 0.010;            // 25 us/s
constexpr double kAccelUnitUsPerS2 = kSpeedUnitUsPerS / 0.080;  // 312.5 us/s^2

}  // namespace

int MaestroTargetQuarterUs(double deg, double us_at_zero, double us_per_deg) {
  return static_cast<int>(std::lround(4.0 * (us_at_zero + deg * us_per_deg)));
}

int MaestroSpeedValue(double deg_per_s, double us_per_deg) {
  double v = deg_per_s * std::fabs(us_per_deg) / kSpeedUnitUsPerS;
  return static_cast<int>(std::clamp<long>(std::lround(v), 1, 16383));
}

int MaestroAccelValue(double deg_per_s2, double us_per_deg) {
  double v = deg_per_s2 * std::fabs(us_per_deg) / kAccelUnitUsPerS2;
  return static_cast<int>(std::clamp<long>(std::lround(v), 1, 255));
}

std::string MaestroCommand(uint8_t command, int channel, int value) {
  std::string b(4, '\0');
  b[0] = static_cast<char>(command);
  b[1] = static_cast<char>(channel & 0x7F);
  b[2] = static_cast<char>(value & 0x7F);
  b[3] = static_cast<char>((value >> 7) & 0x7F);
  return b;
}

std::string DecodeMaestroErrors(uint16_t bits) {
  static const char* kMeaning[] = {
      "serial signal error (bit 0): a stop bit was not detected at the expected place (baud rate mismatch?)",
      "serial overrun error (bit 1): the UART's internal buffer filled up",
      "serial buffer full (bit 2): the firmware's receive buffer filled up and a byte was lost",
      "serial CRC error (bit 3): a command packet's CRC byte did not match",
      "serial protocol error (bit 4): an incorrectly formatted or nonsensical command packet",
      "serial timeout (bit 5): no valid command within the serial timeout period",
      "script stack error (bit 6): the user script over- or underflowed its stack",
      "script call stack error (bit 7): the user script over- or underflowed its call stack",
      "script program counter error (bit 8): the user script's program counter went out of bounds",
  };
  std::string out;
  for (int i = 0; i < 16; ++i) {
    if (!(bits & (1u << i))) continue;
    if (!out.empty()) out += "; ";
    out += i < 9 ? kMeaning[i] : fmt::format("unknown error bit {}", i);
  }
  return out;
}

MaestroMotor::MaestroMotor(MotorConfig config)
    : config_(std::move(config)), selector_(SerialSelector::FromConfig(config_)) {
  const auto& m = config_.maestro;
  channel_ = {m.h_channel, m.v_channel};
  speed_ = {MaestroSpeedValue(config_.speed_deg_per_s, m.h_us_per_deg),
            MaestroSpeedValue(config_.speed_deg_per_s, m.v_us_per_deg)};
  accel_ = {MaestroAccelValue(config_.accel_deg_per_s2, m.h_us_per_deg),
            MaestroAccelValue(config_.accel_deg_per_s2, m.v_us_per_deg)};
}

MaestroMotor::~MaestroMotor() { Close(); }

std::string MaestroMotor::Describe() const { return "maestro on " + selector_.Describe(); }

Error MaestroMotor::Fail(ErrorCode code, const std::string& message) const {
  return Error{code, message, selector_.Describe()};
}

bool MaestroMotor::PortLost(const Error& e) const {
  return e.code == ErrorCode::kIo && (port_ == nullptr || port_->lost());
}

std::array<int, 2> MaestroMotor::Targets(const Pose& pose) const {
  const auto& m = config_.maestro;
  return {MaestroTargetQuarterUs(pose.h_deg, m.h_us_at_zero, m.h_us_per_deg),
          MaestroTargetQuarterUs(pose.v_deg, m.v_us_at_zero, m.v_us_per_deg)};
}

double MaestroMotor::ToDegrees(int axis, int quarter_us) const {
  const auto& m = config_.maestro;
  double us = quarter_us / 4.0;
  return axis == 0 ? (us - m.h_us_at_zero) / m.h_us_per_deg : (us - m.v_us_at_zero) / m.v_us_per_deg;
}

Result<int> MaestroMotor::GetPosition(int channel, bool interruptible) {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  char cmd[2] = {static_cast<char>(kMaestroGetPosition), static_cast<char>(channel)};
  RIG_TRY(port_->Write(std::string_view(cmd, 2), Seconds(config_.reply_timeout_s)));
  auto r = port_->ReadExact(2, Seconds(config_.reply_timeout_s), interruptible);
  if (!r.ok()) return r.error();
  const auto& b = r.value();
  return static_cast<int>(static_cast<uint8_t>(b[0]) | (static_cast<uint8_t>(b[1]) << 8));
}

Result<bool> MaestroMotor::GetMoving(bool interruptible) {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  char cmd = static_cast<char>(kMaestroGetMovingState);
  RIG_TRY(port_->Write(std::string_view(&cmd, 1), Seconds(config_.reply_timeout_s)));
  RIG_ASSIGN_OR_RETURN(std::string b, port_->ReadExact(1, Seconds(config_.reply_timeout_s), interruptible));
  uint8_t v = static_cast<uint8_t>(b[0]);
  if (v > 1) {
    (void)port_->FlushInput();
    return Fail(ErrorCode::kDevice, fmt::format("unexpected moving-state reply 0x{:02x}", v));
  }
  return v == 1;
}

Result<uint16_t> MaestroMotor::GetErrors(bool interruptible) {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  char cmd = static_cast<char>(kMaestroGetErrors);
  RIG_TRY(port_->Write(std::string_view(&cmd, 1), Seconds(config_.reply_timeout_s)));
  RIG_ASSIGN_OR_RETURN(std::string b, port_->ReadExact(2, Seconds(config_.reply_timeout_s), interruptible));
  return static_cast<uint16_t>(static_cast<uint8_t>(b[0]) | (static_cast<uint8_t>(b[1]) << 8));
}

Status MaestroMotor::OpenPort() {
  port_.reset();
  RIG_ASSIGN_OR_RETURN(port_, SerialPort::Open(selector_));
  return Ok();
}

Status MaestroMotor::Initialize() {
  // Reading the error register clears it: errors from before we opened are not ours.
  RIG_ASSIGN_OR_RETURN(uint16_t stale, GetErrors());
  if (stale != 0)
    Log("motion")->warn("maestro port={} cleared errors from before opening: {}", selector_.Describe(),
                        DecodeMaestroErrors(stale));
  std::string cmds;
  for (int a = 0; a < 2; ++a) {
    cmds += MaestroCommand(kMaestroSetSpeed, channel_[a], speed_[a]);
    cmds += MaestroCommand(kMaestroSetAcceleration, channel_[a], accel_[a]);
  }
  RIG_TRY(port_->Write(cmds, Seconds(config_.reply_timeout_s)));
  Log("motion")->info("maestro open port={} device={} channels h={} v={} speed={},{} accel={},{}",
                      selector_.Describe(), port_->device(), channel_[0], channel_[1], speed_[0], speed_[1],
                      accel_[0], accel_[1]);
  return Ok();
}

Status MaestroMotor::Open() {
  Close();
  RIG_TRY(OpenPort());
  Status st = Initialize();
  if (!st.ok()) port_.reset();
  return st;
}

void MaestroMotor::Close() { port_.reset(); }

Status MaestroMotor::Home() {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  fault_.clear();
  Status st = MoveTo(Pose{0, 0});
  if (!st.ok()) return st;
  Log("motion")->info("maestro homed (moved to pose 0,0) port={}", selector_.Describe());
  return Ok();
}

Status MaestroMotor::MoveTo(const Pose& pose) {
  std::string where = "pose " + pose.Name();
  if (const std::string why = SoftLimitViolation(config_, pose); !why.empty())
    return Fail(ErrorCode::kInvalidInput, why).Within(where);
  if (!port_) return Fail(ErrorCode::kFault, "not open").Within(where);
  if (!fault_.empty())
    return Fail(ErrorCode::kFault, "in fault state (" + fault_ + "): home or reconnect first").Within(where);
  Status st = DoMove(pose);
  if (!st.ok() && PortLost(st.error())) {
    Log("motion")->warn("maestro port={} lost during the move to {}; reconnecting", selector_.Describe(),
                        pose.Name());
    Status rc = Reconnect();
    if (!rc.ok()) return rc.error().Within(where);
    st = DoMove(pose);
  }
  if (!st.ok()) return st.error().Within(where);
  return Ok();
}

Status MaestroMotor::DoMove(const Pose& pose) {
  auto targets = Targets(pose);
  for (int a = 0; a < 2; ++a) {
    if (targets[a] < 1 || targets[a] > 16383)
      return Fail(ErrorCode::kInvalidInput,
                  fmt::format("pulse width {:.2f} us on channel {} is outside what the Maestro can send",
                              targets[a] / 4.0, channel_[a]));
  }
  last_pose_.reset();
  RIG_TRY(port_->Write(MaestroCommand(kMaestroSetTarget, channel_[0], targets[0]) +
                           MaestroCommand(kMaestroSetTarget, channel_[1], targets[1]),
                       Seconds(config_.reply_timeout_s)));
  auto deadline = Deadline(Seconds(config_.move_timeout_s));
  for (;;) {
    auto next_poll = Deadline(Seconds(config_.maestro.poll_interval_s));
    auto moving = GetMoving();
    if (!moving.ok()) {
      if (moving.error().code == ErrorCode::kInterrupted) {
        Status st = StopHere();
        Error e = moving.error();
        if (!st.ok()) e.message += "; stopping failed: " + st.error().message;
        return e;
      }
      return moving.error();
    }
    if (!*moving) break;
    if (Clock::now() >= deadline) {
      std::string where;
      for (int a = 0; a < 2; ++a) {
        auto p = GetPosition(channel_[a], false);
        if (p.ok())
          where += fmt::format("{}channel {} at {:.2f} us (target {:.2f} us)", where.empty() ? "" : ", ",
                               channel_[a], *p / 4.0, targets[a] / 4.0);
      }
      Status st = StopHere();
      fault_ = fmt::format("the servos did not stop moving within {:.1f} s ({})", config_.move_timeout_s, where);
      Log("motion")->error("maestro port={} fault: {}", selector_.Describe(), fault_);
      return Fail(ErrorCode::kTimeout, fault_ + (st.ok() ? "; targets set to where they stopped"
                                                         : "; stopping failed: " + st.error().message));
    }
    while (Clock::now() < next_poll) {
      if (SerialInterruptRequested()) {
        (void)StopHere();
        return Fail(ErrorCode::kInterrupted, "interrupted while moving; targets set to where the servos are");
      }
      std::this_thread::sleep_for(
          std::min<Clock::duration>(next_poll - Clock::now(), std::chrono::milliseconds(5)));
    }
  }
  // The Maestro clamps targets to each channel's configured range: moving-state 0 alone does
  // not prove the servo is where we asked.
  const int tolerance = static_cast<int>(std::lround(config_.maestro.position_tolerance_us * 4));
  for (int a = 0; a < 2; ++a) {
    RIG_ASSIGN_OR_RETURN(int pos, GetPosition(channel_[a]));
    if (std::abs(pos - targets[a]) > tolerance) {
      fault_ = fmt::format("channel {} stopped at {:.2f} us, not at the target {:.2f} us (is the target outside "
                           "the channel's min/max range in the Maestro's settings?)",
                           channel_[a], pos / 4.0, targets[a] / 4.0);
      return Fail(ErrorCode::kDevice, fault_);
    }
  }
  RIG_ASSIGN_OR_RETURN(uint16_t errors, GetErrors());
  if (errors != 0)
    return Fail(ErrorCode::kDevice, fmt::format("the Maestro reported errors 0x{:04x}: {}", errors,
                                                DecodeMaestroErrors(errors)));
  last_pose_ = pose;
  return Ok();
}

Status MaestroMotor::StopHere() {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  std::string cmds;
  for (int a = 0; a < 2; ++a) {
    RIG_ASSIGN_OR_RETURN(int pos, GetPosition(channel_[a], false));
    if (pos > 0) cmds += MaestroCommand(kMaestroSetTarget, channel_[a], pos);
  }
  return port_->Write(cmds, Seconds(config_.reply_timeout_s));
}

Result<Pose> MaestroMotor::Position() {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  std::array<double, 2> deg{};
  for (int a = 0; a < 2; ++a) {
    RIG_ASSIGN_OR_RETURN(int pos, GetPosition(channel_[a]));
    if (pos == 0)
      return Fail(ErrorCode::kDevice,
                  fmt::format("channel {} is off (no pulses): its position is unknown", channel_[a]));
    deg[a] = ToDegrees(a, pos);
  }
  return Pose{deg[0], deg[1]};
}

Status MaestroMotor::Stop() {
  if (!port_) return Ok();
  last_pose_.reset();
  return StopHere();
}

Status MaestroMotor::AfterReconnect() {
  if (config_.after_reconnect == "home") {
    fault_.clear();
    return DoMove(Pose{0, 0});
  }
  if (!last_pose_) {
    fault_ = "position unknown after reconnect and after_reconnect = verify";
    return Fail(ErrorCode::kFault, fault_ + ": home first");
  }
  auto targets = Targets(*last_pose_);
  const int tolerance = static_cast<int>(std::lround(config_.maestro.position_tolerance_us * 4));
  for (int a = 0; a < 2; ++a) {
    RIG_ASSIGN_OR_RETURN(int pos, GetPosition(channel_[a]));
    if (std::abs(pos - targets[a]) > tolerance) {
      fault_ = fmt::format("channel {} is at {:.2f} us after reconnect, not at {:.2f} us of the last pose {}",
                           channel_[a], pos / 4.0, targets[a] / 4.0, last_pose_->Name());
      return Fail(ErrorCode::kFault, fault_ + ": re-home (after_reconnect = verify)");
    }
  }
  fault_.clear();
  return Ok();
}

Status MaestroMotor::Reconnect() {
  ++reconnects_;
  auto log = Log("motion");
  port_.reset();
  Error last = Fail(ErrorCode::kFault, "no attempt made");
  double backoff_s = config_.retry_backoff_s;
  const int attempts = std::max(1, config_.retries);
  std::optional<Pose> before = last_pose_;
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    auto until = Deadline(Seconds(backoff_s));
    while (Clock::now() < until) {
      if (SerialInterruptRequested()) return Fail(ErrorCode::kInterrupted, "interrupted while reconnecting");
      std::this_thread::sleep_for(std::min<Clock::duration>(until - Clock::now(), std::chrono::milliseconds(20)));
    }
    backoff_s *= 2;
    Status st = OpenPort();
    if (st.ok()) st = Initialize();
    if (st.ok()) {
      last_pose_ = before;
      st = AfterReconnect();
      if (st.ok()) {
        log->warn("maestro port={} reconnected (attempt {} of {}) after_reconnect={}", selector_.Describe(),
                  attempt, attempts, config_.after_reconnect);
        return Ok();
      }
      if (!PortLost(st.error())) return st;
    }
    if (st.error().code == ErrorCode::kInterrupted) return st;
    last = st.error();
    log->warn("maestro port={} reconnect attempt {} of {} failed: {}", selector_.Describe(), attempt, attempts,
              last.message);
    port_.reset();
  }
  fault_ = fmt::format("the port did not come back after {} attempts ({})", attempts, last.message);
  return Fail(ErrorCode::kFault, fault_);
}

std::unique_ptr<Motor> MakeMaestroMotor(const MotorConfig& config) {
  return std::make_unique<MaestroMotor>(config);
}

}  // namespace rig
