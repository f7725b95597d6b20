// GrblMotor: the lamp arm on a GRBL 1.1 controller (an Arduino with a CNC shield) over a
// serial port, in degrees (one controller unit = units_per_degree degrees).
#pragma once

#include <array>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "config/config.h"
#include "capture/devices/motor.h"
#include "capture/devices/serial_port.h"

namespace rig {

// GRBL 1.1 code tables (doc/csv/error_codes_en_US.csv, alarm_codes_en_US.csv):
// "error:20" -> "Unsupported or invalid g-code command found in block."
const char* GrblErrorMeaning(int code);
const char* GrblAlarmMeaning(int code);

// A parsed real-time status report "<Idle|MPos:1.000,2.000,0.000|FS:0,0|WCO:...>".
struct GrblStatus {
  std::string state;     // "Idle", "Run", "Hold", "Jog", "Alarm", "Door", "Check", "Home", "Sleep"
  int substate = -1;     // "Hold:0" -> 0 (hold complete), "Hold:1" -> 1 (decelerating)
  std::array<double, 3> mpos{};  // machine position (from MPos, or WPos + WCO)
  bool has_position = false;
  std::optional<std::array<double, 3>> wco;  // work coordinate offset, when reported
  bool position_is_work = false;  // the report gave WPos rather than MPos
  std::array<double, 3> wpos{};   // work position, when has_position and wco known or WPos given
  double feed = 0;
};
// Parses a status line; nothing when it is not a well-formed report.
std::optional<GrblStatus> ParseGrblStatus(std::string_view line);

// Thread-compatible (one caller at a time). Every error names the port, and the pose
// where there is one. A lost port (USB unplugged) during MoveTo/Home is recovered by
// Reconnect() once; a recovery that is impossible leaves the motor in a fault state that
// only Home() or Reconnect() clears.
class GrblMotor final : public Motor {
 public:
  explicit GrblMotor(MotorConfig config);
  ~GrblMotor() override;

  std::string Describe() const override;
  Status Open() override;
  void Close() override;
  Status Home() override;
  Status MoveTo(const Pose& pose) override;
  Result<Pose> Position() override;
  Status Stop() override;
  Status Reconnect() override;
  // Every pose's work coordinates inside the firmware's travel (machine space -$13n .. 0
  // after homing, work = machine - G54 - G92 as read with $#), when homing is enabled ($22=1).
  Status CheckReach(const std::vector<Pose>& poses) override;
  // $X: kills the alarm lock without homing (the controller's position is kept, unverified).
  Status Unlock() override;

  // Diagnostics (for logs, tests and the benchmark).
  const std::string& fault() const { return fault_; }
  const std::map<int, double>& settings() const { return settings_; }
  const std::string& state() const { return state_; }
  // The G54 and G92 offsets read with $# at open (machine units).
  const std::array<double, 3>& g54() const { return g54_; }
  int reconnects() const { return reconnects_; }
  int ignored_lines() const { return ignored_lines_; }

 private:
  enum class Kind { kOk, kError, kAlarm, kStatus, kBanner, kMessage, kSetting, kStartup, kGarbage };
  struct Line {
    Kind kind = Kind::kGarbage;
    int code = 0;
    std::string text;
  };
  enum class OnAlarm { kFail, kRecord };

  Status OpenPort();
  Status AwaitBanner(Seconds timeout);
  Status WaitForBannerOrReset();
  Line Classify(const std::string& text);
  Result<Line> NextLine(Seconds timeout, bool interruptible = true);
  Status SendRealtime(char c);
  Status Queue(const std::string& line);
  // Waits for the ok/error of the oldest outstanding line. error:N is returned as a
  // Line (kind kError), not as an Error.
  Result<Line> AwaitResponse(Seconds timeout, OnAlarm on_alarm, bool interruptible = true);
  Result<GrblStatus> QueryStatus(bool interruptible = true);
  Status ReadSettings();
  Status ReadBuildOptions();  // $I: HOMING_FORCE_SET_ORIGIN
  Status ReadOffsets();  // $#: G54 and G92
  // The one mapping of rig angles to the controller's work coordinates and back.
  std::array<double, 3> ToWork(const Pose& pose) const;
  Pose ToPose(const std::array<double, 3>& work) const;
  // Why the firmware would refuse `pose` (outside its travel), naming both limits; "" if not.
  std::string TravelViolation(const Pose& pose) const;
  // After the port came back: a status report (the controller kept running) or a banner
  // (it was reset); sends a soft reset only when it says nothing at all.
  Status ProbeAfterReopen(bool* was_reset);
  Status DoHome();
  Status DoMove(const Pose& pose);
  Status WaitIdleByPolling(const Pose& pose, const std::array<double, 3>& target);
  // A move that did not complete: feed hold, soft reset, fault.
  Error AbortMove(const Pose& pose, const Error& why);
  Status StopMotion(bool unlock);
  // How long a feed hold may take to stop, from the feed and $11n/$12n, with a margin.
  Seconds BrakeWait() const;
  Status AfterReconnect(bool was_reset);
  Error Fail(ErrorCode code, const std::string& message) const;
  Error AlarmError(int code, const std::string& during) const;
  // The alarm lock (power-up with homing enabled, or after an alarm): kFault, says $H / $X.
  Error AlarmLocked() const;
  bool PortLost(const Error& e) const;
  std::array<double, 3> WorkPosition(const GrblStatus& s) const;

  MotorConfig config_;
  SerialSelector selector_;
  std::unique_ptr<SerialPort> port_;
  int h_index_ = 0, v_index_ = 1;
  std::deque<std::pair<std::string, size_t>> outstanding_;  // line text, bytes in GRBL's buffer
  std::string state_ = "Unknown";
  std::array<double, 3> wco_{};
  std::array<double, 3> g54_{}, g92_{};
  bool offsets_known_ = false;
  bool force_set_origin_ = false;  // $I lists 'Z' (HOMING_FORCE_SET_ORIGIN)
  std::map<int, double> settings_;
  std::optional<Pose> last_pose_;
  std::string fault_;
  int pending_alarm_ = 0;
  bool reset_seen_ = false;
  int reconnects_ = 0;
  int ignored_lines_ = 0;
};

// The factory rig/backends.cc calls for motor.backend = "grbl".
std::unique_ptr<Motor> MakeGrblMotor(const MotorConfig& config);

}  // namespace rig
