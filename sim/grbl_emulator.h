// A GRBL 1.1 controller emulated byte for byte on a pseudo-terminal, with faults on demand;
// and PtyEmulator, the pseudo-terminal device end both emulators (GRBL, Maestro) share.
//
// The emulator owns the pty master (openpty, raw mode) and a thread; a client opens the
// slave (device_path(), or the stable link path) like any serial port. Unplug() closes the
// pty (the client sees a hang-up and the link vanishes); after the replug delay a new pty
// appears at the same link path, like a USB device plugged back in.
//
// Emulated time: motion and homing run `time_scale` times faster than real time (tests use
// 50..1000); timings the client observes (banner delay, replug delay) are real seconds.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "config/result.h"

namespace rig {

// The device end of a pseudo-terminal, run on its own thread. Subclasses implement the
// protocol; their hooks run on the emulator thread with mu_ held.
class PtyEmulator {
 public:
  virtual ~PtyEmulator();
  PtyEmulator(const PtyEmulator&) = delete;
  PtyEmulator& operator=(const PtyEmulator&) = delete;

  // Creates the pty (and the symlink `link_path` to it, replaced atomically, if not empty)
  // and starts the thread.
  Status Start(const std::string& link_path = "");
  // Stops the thread, closes the pty and removes the link. Idempotent.
  void Stop();

  // The path clients open: the link if one was given, else the pty slave (/dev/pts/N).
  std::string path() const;
  std::string device_path() const;
  // USB unplugged now; plugged back (a new pty at the same link) after `replug_after`
  // real seconds, with a power-up unless `keep_state`.
  void Unplug(double replug_after_s, bool keep_state = false);
  bool plugged() const;
  // How many ptys were created (1 after Start, +1 per replug).
  int plug_count() const;

 protected:
  explicit PtyEmulator(double time_scale);
  // Emulated seconds since Start (real seconds * time_scale).
  double Now() const;
  double RealNow() const;
  double time_scale() const { return time_scale_; }
  // Queues bytes for the client, not before `real_delay_s` from now and after everything
  // queued before (order is kept). Bytes written while nobody reads are lost once the
  // pty's buffer is full, as on a real line.
  void Send(std::string_view bytes, double real_delay_s = 0);
  void DropQueuedOutput();
  bool PluggedLocked() const { return plugged_; }
  void UnplugLocked(double replug_after_s, bool keep_state);

  virtual void OnPowerUp() = 0;               // a new pty, or the client's open resets us
  virtual void OnClientOpen() {}              // a client opened the slave (DTR rises)
  virtual void OnInput(std::string_view bytes) = 0;
  virtual void OnTick() = 0;                  // about every millisecond

  mutable std::mutex mu_;

 private:
  Status CreatePty();
  void ClosePty();
  void Run();
  void FlushOutput();

  const double time_scale_;
  std::string link_path_, device_path_;
  int master_fd_ = -1, slave_fd_ = -1, inotify_fd_ = -1, watch_ = -1, wake_fd_[2] = {-1, -1};
  std::thread thread_;
  std::atomic<bool> stop_{false};
  bool plugged_ = false;
  bool keep_state_on_replug_ = false;
  double replug_at_real_ = 0;
  int plug_count_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::deque<std::pair<double, std::string>> out_;  // (real time due, bytes)
};

struct GrblEmulatorOptions {
  double time_scale = 1.0;        // emulated seconds per real second
  double banner_delay_s = 1.5;    // real seconds from power-up / DTR reset to the banner
  bool reset_on_open = true;      // an Arduino resets when the port is opened (DTR)
  bool homing_enabled = true;     // $22: homing cycle enabled, alarm lock at power-up
  // The firmware build (config.h). true: stock GRBL, HOMING_CYCLE_0 = Z first, then X and Y;
  // with no Z switch $H searches Z for 1.5 x $132, ends in ALARM:9 and X, Y never move.
  // false: the two-axis build, HOMING_CYCLE_0 = X|Y, no Z cycle (docs/rig-setup.md).
  bool stock_homing_cycle = false;
  // HOMING_FORCE_SET_ORIGIN in config.h: after homing every homed axis is at machine 0, and
  // the travel lies on the side the axis homed from: 0 .. $13n when it homed towards its
  // negative end ($23 bit set), -$13n .. 0 otherwise (system_check_travel_limits). $I lists
  // the build option as 'Z'.
  bool homing_force_set_origin = false;
  // The machine: which axes have a limit switch (bit 0 X, 1 Y, 2 Z), and which of those sit
  // at their axis's negative end (the rig's 0 deg end). An axis homes towards its negative
  // end when its $23 bit is set, towards the positive end when clear (limits.c); homing away
  // from the switch searches 1.5 x $13n and ends in ALARM:9.
  int switch_axes = 0b011;
  int switches_at_negative_end = 0b011;
  // The G54 work offset stored in EEPROM (machine units). Absent: what the guide's
  // `G10 L20 P1 X0 Y0` right after homing leaves (the homed machine position), or 0 with
  // homing disabled (work = machine, 0 at power-up).
  std::optional<std::array<double, 3>> g54;
  // Settings written over the defaults ($100.. steps/unit, $110.. max rate units/min,
  // $120.. acceleration units/s^2, $24/$25 homing feed/seek, $27 pull-off, $130.. travel).
  std::map<int, double> settings;

  // Faults on demand. Move numbers count accepted motion lines (G0/G1 with axis words).
  bool no_banner = false;         // never prints its banner (dead firmware, wrong baud)
  int garbage_every = 0;          // every Nth line out: a garbage line first, then the line in two pieces
  int error_at_move = 0;          // this motion line is answered error:`error_code`, not executed
  int error_code = 20;
  int alarm_at_move = 0;          // half way through this move: ALARM:`alarm_code`, motion stops
  int alarm_code = 1;             // 1 and 2 are critical: "[MSG:Reset to continue]"
  int stall_at_move = 0;          // this move stops half way and never reaches Idle
  int disconnect_mid_move = 0;    // unplugged half way through this move; motion goes on
  int homing_fail_alarm = 0;      // 0: homing works; 8 or 9: $H fails with that alarm
  int disconnect_at_move = 0;     // unplugged when this motion line arrives
  double replug_after_s = 0.5;    // real seconds until it is back
  bool reset_on_replug = true;    // false: state and position survive the unplug
};

// GRBL 1.1h as seen from its serial port: banner, line protocol with ok/error:N, status
// reports, planner with trapezoidal motion, G4 dwell, $H homing with limit switches (the
// cycles of the build, direction by $23, machine space negative after homing, or at the
// origin with HOMING_FORCE_SET_ORIGIN), the G54 work offset (G10 L2/L20 P1, $#, WCO), soft limits ($20:
// ALARM:2, then silent, not even '?', until a reset), alarm lock, feed hold and resume, soft
// reset, $$ settings. Not emulated: arcs, jogging, overrides, probing, spindle, coolant, check
// mode, G92, G55-G59, startup blocks.
class GrblEmulator final : public PtyEmulator {
 public:
  explicit GrblEmulator(GrblEmulatorOptions options = {});
  ~GrblEmulator() override;

  // Machine position in units (X, Y, Z), now.
  std::array<double, 3> Position() const;
  // Work position (machine position - G54), what the client's G-code addresses.
  std::array<double, 3> WorkPosition() const;
  std::string State() const;  // "Idle", "Run", "Hold:0", "Home", "Alarm", ...
  int moves() const;          // motion lines accepted
  int homings() const;        // successful homing cycles
  int resets() const;         // soft resets (0x18) and power-ups
  int lines() const;          // lines received
  // Emulated duration of every completed motion block, in order (emulated seconds).
  std::vector<double> motion_times_s() const;
  // The G54 work offset (machine units).
  std::array<double, 3> WorkOffset() const;
  // Changes faults while running (thread-safe).
  void SetOptions(const GrblEmulatorOptions& options);

 private:
  struct Block {
    std::array<double, 3> from{}, to{};
    double v = 0, a = 1, length = 0;   // units/s, units/s^2, units
    double t_start = 0, duration = 0;  // emulated seconds
    double t_accel = 0, v_peak = 0;
    bool started = false;
    bool stall = false, alarm = false, unplug = false;
    int move_number = 0;
  };

  void OnPowerUp() override;
  void OnClientOpen() override;
  void OnInput(std::string_view bytes) override;
  void OnTick() override;

  void Reset(bool power_up, double banner_delay_s);
  void SendLine(const std::string& line);
  void Realtime(char c);
  void ProcessLines();
  std::string ExecuteLine(const std::string& line);  // "" when the reply is deferred
  std::string ExecuteSystem(const std::string& line);
  std::string ExecuteGcode(const std::string& line);
  void StartBlock(Block& b, double now);
  std::array<double, 3> BlockPosition(const Block& b, double now) const;
  double BlockSpeed(const Block& b, double now) const;
  void Plan(const std::array<double, 3>& target, double feed_units_per_min, bool rapid, int move_number);
  void StatusReport();
  void RaiseAlarm(int code);
  void FinishHoming();
  // Seconds a $H takes and the alarm it ends in (0: homed), by the build, $23 and switches.
  std::pair<double, int> HomingPlan() const;
  std::array<double, 3> HomedPosition() const;
  // The soft-limit check of system.c (machine space -$13n .. 0), for a machine target.
  bool OutsideTravel(const std::array<double, 3>& machine) const;
  std::string SetWorkOffset(const std::map<char, double>& words, bool relative_to_position);
  double Setting(int n) const;
  bool Moving() const;

  GrblEmulatorOptions options_;
  std::map<int, double> settings_;
  std::string state_ = "Idle";  // Idle Run Hold Home Alarm
  int hold_substate_ = 0;
  bool booting_ = false;
  double boot_done_real_ = 0;
  bool critical_ = false;
  std::array<double, 3> pos_{};
  std::array<double, 3> g54_{};     // persists over resets (EEPROM)
  std::deque<Block> planner_;
  std::optional<std::array<double, 3>> held_target_;  // what '~' resumes to
  Block hold_decel_;
  bool holding_ = false;
  std::string rx_;                  // bytes not yet parsed into lines
  std::deque<std::string> lines_;   // complete lines waiting to be executed
  bool line_overflow_ = false;
  bool comment_paren_ = false, comment_semi_ = false;
  std::array<double, 3> planned_{};  // where the last queued block ends
  // A line whose reply waits: G4 (planner empty, then dwell) or $H (homing cycle).
  enum class Wait { kNone, kSync, kDwell, kHoming } wait_ = Wait::kNone;
  double wait_until_ = 0, dwell_s_ = 0;
  int homing_result_alarm_ = 0;
  bool status_pending_ = false;
  // Parser modal state.
  bool absolute_ = true;
  int motion_mode_ = 0;
  double feed_ = 0;
  bool feed_set_ = false;
  int report_count_ = 0, lines_out_ = 0;
  int moves_ = 0, homings_ = 0, resets_ = 0, lines_in_ = 0;
  std::vector<double> motion_times_;
};

// Starts a GRBL emulator at `link_path` (empty: only /dev/pts/N); its path() is what a
// motor's `port` names. For dry runs and tests.
Result<std::unique_ptr<GrblEmulator>> StartGrblEmulator(const GrblEmulatorOptions& options,
                                                        const std::string& link_path = "");

}  // namespace rig
