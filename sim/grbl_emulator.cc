// PtyEmulator (pty, thread, unplug/replug) and GrblEmulator (GRBL 1.1h byte for byte).
#include "sim/grbl_emulator.h"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <sys/inotify.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>

#include <fmt/format.h>

#include "config/log.h"

namespace rig {

// ---------------------------------------------------------------------------------------
// PtyEmulator

PtyEmulator::PtyEmulator(double time_scale) : time_scale_(time_scale > 0 ? time_scale : 1.0) {}

PtyEmulator::~PtyEmulator() { Stop(); }

double PtyEmulator::RealNow() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

double PtyEmulator::Now() const { return RealNow() * time_scale_; }

Status PtyEmulator::Start(const std::string& link_path) {
  RIG_CHECK(!thread_.joinable(), "emulator started twice");
  start_ = std::chrono::steady_clock::now();
  link_path_ = link_path;
  if (pipe2(wake_fd_, O_NONBLOCK | O_CLOEXEC) != 0)
    return MakeError(ErrorCode::kIo, "emulator", "pipe: {}", std::strerror(errno));
  inotify_fd_ = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  if (inotify_fd_ < 0) return MakeError(ErrorCode::kIo, "emulator", "inotify: {}", std::strerror(errno));
  {
    std::lock_guard<std::mutex> lock(mu_);
    RIG_TRY(CreatePty());
    OnPowerUp();
  }
  stop_ = false;
  thread_ = std::thread(&PtyEmulator::Run, this);
  return Ok();
}

void PtyEmulator::Stop() {
  if (thread_.joinable()) {
    stop_ = true;
    char c = 1;
    (void)!write(wake_fd_[1], &c, 1);
    thread_.join();
  }
  std::lock_guard<std::mutex> lock(mu_);
  ClosePty();
  replug_at_real_ = 0;
  for (int* fd : {&inotify_fd_, &wake_fd_[0], &wake_fd_[1]}) {
    if (*fd >= 0) close(*fd);
    *fd = -1;
  }
}

Status PtyEmulator::CreatePty() {
  termios t{};
  cfmakeraw(&t);
  cfsetispeed(&t, B115200);
  cfsetospeed(&t, B115200);
  int master = -1, slave = -1;
  char name[256] = {0};
  if (openpty(&master, &slave, name, &t, nullptr) != 0)
    return MakeError(ErrorCode::kIo, "emulator", "openpty: {}", std::strerror(errno));
  fcntl(master, F_SETFL, fcntl(master, F_GETFL) | O_NONBLOCK);
  fcntl(master, F_SETFD, FD_CLOEXEC);
  fcntl(slave, F_SETFD, FD_CLOEXEC);
  master_fd_ = master;
  // Holding the slave open keeps the master readable between two clients (no EIO), and
  // keeps what we write buffered until a client reads, as on a real line.
  slave_fd_ = slave;
  device_path_ = name;
  watch_ = inotify_add_watch(inotify_fd_, name, IN_OPEN);
  if (!link_path_.empty()) {
    std::string tmp = link_path_ + ".new";
    unlink(tmp.c_str());
    if (symlink(name, tmp.c_str()) != 0 || rename(tmp.c_str(), link_path_.c_str()) != 0) {
      int err = errno;
      ClosePty();
      return MakeError(ErrorCode::kIo, link_path_, "cannot link the emulator's pty {}: {}", name,
                       std::strerror(err));
    }
  }
  plugged_ = true;
  ++plug_count_;
  return Ok();
}

void PtyEmulator::ClosePty() {
  if (watch_ >= 0 && inotify_fd_ >= 0) inotify_rm_watch(inotify_fd_, watch_);
  watch_ = -1;
  if (master_fd_ >= 0) close(master_fd_);
  if (slave_fd_ >= 0) close(slave_fd_);
  master_fd_ = slave_fd_ = -1;
  // An unplugged USB device takes its /dev/serial/by-id link with it.
  if (plugged_ && !link_path_.empty()) unlink(link_path_.c_str());
  plugged_ = false;
  out_.clear();
}

std::string PtyEmulator::path() const {
  std::lock_guard<std::mutex> lock(mu_);
  return link_path_.empty() ? device_path_ : link_path_;
}

std::string PtyEmulator::device_path() const {
  std::lock_guard<std::mutex> lock(mu_);
  return device_path_;
}

bool PtyEmulator::plugged() const {
  std::lock_guard<std::mutex> lock(mu_);
  return plugged_;
}

int PtyEmulator::plug_count() const {
  std::lock_guard<std::mutex> lock(mu_);
  return plug_count_;
}

void PtyEmulator::Unplug(double replug_after_s, bool keep_state) {
  std::lock_guard<std::mutex> lock(mu_);
  UnplugLocked(replug_after_s, keep_state);
}

void PtyEmulator::UnplugLocked(double replug_after_s, bool keep_state) {
  ClosePty();
  replug_at_real_ = RealNow() + std::max(replug_after_s, 1e-3);
  keep_state_on_replug_ = keep_state;
  Log("sim")->info("emulator unplugged; back in {:.2f} s", replug_after_s);
}

void PtyEmulator::Send(std::string_view bytes, double real_delay_s) {
  if (!plugged_ || bytes.empty()) return;
  double due = RealNow() + real_delay_s;
  if (!out_.empty()) due = std::max(due, out_.back().first);
  out_.emplace_back(due, std::string(bytes));
}

void PtyEmulator::DropQueuedOutput() { out_.clear(); }

void PtyEmulator::FlushOutput() {
  double now = RealNow();
  while (plugged_ && !out_.empty() && out_.front().first <= now) {
    std::string& b = out_.front().second;
    ssize_t n = write(master_fd_, b.data(), b.size());
    if (n < 0) {
      if (errno == EAGAIN || errno == EINTR) return;
      out_.clear();  // nobody on the line: bytes are lost
      return;
    }
    if (static_cast<size_t>(n) < b.size()) {
      b.erase(0, static_cast<size_t>(n));
      return;
    }
    out_.pop_front();
  }
}

void PtyEmulator::Run() {
  char buf[4096];
  while (!stop_) {
    pollfd fds[3];
    int master;
    {
      std::lock_guard<std::mutex> lock(mu_);
      master = plugged_ ? master_fd_ : -1;
    }
    fds[0] = {wake_fd_[0], POLLIN, 0};
    fds[1] = {master, POLLIN, 0};
    fds[2] = {inotify_fd_, POLLIN, 0};
    poll(fds, 3, 1);
    std::lock_guard<std::mutex> lock(mu_);
    if (fds[0].revents & POLLIN) {
      while (read(wake_fd_[0], buf, sizeof(buf)) > 0) {
      }
    }
    if (stop_) break;
    if (plugged_ && master == master_fd_ && (fds[1].revents & POLLIN)) {
      ssize_t n = read(master_fd_, buf, sizeof(buf));
      if (n > 0) OnInput(std::string_view(buf, static_cast<size_t>(n)));
    }
    if (fds[2].revents & POLLIN) {
      char ev[4096] __attribute__((aligned(alignof(inotify_event))));
      ssize_t n = read(inotify_fd_, ev, sizeof(ev));
      for (ssize_t off = 0; n > 0 && off < n;) {
        auto* e = reinterpret_cast<inotify_event*>(ev + off);
        if (plugged_ && e->wd == watch_ && (e->mask & IN_OPEN)) OnClientOpen();
        off += static_cast<ssize_t>(sizeof(inotify_event) + e->len);
      }
    }
    if (!plugged_ && replug_at_real_ > 0 && RealNow() >= replug_at_real_) {
      Status st = CreatePty();
      if (st.ok()) {
        replug_at_real_ = 0;
        Log("sim")->info("emulator plugged back in at {} ({})", link_path_, device_path_);
        if (!keep_state_on_replug_) OnPowerUp();
      } else {
        replug_at_real_ = RealNow() + 0.05;
      }
    }
    OnTick();
    FlushOutput();
  }
}

// ---------------------------------------------------------------------------------------
// GrblEmulator

namespace {

constexpr char kBanner[] = "\r\nGrbl 1.1h ['$' for help]\r\n";
constexpr char kUnlockMessage[] = "[MSG:'$H'|'$X' to unlock]";
constexpr size_t kLineBufferSize = 80;  // LINE_BUFFER_SIZE in GRBL's protocol.h
constexpr char kOverflowLine[] = "\x01overflow";

bool IsIntegerSetting(int n) {
  switch (n) {
    case 0: case 1: case 2: case 3: case 4: case 5: case 6: case 10: case 13: case 20: case 21:
    case 22: case 23: case 26: case 30: case 31: case 32:
      return true;
  }
  return false;
}

std::map<int, double> DefaultSettings() {
  // GRBL 1.1 defaults, with axes set up for a lamp arm in degrees: 1.8 deg steppers at
  // 1/16 microstepping through a 2:1 belt (17.778 steps/deg), 60 deg/s, 60 deg/s^2.
  std::map<int, double> s = {
      {0, 10}, {1, 25}, {2, 0}, {3, 0}, {4, 0}, {5, 0}, {6, 0}, {10, 1}, {11, 0.010}, {12, 0.002},
      {13, 0}, {20, 0}, {21, 0}, {22, 1}, {23, 0}, {24, 25.0}, {25, 500.0}, {26, 250}, {27, 1.0},
      {30, 1000}, {31, 0}, {32, 0}};
  for (int i = 0; i < 3; ++i) {
    s[100 + i] = 17.778;
    s[110 + i] = 3600.0;
    s[120 + i] = 60.0;
    s[130 + i] = 200.0;
  }
  return s;
}

}  // namespace

GrblEmulator::GrblEmulator(GrblEmulatorOptions options)
    : PtyEmulator(options.time_scale), options_(std::move(options)) {
  settings_ = DefaultSettings();
  settings_[22] = options_.homing_enabled ? 1 : 0;
  // $23 as the guide sets it: home each switched axis towards the end its switch is at.
  settings_[23] = options_.switches_at_negative_end & options_.switch_axes;
  for (auto [k, v] : options_.settings) settings_[k] = v;
  if (options_.g54)
    g54_ = *options_.g54;
  else if (Setting(22) != 0)
    g54_ = HomedPosition();
}

std::array<double, 3> GrblEmulator::WorkOffset() const {
  std::lock_guard<std::mutex> lock(mu_);
  return g54_;
}

// The two-axis build homes X and Y in one cycle; stock GRBL homes Z first (config.h).
std::array<double, 3> GrblEmulator::HomedPosition() const {
  // limits.c, without HOMING_FORCE_SET_ORIGIN: machine space is all negative. An axis homed
  // towards its negative end ($23 bit set) is at max_travel + pulloff (max_travel stored
  // negative: -$13n + $27), one homed towards its positive end at -$27.
  std::array<double, 3> p = pos_;
  const int cycle = options_.stock_homing_cycle ? 0b100 : 0b011;
  const int dir = static_cast<int>(Setting(23));
  for (int i = 0; i < 3; ++i) {
    if (!(cycle & (1 << i))) continue;
    if (options_.homing_force_set_origin) p[i] = 0;
    else p[i] = (dir & (1 << i)) ? -Setting(130 + i) + Setting(27) : -Setting(27);
  }
  return p;
}

std::pair<double, int> GrblEmulator::HomingPlan() const {
  double seek = Setting(25) / 60, feed = Setting(24) / 60, pulloff = Setting(27);
  double debounce = Setting(26) / 1000;
  const int cycle = options_.stock_homing_cycle ? 0b100 : 0b011;
  const int dir = static_cast<int>(Setting(23));
  double search = 0;  // limits_go_home(): 1.5 x the largest max travel of the cycle's axes
  for (int i = 0; i < 3; ++i)
    if (cycle & (1 << i)) search = std::max(search, 1.5 * Setting(130 + i));
  for (int i = 0; i < 3; ++i) {
    if (!(cycle & (1 << i))) continue;
    const bool has_switch = options_.switch_axes & (1 << i);
    const bool towards_negative = dir & (1 << i);
    const bool switch_negative = options_.switches_at_negative_end & (1 << i);
    // No switch on this axis, or searching away from it: nothing trips within the search.
    if (!has_switch || towards_negative != switch_negative) return {search / seek, 9};
  }
  if (options_.homing_fail_alarm == 9) return {search / seek, 9};
  std::array<double, 3> homed = HomedPosition();
  double travel = 0;
  for (int i = 0; i < 3; ++i) travel = std::max(travel, std::fabs(pos_[i] - homed[i]));
  if (options_.homing_fail_alarm == 8) return {(travel + pulloff) / seek + debounce + pulloff / seek, 8};
  return {(travel + pulloff) / seek + 2 * pulloff * 1.5 / feed + 2 * debounce + pulloff / seek,
          options_.homing_fail_alarm};
}

bool GrblEmulator::OutsideTravel(const std::array<double, 3>& machine) const {
  // system_check_travel_limits(): max_travel is stored negative, the space is -$13n .. 0;
  // with HOMING_FORCE_SET_ORIGIN, 0 .. $13n for an axis whose $23 bit is set.
  const int dir = static_cast<int>(Setting(23));
  for (int i = 0; i < 3; ++i) {
    const bool positive = options_.homing_force_set_origin && (dir & (1 << i));
    const double lo = positive ? 0 : -Setting(130 + i), hi = positive ? Setting(130 + i) : 0;
    if (machine[i] > hi || machine[i] < lo) return true;
  }
  return false;
}

// G10 L2 P1 (offset given) and G10 L20 P1 (the current position becomes the given work
// coordinate): the G54 offset, stored in EEPROM like GRBL's coordinate systems.
std::string GrblEmulator::SetWorkOffset(const std::map<char, double>& words, bool relative_to_position) {
  auto p = words.find('P');
  if (p == words.end() || p->second != 1) return "error:29";  // only G54 (P1) is emulated
  const char axes[3] = {'X', 'Y', 'Z'};
  bool any = false;
  for (int a = 0; a < 3; ++a) {
    auto w = words.find(axes[a]);
    if (w == words.end()) continue;
    any = true;
    g54_[a] = relative_to_position ? pos_[a] - w->second : w->second;
  }
  return any ? "ok" : "error:26";
}

GrblEmulator::~GrblEmulator() { Stop(); }

double GrblEmulator::Setting(int n) const {
  auto it = settings_.find(n);
  return it == settings_.end() ? 0 : it->second;
}

bool GrblEmulator::Moving() const { return !planner_.empty() || holding_; }

void GrblEmulator::SetOptions(const GrblEmulatorOptions& options) {
  std::lock_guard<std::mutex> lock(mu_);
  options_ = options;
}

std::array<double, 3> GrblEmulator::Position() const {
  std::lock_guard<std::mutex> lock(mu_);
  return pos_;
}

std::array<double, 3> GrblEmulator::WorkPosition() const {
  std::lock_guard<std::mutex> lock(mu_);
  return {pos_[0] - g54_[0], pos_[1] - g54_[1], pos_[2] - g54_[2]};
}

std::string GrblEmulator::State() const {
  std::lock_guard<std::mutex> lock(mu_);
  return state_ == "Hold" ? fmt::format("Hold:{}", hold_substate_) : state_;
}

int GrblEmulator::moves() const {
  std::lock_guard<std::mutex> lock(mu_);
  return moves_;
}
int GrblEmulator::homings() const {
  std::lock_guard<std::mutex> lock(mu_);
  return homings_;
}
int GrblEmulator::resets() const {
  std::lock_guard<std::mutex> lock(mu_);
  return resets_;
}
int GrblEmulator::lines() const {
  std::lock_guard<std::mutex> lock(mu_);
  return lines_in_;
}
std::vector<double> GrblEmulator::motion_times_s() const {
  std::lock_guard<std::mutex> lock(mu_);
  return motion_times_;
}

void GrblEmulator::OnPowerUp() { Reset(true, options_.banner_delay_s); }

void GrblEmulator::OnClientOpen() {
  // Opening the port raises DTR, which resets an Arduino through its bootloader.
  if (options_.reset_on_open) Reset(true, options_.banner_delay_s);
}

void GrblEmulator::Reset(bool power_up, double banner_delay_s) {
  if (power_up) {
    pos_ = {0, 0, 0};
    state_ = Setting(22) != 0 ? "Alarm" : "Idle";  // HOMING_INIT_LOCK
    DropQueuedOutput();
    booting_ = true;
    boot_done_real_ = RealNow() + banner_delay_s;
  } else {
    // 1.1h's mc_reset(): ALARM:3 only in a motion state (cycle, homing, jog) or while a
    // feed hold is still decelerating (STEP_CONTROL_EXECUTE_HOLD). A completed hold
    // ("Hold:0") clears that flag, so a reset then keeps the position and raises nothing.
    bool in_motion = state_ == "Home" || (holding_ ? hold_substate_ == 1 : !planner_.empty());
    if (in_motion) {
      SendLine(state_ == "Home" ? "ALARM:6" : "ALARM:3");
      state_ = "Alarm";
    } else if (state_ != "Alarm") {
      state_ = "Idle";  // an alarm lock survives a reset (main.c keeps the prior state)
    }
  }
  planner_.clear();
  holding_ = false;
  hold_substate_ = 0;
  planned_ = pos_;
  rx_.clear();
  lines_.clear();
  line_overflow_ = comment_paren_ = comment_semi_ = false;
  wait_ = Wait::kNone;
  critical_ = false;
  status_pending_ = false;
  absolute_ = true;
  motion_mode_ = 0;
  feed_ = 0;
  feed_set_ = false;
  ++resets_;
  if (!options_.no_banner) {
    Send(kBanner, power_up ? banner_delay_s : 0);
    if (state_ == "Alarm") SendLine(kUnlockMessage);
  }
}

void GrblEmulator::SendLine(const std::string& line) {
  ++lines_out_;
  if (options_.garbage_every > 0 && lines_out_ % options_.garbage_every == 0) {
    // Line noise, then the real line in two pieces a moment apart.
    Send(fmt::format("\xfe\x13#{}@\x80\x07~noise\r\n", lines_out_));
    size_t half = line.size() / 2;
    Send(line.substr(0, half));
    Send(line.substr(half) + "\r\n", 0.002);
    return;
  }
  Send(line + "\r\n");
}

void GrblEmulator::StatusReport() {
  std::string state = state_ == "Hold" ? fmt::format("Hold:{}", hold_substate_) : state_;
  double feed = 0;
  if (!planner_.empty() && planner_.front().started && !holding_)
    feed = BlockSpeed(planner_.front(), Now()) * 60;
  std::string s = fmt::format("<{}|MPos:{:.3f},{:.3f},{:.3f}|FS:{:.0f},0", state, pos_[0], pos_[1], pos_[2], feed);
  if (report_count_++ % 10 == 0) s += fmt::format("|WCO:{:.3f},{:.3f},{:.3f}", g54_[0], g54_[1], g54_[2]);
  s += ">";
  SendLine(s);
}

void GrblEmulator::RaiseAlarm(int code) {
  planner_.clear();
  holding_ = false;
  planned_ = pos_;
  state_ = "Alarm";
  SendLine(fmt::format("ALARM:{}", code));
  if (code == 1 || code == 2) {
    // Critical: everything but status reports and reset is ignored until a reset.
    SendLine("[MSG:Reset to continue]");
    critical_ = true;
    return;
  }
  // Other alarms abort through mc_reset(): the controller re-initialises.
  wait_ = Wait::kNone;
  lines_.clear();
  rx_.clear();
  if (!options_.no_banner) {
    Send(kBanner);
    SendLine(kUnlockMessage);
  }
}

void GrblEmulator::Realtime(char c) {
  double now = Now();
  switch (c) {
    case '!':
      if (state_ == "Alarm" || state_ == "Home" || holding_) return;
      holding_ = true;
      hold_substate_ = 0;
      if (!planner_.empty() && planner_.front().started) {
        Block& b = planner_.front();
        if (b.stall) return;  // a stalled axis has nothing left to decelerate
        double v = BlockSpeed(b, now);
        std::array<double, 3> here = BlockPosition(b, now);
        double stop_dist = v * v / (2 * b.a);
        // The decelerating segment, then the rest of the block re-planned on resume.
        hold_decel_ = Block{};
        hold_decel_.from = here;
        for (int i = 0; i < 3; ++i)
          hold_decel_.to[i] = here[i] + (b.to[i] - b.from[i]) / b.length * stop_dist;
        hold_decel_.v = v;
        hold_decel_.a = b.a;
        hold_decel_.length = stop_dist;
        hold_decel_.duration = v / b.a;
        hold_decel_.t_start = now;
        hold_substate_ = v > 1e-9 ? 1 : 0;
        b.started = false;
        pos_ = here;
      }
      return;
    case '~':
      if (!holding_ || hold_substate_ != 0) return;
      holding_ = false;
      if (!planner_.empty()) planner_.front().started = false;  // re-planned from here
      return;
    case '\x18':
      Reset(false, 0);
      return;
  }
}

void GrblEmulator::OnInput(std::string_view bytes) {
  if (booting_) return;  // the bootloader swallows what arrives before the firmware runs
  for (char ch : bytes) {
    unsigned char c = static_cast<unsigned char>(ch);
    if (c == '?') {
      // protocol.c: a soft- or hard-limit alarm spins in a loop that serves nothing, status
      // reports included, until a reset (the comment there says otherwise; the loop is empty).
      if (critical_) continue;
      if (state_ == "Home")
        status_pending_ = true;  // no reports during a homing cycle
      else
        StatusReport();
      continue;
    }
    if (c == '!' || c == '~' || c == 0x18) {
      Realtime(static_cast<char>(c));
      continue;
    }
    if (c >= 0x80) continue;  // extended real-time commands (overrides): not emulated
    if (critical_) continue;
    if (c == '\n' || c == '\r') {
      lines_.push_back(line_overflow_ ? std::string(kOverflowLine) : rx_);
      rx_.clear();
      line_overflow_ = comment_paren_ = comment_semi_ = false;
      continue;
    }
    if (comment_paren_ || comment_semi_ || line_overflow_) {
      if (c == ')') comment_paren_ = false;
      continue;
    }
    if (c <= ' ' || c == '/') continue;
    if (c == '(') {
      comment_paren_ = true;
    } else if (c == ';') {
      comment_semi_ = true;
    } else if (rx_.size() >= kLineBufferSize - 1) {
      line_overflow_ = true;
    } else {
      rx_ += static_cast<char>(std::toupper(c));
    }
  }
  ProcessLines();
}

void GrblEmulator::ProcessLines() {
  while (wait_ == Wait::kNone && !critical_ && !lines_.empty() && PluggedLocked()) {
    std::string line = lines_.front();
    lines_.pop_front();
    ++lines_in_;
    std::string reply = ExecuteLine(line);
    if (!reply.empty()) SendLine(reply);
  }
}

std::string GrblEmulator::ExecuteLine(const std::string& line) {
  if (line == kOverflowLine) return "error:11";
  if (line.empty()) return "ok";
  if (line[0] == '$') return ExecuteSystem(line);
  if (state_ == "Alarm") return "error:9";
  return ExecuteGcode(line);
}

std::string GrblEmulator::ExecuteSystem(const std::string& line) {
  const bool idle_or_alarm = (state_ == "Idle" || state_ == "Alarm") && !Moving();
  if (line == "$") {
    SendLine("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]");
    return "ok";
  }
  if (line == "$$") {
    if (state_ == "Run" || state_ == "Hold") return "error:8";
    for (auto [n, v] : settings_)
      SendLine(IsIntegerSetting(n) ? fmt::format("${}={}", n, static_cast<int>(v)) : fmt::format("${}={:.3f}", n, v));
    return "ok";
  }
  if (line == "$G") {
    SendLine(fmt::format("[GC:G{} G54 G17 G21 G{} G94 M5 M9 T0 F{:g} S0]", motion_mode_, absolute_ ? 90 : 91,
                         feed_));
    return "ok";
  }
  if (line == "$I") {
    SendLine("[VER:1.1h.20190830:]");
    SendLine(options_.homing_force_set_origin ? "[OPT:VZ,15,128]" : "[OPT:V,15,128]");
    return "ok";
  }
  if (line == "$N") {
    SendLine("$N0=");
    SendLine("$N1=");
    return "ok";
  }
  if (line == "$#") {
    for (const char* p : {"G54", "G55", "G56", "G57", "G58", "G59", "G28", "G30", "G92"})
      SendLine(std::string(p) == "G54" ? fmt::format("[G54:{:.3f},{:.3f},{:.3f}]", g54_[0], g54_[1], g54_[2])
                                     : fmt::format("[{}:0.000,0.000,0.000]", p));
    SendLine("[TLO:0.000]");
    SendLine("[PRB:0.000,0.000,0.000:0]");
    return "ok";
  }
  if (line == "$X") {
    if (state_ == "Alarm") {
      SendLine("[MSG:Caution: Unlocked]");
      state_ = "Idle";
    }
    return "ok";
  }
  if (line == "$H") {
    if (!idle_or_alarm) return "error:8";
    if (Setting(22) == 0) return "error:5";
    state_ = "Home";
    wait_ = Wait::kHoming;
    auto [duration, alarm] = HomingPlan();
    homing_result_alarm_ = alarm;
    wait_until_ = Now() + duration;
    return "";
  }
  // $n=value
  size_t eq = line.find('=');
  if (eq == std::string::npos || eq < 2) return "error:3";
  char* end = nullptr;
  std::string num = line.substr(1, eq - 1), val = line.substr(eq + 1);
  long n = std::strtol(num.c_str(), &end, 10);
  if (end == num.c_str() || *end != '\0') return "error:3";  // $J=, $RST=, $N0=... not emulated
  double v = std::strtod(val.c_str(), &end);
  if (end == val.c_str() || *end != '\0') return "error:2";
  if (!idle_or_alarm) return "error:8";
  if (v < 0) return "error:4";
  if (!settings_.count(static_cast<int>(n))) return "error:3";
  settings_[static_cast<int>(n)] = v;
  return "ok";
}

std::string GrblEmulator::ExecuteGcode(const std::string& line) {
  std::map<char, double> words;
  std::vector<int> gcodes;
  size_t i = 0;
  while (i < line.size()) {
    char letter = line[i++];
    if (letter < 'A' || letter > 'Z') return "error:1";
    // gcode.c's read_float(): an optional sign, digits and one decimal point; no exponent and
    // no hexadecimal (strtod would read "G0X5" as G5, 0X5 being hex).
    size_t j = i;
    if (j < line.size() && (line[j] == '-' || line[j] == '+')) ++j;
    bool digits = false, point = false;
    for (; j < line.size(); ++j) {
      if (std::isdigit(static_cast<unsigned char>(line[j]))) digits = true;
      else if (line[j] == '.' && !point) point = true;
      else break;
    }
    if (!digits) return "error:2";
    const double value = std::strtod(line.substr(i, j - i).c_str(), nullptr);
    if (!std::isfinite(value)) return "error:2";
    i = j;
    if (letter == 'G') {
      if (value != std::floor(value)) return "error:20";  // G38.2, G59.1, ...: not emulated
      gcodes.push_back(static_cast<int>(value));
      continue;
    }
    if (letter == 'M') {
      int m = static_cast<int>(value);
      if (value != m || !(m == 0 || m == 1 || m == 2 || m == 30 || m == 3 || m == 4 || m == 5 || m == 7 ||
                          m == 8 || m == 9))
        return "error:20";
      continue;
    }
    if (std::string("FXYZPNSTL").find(letter) == std::string::npos) return "error:20";
    if (words.count(letter)) return "error:25";
    words[letter] = value;
  }
  int motion = -1;
  bool dwell = false, machine_coords = false, set_offset = false;
  for (int g : gcodes) {
    switch (g) {
      case 0: case 1:
        if (motion >= 0) return "error:21";
        motion = g;
        break;
      case 4: dwell = true; break;
      case 10: set_offset = true; break;
      case 53: machine_coords = true; break;  // this block in machine coordinates
      case 90: absolute_ = true; break;
      case 91: absolute_ = false; break;
      case 17: case 20: case 21: case 54: case 94: break;
      default: return "error:20";
    }
  }
  if (set_offset) {
    auto l = words.find('L');
    if (l == words.end() || (l->second != 2 && l->second != 20)) return "error:20";
    return SetWorkOffset(words, l->second == 20);
  }
  if (words.count('L')) return "error:20";
  if (words.count('F')) {
    if (words['F'] < 0) return "error:4";
    feed_ = words['F'];
    feed_set_ = true;
  }
  bool has_axis = words.count('X') || words.count('Y') || words.count('Z');
  if (dwell) {
    if (!words.count('P')) return "error:28";
    if (words['P'] < 0) return "error:4";
    if (has_axis) return "error:31";
    dwell_s_ = words['P'];
    wait_ = Wait::kSync;  // the ok comes once the planner is empty and the dwell is over
    return "";
  }
  if (words.count('P')) return "error:36";
  if (motion >= 0) motion_mode_ = motion;
  if (!has_axis) return "ok";
  if (motion_mode_ == 1 && (!feed_set_ || feed_ <= 0)) return "error:22";
  int n = ++moves_;
  if (options_.error_at_move == n) return fmt::format("error:{}", options_.error_code);
  if (options_.disconnect_at_move == n) {
    UnplugLocked(options_.replug_after_s, !options_.reset_on_replug);
    return "";
  }
  std::array<double, 3> target = planned_;
  const char axes[3] = {'X', 'Y', 'Z'};
  for (int a = 0; a < 3; ++a) {
    if (!words.count(axes[a])) continue;
    const double offset = machine_coords ? 0 : g54_[a];
    target[a] = absolute_ || machine_coords ? words[axes[a]] + offset : planned_[a] + words[axes[a]];
  }
  if (Setting(20) != 0 && OutsideTravel(target)) {
    // limits_soft_check(): a controlled stop if moving, then ALARM:2 and the critical loop.
    // The line is never acknowledged.
    RaiseAlarm(2);
    return "";
  }
  Plan(target, feed_, motion_mode_ == 0, n);
  return "ok";
}

void GrblEmulator::Plan(const std::array<double, 3>& target, double feed_units_per_min, bool rapid,
                        int move_number) {
  Block b;
  b.from = planned_;
  b.to = target;
  double len2 = 0;
  for (int i = 0; i < 3; ++i) len2 += (b.to[i] - b.from[i]) * (b.to[i] - b.from[i]);
  b.length = std::sqrt(len2);
  planned_ = target;
  if (b.length < 1e-9) return;  // GRBL drops zero-length blocks
  double v = rapid ? std::numeric_limits<double>::infinity() : feed_units_per_min / 60;
  double a = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    double u = std::fabs(b.to[i] - b.from[i]) / b.length;
    if (u < 1e-12) continue;
    v = std::min(v, Setting(110 + i) / 60 / u);
    a = std::min(a, Setting(120 + i) / u);
  }
  b.v = v;
  b.a = a;
  b.stall = options_.stall_at_move == move_number;
  b.alarm = options_.alarm_at_move == move_number;
  b.unplug = options_.disconnect_mid_move == move_number;
  b.move_number = move_number;
  planner_.push_back(b);
}

void GrblEmulator::StartBlock(Block& b, double now) {
  // A block starts (or restarts after a hold) from rest at the current position.
  b.from = pos_;
  double len2 = 0;
  for (int i = 0; i < 3; ++i) len2 += (b.to[i] - b.from[i]) * (b.to[i] - b.from[i]);
  b.length = std::sqrt(len2);
  if (b.length >= b.v * b.v / b.a) {
    b.v_peak = b.v;
    b.t_accel = b.v / b.a;
    b.duration = b.length / b.v + b.v / b.a;
  } else {
    b.v_peak = std::sqrt(b.length * b.a);
    b.t_accel = b.v_peak / b.a;
    b.duration = 2 * b.t_accel;
  }
  b.t_start = now;
  b.started = true;
}

double GrblEmulator::BlockSpeed(const Block& b, double now) const {
  double t = std::clamp(now - b.t_start, 0.0, b.duration);
  if (b.stall && t >= b.duration / 2) return 0;
  if (t < b.t_accel) return b.a * t;
  if (t < b.duration - b.t_accel) return b.v_peak;
  return b.a * (b.duration - t);
}

std::array<double, 3> GrblEmulator::BlockPosition(const Block& b, double now) const {
  double t = std::clamp(now - b.t_start, 0.0, b.duration);
  if (b.stall) t = std::min(t, b.duration / 2);
  double s;
  if (t < b.t_accel) {
    s = 0.5 * b.a * t * t;
  } else if (t < b.duration - b.t_accel) {
    s = 0.5 * b.a * b.t_accel * b.t_accel + b.v_peak * (t - b.t_accel);
  } else {
    double r = b.duration - t;
    s = b.length - 0.5 * b.a * r * r;
  }
  std::array<double, 3> p{};
  for (int i = 0; i < 3; ++i)
    p[i] = b.length > 0 ? b.from[i] + (b.to[i] - b.from[i]) * (s / b.length) : b.to[i];
  return p;
}

void GrblEmulator::OnTick() {
  if (booting_ && RealNow() >= boot_done_real_) booting_ = false;
  const double now = Now();
  if (wait_ == Wait::kHoming && now >= wait_until_) {
    wait_ = Wait::kNone;
    if (homing_result_alarm_ != 0) {
      // limits_go_home(): ALARM:N, then the ok of $H, then the reset (banner, lock message).
      state_ = "Alarm";
      SendLine(fmt::format("ALARM:{}", homing_result_alarm_));
      SendLine("ok");
      lines_.clear();
      rx_.clear();
      if (!options_.no_banner) {
        Send(kBanner);
        SendLine(kUnlockMessage);
      }
    } else {
      pos_ = HomedPosition();
      planned_ = pos_;
      state_ = "Idle";
      ++homings_;
      SendLine("ok");
    }
    if (status_pending_) {
      status_pending_ = false;
      StatusReport();
    }
  }
  if (holding_ && hold_substate_ == 1) {
    double t = std::min(now - hold_decel_.t_start, hold_decel_.duration);
    double s = hold_decel_.v * t - 0.5 * hold_decel_.a * t * t;
    for (int i = 0; i < 3; ++i)
      pos_[i] = hold_decel_.from[i] +
                (hold_decel_.length > 0 ? (hold_decel_.to[i] - hold_decel_.from[i]) * s / hold_decel_.length : 0);
    if (t >= hold_decel_.duration) hold_substate_ = 0;
  }
  if (!holding_ && state_ != "Alarm" && state_ != "Home") {
    while (!planner_.empty()) {
      Block& b = planner_.front();
      if (!b.started) StartBlock(b, now);
      if (b.unplug && now - b.t_start >= b.duration / 2) {
        b.unplug = false;  // the link goes; the controller, powered on its own, moves on
        UnplugLocked(options_.replug_after_s, !options_.reset_on_replug);
      }
      if (b.alarm && now - b.t_start >= b.duration / 2) {
        pos_ = BlockPosition(b, b.t_start + b.duration / 2);
        RaiseAlarm(options_.alarm_code);
        break;
      }
      if (!b.stall && now >= b.t_start + b.duration) {
        pos_ = b.to;
        motion_times_.push_back(b.duration);
        planner_.pop_front();
        continue;
      }
      pos_ = BlockPosition(b, now);
      break;
    }
  }
  if (state_ != "Alarm" && state_ != "Home") state_ = holding_ ? "Hold" : planner_.empty() ? "Idle" : "Run";
  if (wait_ == Wait::kSync && planner_.empty() && !holding_ && state_ != "Alarm") {
    wait_ = Wait::kDwell;
    wait_until_ = now + dwell_s_;
  }
  if (wait_ == Wait::kDwell && now >= wait_until_) {
    wait_ = Wait::kNone;
    SendLine("ok");
  }
  ProcessLines();
}

Result<std::unique_ptr<GrblEmulator>> StartGrblEmulator(const GrblEmulatorOptions& options,
                                                        const std::string& link_path) {
  auto e = std::make_unique<GrblEmulator>(options);
  RIG_TRY(e->Start(link_path));
  return e;
}

}  // namespace rig
