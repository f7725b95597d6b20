// MaestroMotor: the lamp arm on two hobby servos driven by a Pololu Maestro over its
// compact serial protocol, with a per-axis angle -> pulse-width calibration.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "config/config.h"
#include "capture/devices/motor.h"
#include "capture/devices/serial_port.h"

namespace rig {

// Compact-protocol command bytes (Pololu Maestro User's Guide, section 5.e/5.f).
inline constexpr uint8_t kMaestroSetTarget = 0x84;
inline constexpr uint8_t kMaestroSetSpeed = 0x87;
inline constexpr uint8_t kMaestroSetAcceleration = 0x89;
inline constexpr uint8_t kMaestroGetPosition = 0x90;
inline constexpr uint8_t kMaestroGetMovingState = 0x93;
inline constexpr uint8_t kMaestroGetErrors = 0xA1;

// Pulse width in quarter-microseconds for an angle: 4 * (us_at_zero + deg * us_per_deg),
// rounded.
int MaestroTargetQuarterUs(double deg, double us_at_zero, double us_per_deg);
// Speed limit in the Maestro's unit of 0.25 us / 10 ms (= 25 us/s), at least 1.
int MaestroSpeedValue(double deg_per_s, double us_per_deg);
// Acceleration limit in 0.25 us / 10 ms / 80 ms (= 312.5 us/s^2), 1..255.
int MaestroAccelValue(double deg_per_s2, double us_per_deg);
// The 4-byte command: command, channel, low 7 bits, high 7 bits.
std::string MaestroCommand(uint8_t command, int channel, int value);
// "serial protocol error (bit 4): ..., serial timeout (bit 5): ..." for the error register.
std::string DecodeMaestroErrors(uint16_t bits);

// Thread-compatible (one caller at a time). Errors name the port and, where there is one,
// the pose. "Homing" a servo is a move to pose 0,0: a servo knows its position.
class MaestroMotor final : public Motor {
 public:
  explicit MaestroMotor(MotorConfig config);
  ~MaestroMotor() override;

  std::string Describe() const override;
  Status Open() override;
  void Close() override;
  Status Home() override;
  Status MoveTo(const Pose& pose) override;
  Result<Pose> Position() override;
  Status Stop() override;
  Status Reconnect() override;

  const std::string& fault() const { return fault_; }
  int reconnects() const { return reconnects_; }
  // The speed and acceleration values sent per channel (h, v).
  std::array<int, 2> speed_values() const { return speed_; }
  std::array<int, 2> accel_values() const { return accel_; }

 private:
  Status OpenPort();
  Status Initialize();
  Result<int> GetPosition(int channel, bool interruptible = true);
  Result<bool> GetMoving(bool interruptible = true);
  Result<uint16_t> GetErrors(bool interruptible = true);
  Status DoMove(const Pose& pose);
  Status StopHere();
  Status AfterReconnect();
  Error Fail(ErrorCode code, const std::string& message) const;
  bool PortLost(const Error& e) const;
  std::array<int, 2> Targets(const Pose& pose) const;
  double ToDegrees(int axis, int quarter_us) const;

  MotorConfig config_;
  SerialSelector selector_;
  std::unique_ptr<SerialPort> port_;
  std::array<int, 2> channel_{}, speed_{}, accel_{};
  std::optional<Pose> last_pose_;
  std::string fault_;
  int reconnects_ = 0;
};

// The factory rig/backends.cc calls for motor.backend = "maestro".
std::unique_ptr<Motor> MakeMaestroMotor(const MotorConfig& config);

}  // namespace rig
