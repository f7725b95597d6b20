// A Pololu Mini Maestro emulated byte for byte on a pseudo-terminal: the compact protocol
// (and the Pololu protocol, 0xAA + device number), servo outputs that follow their targets
// under the speed and acceleration limits every 10 ms, the error register, and faults.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sim/grbl_emulator.h"

namespace rig {

struct MaestroEmulatorOptions {
  double time_scale = 1.0;     // emulated seconds per real second
  int channels = 12;           // Mini Maestro 12
  int device_number = 12;      // for the Pololu protocol
  double min_us = 992, max_us = 2000;  // each channel's range: targets are clamped to it
  // Faults on demand. Target numbers count Set Target commands (two per pose).
  int stall_at_target = 0;          // that channel freezes half way: moving state stays 1
  int error_at_target = 0;          // that command sets `error_bits` in the error register
  uint16_t error_bits = 0x0010;     // default: serial protocol error
  int disconnect_at_target = 0;     // unplugged when that command arrives
  double replug_after_s = 0.5;      // real seconds
  bool reset_on_replug = true;      // false: targets and positions survive the unplug
};

class MaestroEmulator final : public PtyEmulator {
 public:
  explicit MaestroEmulator(MaestroEmulatorOptions options = {});
  ~MaestroEmulator() override;

  // In quarter-microseconds.
  int target(int channel) const;
  int position(int channel) const;
  int speed(int channel) const;
  int acceleration(int channel) const;
  uint16_t errors() const;
  void SetErrors(uint16_t bits);  // raises error bits now (thread-safe)
  int set_target_count() const;
  // Emulated duration of every completed motion (first target of a batch until every
  // channel reached its target), emulated seconds.
  std::vector<double> motion_times_s() const;
  void SetOptions(const MaestroEmulatorOptions& options);

 private:
  struct Channel {
    int target = 0;        // 0: off (no pulses)
    double position = 0;   // quarter-us; 0 while off
    double velocity = 0;   // quarter-us per 10 ms
    int speed = 0, accel = 0;
    bool stalled = false;
    double stall_at = 0;
  };

  void OnPowerUp() override;
  void OnInput(std::string_view bytes) override;
  void OnTick() override;
  void Execute();
  void Update10ms();
  bool AnyMoving() const;

  MaestroEmulatorOptions options_;
  std::vector<Channel> ch_;
  uint16_t errors_ = 0;
  std::string packet_;         // the command being received
  bool pololu_ = false;        // inside an 0xAA packet
  double next_update_ = 0;     // emulated time of the next 10 ms update
  int set_targets_ = 0;
  bool in_motion_ = false;
  double motion_start_ = 0;
  std::vector<double> motion_times_;
};

Result<std::unique_ptr<MaestroEmulator>> StartMaestroEmulator(const MaestroEmulatorOptions& options,
                                                              const std::string& link_path = "");

}  // namespace rig
