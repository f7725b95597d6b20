// GrblMotor: GRBL 1.1's line protocol (one ok/error:N per line, character counting),
// real-time commands (? ! ~ ctrl-x), homing, and recovery from the controller's bad days.
#include "capture/devices/grbl_motor.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <thread>

#include "config/log.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

// GRBL's serial receive buffer is 128 bytes; streaming keeps the sum of unacknowledged
// lines below it (the "character counting" protocol of doc/markdown/interface.md).
constexpr size_t kGrblRxBuffer = 127;
// Status reports carry three decimals; a position within this many units is "there".
constexpr double kPositionToleranceUnits = 0.0105;

Seconds Left(Clock::time_point deadline) {
  return std::chrono::duration<double>(deadline - Clock::now());
}

Clock::time_point After(Seconds s) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(s);
}

bool ParseInt(std::string_view s, int* out) {
  if (s.empty() || s.size() > 4) return false;
  int v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  *out = v;
  return true;
}

bool ParseTriple(std::string_view s, std::array<double, 3>* out) {
  std::string text(s);
  const char* p = text.c_str();
  for (int i = 0; i < 3; ++i) {
    char* end = nullptr;
    double v = std::strtod(p, &end);
    if (end == p) return false;
    (*out)[i] = v;
    p = end;
    if (i < 2) {
      if (*p != ',') return false;
      ++p;
    }
  }
  // More axes (A, B, C) may follow; they are not ours.
  return *p == '\0' || *p == ',';
}

int AxisIndex(const std::string& axis) { return axis == "Y" ? 1 : axis == "Z" ? 2 : 0; }

}  // namespace

const char* GrblErrorMeaning(int code) {
  switch (code) {
    case 1: return "G-code words consist of a letter and a value. Letter was not found.";
    case 2: return "Missing the expected G-code word value or numeric value format is not valid.";
    case 3: return "Grbl '$' system command was not recognized or supported.";
    case 4: return "Negative value received for an expected positive value.";
    case 5: return "Homing cycle failure. Homing is not enabled via settings.";
    case 6: return "Minimum step pulse time must be greater than 3usec.";
    case 7: return "An EEPROM read failed. Auto-restoring affected EEPROM to default values.";
    case 8: return "Grbl '$' command cannot be used unless Grbl is IDLE. Ensures smooth operation during a job.";
    case 9: return "G-code commands are locked out during alarm or jog state.";
    case 10: return "Soft limits cannot be enabled without homing also enabled.";
    case 11: return "Max characters per line exceeded. Received command line was not executed.";
    case 12: return "Grbl '$' setting value cause the step rate to exceed the maximum supported.";
    case 13: return "Safety door detected as opened and door state initiated.";
    case 14: return "Build info or startup line exceeded EEPROM line length limit. Line not stored.";
    case 15: return "Jog target exceeds machine travel. Jog command has been ignored.";
    case 16: return "Jog command has no '=' or contains prohibited g-code.";
    case 17: return "Laser mode requires PWM output.";
    case 20: return "Unsupported or invalid g-code command found in block.";
    case 21: return "More than one g-code command from same modal group found in block.";
    case 22: return "Feed rate has not yet been set or is undefined.";
    case 23: return "G-code command in block requires an integer value.";
    case 24: return "More than one g-code command that requires axis words found in block.";
    case 25: return "Repeated g-code word found in block.";
    case 26: return "No axis words found in block for g-code command or current modal state which requires them.";
    case 27: return "Line number value is invalid.";
    case 28: return "G-code command is missing a required value word.";
    case 29: return "G59.x work coordinate systems are not supported.";
    case 30: return "G53 only allowed with G0 and G1 motion modes.";
    case 31: return "Axis words found in block when no command or current modal state uses them.";
    case 32: return "G2 and G3 arcs require at least one in-plane axis word.";
    case 33: return "Motion command target is invalid.";
    case 34: return "Arc radius value is invalid.";
    case 35: return "G2 and G3 arcs require at least one in-plane offset word.";
    case 36: return "Unused value words found in block.";
    case 37: return "G43.1 dynamic tool length offset is not assigned to configured tool length axis.";
    case 38: return "Tool number greater than max supported value.";
  }
  return "unknown error code (not in the GRBL 1.1 table)";
}

const char* GrblAlarmMeaning(int code) {
  switch (code) {
    case 1: return "Hard limit triggered. Machine position is likely lost due to sudden and immediate halt. Re-homing is highly recommended.";
    case 2: return "G-code motion target exceeds machine travel. Machine position safely retained. Alarm may be unlocked.";
    case 3: return "Reset while in motion. Grbl cannot guarantee position. Lost steps are likely. Re-homing is highly recommended.";
    case 4: return "Probe fail. The probe is not in the expected initial state before starting probe cycle.";
    case 5: return "Probe fail. Probe did not contact the workpiece within the programmed travel for G38.2 and G38.4.";
    case 6: return "Homing fail. Reset during active homing cycle.";
    case 7: return "Homing fail. Safety door was opened during active homing cycle.";
    case 8: return "Homing fail. Cycle failed to clear limit switch when pulling off. Try increasing pull-off setting or check wiring.";
    case 9: return "Homing fail. Could not find limit switch within search distance. Defined as 1.5 * max_travel on search and 5 * pulloff on locate phases.";
  }
  return "unknown alarm code (not in the GRBL 1.1 table)";
}

std::optional<GrblStatus> ParseGrblStatus(std::string_view line) {
  if (line.size() < 3 || line.front() != '<' || line.back() != '>') return std::nullopt;
  std::string_view body = line.substr(1, line.size() - 2);
  GrblStatus s;
  bool first = true;
  bool have_wpos = false;
  while (!body.empty()) {
    size_t bar = body.find('|');
    std::string_view field = body.substr(0, bar);
    body = bar == std::string_view::npos ? std::string_view() : body.substr(bar + 1);
    if (first) {
      first = false;
      size_t colon = field.find(':');
      s.state = std::string(field.substr(0, colon));
      if (colon != std::string_view::npos && !ParseInt(field.substr(colon + 1), &s.substate))
        return std::nullopt;
      static const char* kStates[] = {"Idle", "Run", "Hold", "Jog", "Alarm", "Door", "Check", "Home", "Sleep"};
      bool known = false;
      for (const char* k : kStates) known = known || s.state == k;
      if (!known) return std::nullopt;
      continue;
    }
    size_t colon = field.find(':');
    if (colon == std::string_view::npos) return std::nullopt;
    std::string_view key = field.substr(0, colon), value = field.substr(colon + 1);
    if (key == "MPos") {
      if (!ParseTriple(value, &s.mpos)) return std::nullopt;
      s.has_position = true;
    } else if (key == "WPos") {
      if (!ParseTriple(value, &s.wpos)) return std::nullopt;
      s.has_position = true;
      have_wpos = true;
    } else if (key == "WCO") {
      std::array<double, 3> w{};
      if (!ParseTriple(value, &w)) return std::nullopt;
      s.wco = w;
    } else if (key == "FS" || key == "F") {
      s.feed = std::strtod(std::string(value).c_str(), nullptr);
    }
  }
  if (first || !s.has_position) return std::nullopt;
  s.position_is_work = have_wpos;
  if (have_wpos && s.wco) {
    for (int i = 0; i < 3; ++i) s.mpos[i] = s.wpos[i] + (*s.wco)[i];
  } else if (!have_wpos && s.wco) {
    for (int i = 0; i < 3; ++i) s.wpos[i] = s.mpos[i] - (*s.wco)[i];
  }
  return s;
}

GrblMotor::GrblMotor(MotorConfig config)
    : config_(std::move(config)), selector_(SerialSelector::FromConfig(config_)) {
  h_index_ = AxisIndex(config_.grbl.h_axis);
  v_index_ = AxisIndex(config_.grbl.v_axis);
}

GrblMotor::~GrblMotor() { Close(); }

std::string GrblMotor::Describe() const { return "grbl on " + selector_.Describe(); }

Error GrblMotor::Fail(ErrorCode code, const std::string& message) const {
  return Error{code, message, selector_.Describe()};
}

Error GrblMotor::AlarmLocked() const {
  return Fail(ErrorCode::kFault,
              "the controller is alarm-locked ([MSG:'$H'|'$X' to unlock]) and refuses motion: it does "
              "not know where the arm is. Home it with $H ('rig home', or motor.home_on_start = true), "
              "or, only if the arm is known to stand where the controller last had it, unlock it with "
              "$X ('rig home --unlock')");
}

Error GrblMotor::AlarmError(int code, const std::string& during) const {
  return Fail(ErrorCode::kDevice, fmt::format("ALARM:{} {}: {}", code, during, GrblAlarmMeaning(code)));
}

bool GrblMotor::PortLost(const Error& e) const {
  return e.code == ErrorCode::kIo && (port_ == nullptr || port_->lost());
}

std::array<double, 3> GrblMotor::WorkPosition(const GrblStatus& s) const {
  if (s.position_is_work) return s.wpos;
  std::array<double, 3> w{};
  const auto& wco = s.wco ? *s.wco : wco_;
  for (int i = 0; i < 3; ++i) w[i] = s.mpos[i] - wco[i];
  return w;
}

GrblMotor::Line GrblMotor::Classify(const std::string& text) {
  Line l;
  l.text = text;
  int code = 0;
  if (text == "ok") {
    l.kind = Kind::kOk;
  } else if (text.rfind("error:", 0) == 0 && ParseInt(std::string_view(text).substr(6), &code)) {
    l.kind = Kind::kError;
    l.code = code;
  } else if (text.rfind("ALARM:", 0) == 0 && ParseInt(std::string_view(text).substr(6), &code)) {
    l.kind = Kind::kAlarm;
    l.code = code;
    state_ = "Alarm";
  } else if (text.front() == '<') {
    auto s = ParseGrblStatus(text);
    if (s) {
      l.kind = Kind::kStatus;
      state_ = s->state;
      if (s->wco) wco_ = *s->wco;
    }
  } else if (text.rfind("Grbl ", 0) == 0 && text.find("['$' for help]") != std::string::npos) {
    l.kind = Kind::kBanner;
    if (text.rfind("Grbl 1.1", 0) != 0)
      Log("motion")->warn("grbl port={} version='{}' is not 1.1: the protocol may differ",
                          selector_.Describe(), text);
    if (state_ != "Alarm") state_ = "Idle";
  } else if (text.front() == '[' && text.back() == ']') {
    l.kind = Kind::kMessage;
    if (text.find("'$H'|'$X' to unlock") != std::string::npos) state_ = "Alarm";
    if (text.find("Caution: Unlocked") != std::string::npos) state_ = "Idle";
    std::array<double, 3> offset{};
    if (text.rfind("[G54:", 0) == 0 && ParseTriple(std::string_view(text).substr(5, text.size() - 6), &offset))
      g54_ = offset;
    if (text.rfind("[G92:", 0) == 0 && ParseTriple(std::string_view(text).substr(5, text.size() - 6), &offset))
      g92_ = offset;
    // $I's build options (report.c): the letters before the first comma; 'Z' is
    // HOMING_FORCE_SET_ORIGIN.
    if (text.rfind("[OPT:", 0) == 0) {
      const std::string letters = text.substr(5, text.find(',') == std::string::npos ? std::string::npos
                                                                                       : text.find(',') - 5);
      force_set_origin_ = letters.find('Z') != std::string::npos;
    }
    Log("motion")->debug("grbl port={} message='{}'", selector_.Describe(), text);
  } else if (text.front() == '$' && text.find('=') != std::string::npos) {
    int n = 0;
    size_t eq = text.find('=');
    char* end = nullptr;
    std::string value = text.substr(eq + 1);
    double v = std::strtod(value.c_str(), &end);
    if (ParseInt(std::string_view(text).substr(1, eq - 1), &n) && end != value.c_str() && *end == '\0') {
      l.kind = Kind::kSetting;
      settings_[n] = v;
    }
  } else if (text.front() == '>') {
    l.kind = Kind::kStartup;  // ">G54:ok": a startup block ran
  }
  if (l.kind == Kind::kGarbage) {
    ++ignored_lines_;
    Log("motion")->warn("grbl port={} ignoring unexpected line '{}'", selector_.Describe(),
                        EscapeForLog(text));
  }
  return l;
}

Result<GrblMotor::Line> GrblMotor::NextLine(Seconds timeout, bool interruptible) {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  RIG_ASSIGN_OR_RETURN(auto text, port_->ReadLine(timeout, interruptible));
  if (!text) return Fail(ErrorCode::kTimeout, fmt::format("no reply within {:.2f} s", timeout.count()));
  Log("motion")->trace("grbl port={} << '{}'", selector_.Describe(), EscapeForLog(*text));
  return Classify(*text);
}

Status GrblMotor::SendRealtime(char c) {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  return port_->Write(std::string_view(&c, 1), Seconds(config_.reply_timeout_s));
}

Status GrblMotor::Queue(const std::string& line) {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  size_t bytes = line.size() + 1;
  auto used = [&] {
    size_t n = 0;
    for (const auto& o : outstanding_) n += o.second;
    return n;
  };
  while (!outstanding_.empty() && used() + bytes > kGrblRxBuffer) {
    RIG_ASSIGN_OR_RETURN(Line r, AwaitResponse(Seconds(config_.reply_timeout_s), OnAlarm::kRecord));
    (void)r;
  }
  Log("motion")->trace("grbl port={} >> '{}'", selector_.Describe(), line);
  RIG_TRY(port_->Write(line + "\n", Seconds(config_.reply_timeout_s)));
  outstanding_.emplace_back(line, bytes);
  return Ok();
}

Result<GrblMotor::Line> GrblMotor::AwaitResponse(Seconds timeout, OnAlarm on_alarm, bool interruptible) {
  RIG_CHECK(!outstanding_.empty(), "no line awaits a reply");
  auto deadline = After(timeout);
  for (;;) {
    std::string waiting_for = outstanding_.front().first;
    Seconds left = Left(deadline);
    if (left.count() <= 0)
      return Fail(ErrorCode::kTimeout,
                  fmt::format("no reply to '{}' within {:.2f} s", waiting_for, timeout.count()));
    auto next = NextLine(left, interruptible);
    if (!next.ok()) {
      if (next.error().code == ErrorCode::kTimeout)
        return Fail(ErrorCode::kTimeout,
                    fmt::format("no reply to '{}' within {:.2f} s", waiting_for, timeout.count()));
      return next.error();
    }
    Line l = std::move(next).value();
    switch (l.kind) {
      case Kind::kOk:
      case Kind::kError:
        outstanding_.pop_front();
        return l;
      case Kind::kAlarm:
        pending_alarm_ = l.code;
        if (on_alarm == OnAlarm::kFail)
          return AlarmError(l.code, fmt::format("while waiting for the reply to '{}'", waiting_for));
        break;
      case Kind::kBanner:
        outstanding_.clear();
        reset_seen_ = true;
        return Fail(ErrorCode::kDevice,
                    fmt::format("the controller reset (banner received) while waiting for the reply to '{}'",
                                waiting_for));
      default:
        break;
    }
  }
}

Result<GrblStatus> GrblMotor::QueryStatus(bool interruptible) {
  RIG_TRY(SendRealtime('?'));
  Seconds timeout(config_.reply_timeout_s);
  auto deadline = After(timeout);
  for (;;) {
    Seconds left = Left(deadline);
    if (left.count() <= 0) break;
    auto next = NextLine(left, interruptible);
    if (!next.ok()) {
      if (next.error().code == ErrorCode::kTimeout) break;
      return next.error();
    }
    Line& l = next.value();
    if (l.kind == Kind::kStatus) return *ParseGrblStatus(l.text);
    if (l.kind == Kind::kAlarm) pending_alarm_ = l.code;
    if ((l.kind == Kind::kOk || l.kind == Kind::kError) && !outstanding_.empty()) outstanding_.pop_front();
  }
  return Fail(ErrorCode::kTimeout,
              fmt::format("no status report in reply to '?' within {:.2f} s", timeout.count()));
}

Status GrblMotor::AwaitBanner(Seconds timeout) {
  auto deadline = After(timeout);
  for (;;) {
    Seconds left = Left(deadline);
    if (left.count() <= 0) return Fail(ErrorCode::kTimeout, "no banner");
    auto next = NextLine(left);
    if (!next.ok()) return next.error();
    if (next->kind == Kind::kBanner) {
      outstanding_.clear();
      pending_alarm_ = 0;
      return Ok();
    }
  }
}

Status GrblMotor::WaitForBannerOrReset() {
  Seconds timeout(config_.grbl.banner_timeout_s);
  Status st = AwaitBanner(timeout);
  if (st.ok() || st.error().code != ErrorCode::kTimeout) return st;
  // Boards without the DTR auto-reset (or a controller that was already running) stay
  // silent on open: a soft reset makes GRBL print its banner again.
  Log("motion")->warn("grbl port={} no banner within {:.1f} s after opening; sending a soft reset (ctrl-x)",
                      selector_.Describe(), timeout.count());
  RIG_TRY(SendRealtime('\x18'));
  st = AwaitBanner(timeout);
  if (st.ok() || st.error().code != ErrorCode::kTimeout) return st;
  return Fail(ErrorCode::kTimeout,
              fmt::format("no GRBL banner within {:.1f} s after opening nor after a soft reset (ctrl-x): "
                          "is a GRBL 1.1 controller on this port at {} baud?",
                          timeout.count(), config_.baud));
}

Status GrblMotor::ReadSettings() {
  RIG_TRY(Queue("$$"));
  RIG_ASSIGN_OR_RETURN(Line r, AwaitResponse(Seconds(config_.reply_timeout_s), OnAlarm::kRecord));
  auto log = Log("motion");
  if (r.kind == Kind::kError) {
    log->warn("grbl port={} cannot read settings ($$): error:{} ({})", selector_.Describe(), r.code,
              GrblErrorMeaning(r.code));
    return Ok();
  }
  auto get = [&](int n) { auto it = settings_.find(n); return it == settings_.end() ? NAN : it->second; };
  const double upd = config_.grbl.units_per_degree;
  for (auto [name, index] : {std::pair{"h", h_index_}, std::pair{"v", v_index_}}) {
    double steps = get(100 + index), rate = get(110 + index), accel = get(120 + index);
    log->info("grbl port={} axis={} ${}={} steps/unit ({:.3f} steps/deg) ${}={} units/min ${}={} units/s^2",
              selector_.Describe(), name, 100 + index, steps, steps * upd, 110 + index, rate, 120 + index,
              accel);
    double feed = config_.speed_deg_per_s * 60 * upd;
    if (std::isfinite(rate) && feed > rate + 1e-9)
      log->warn("grbl port={} axis={} speed_deg_per_s={} needs F{:.1f} but ${}={} caps it: moves will be slower",
                selector_.Describe(), name, config_.speed_deg_per_s, feed, 110 + index, rate);
    if (std::isfinite(accel) && std::fabs(accel / upd - config_.accel_deg_per_s2) > 1e-6)
      log->info("grbl port={} axis={} plans with its own acceleration ${}={} ({:.3f} deg/s^2), not "
                "accel_deg_per_s2={}",
                selector_.Describe(), name, 120 + index, accel, accel / upd, config_.accel_deg_per_s2);
  }
  return Ok();
}

Status GrblMotor::ReadBuildOptions() {
  force_set_origin_ = false;
  RIG_TRY(Queue("$I"));
  RIG_ASSIGN_OR_RETURN(Line r, AwaitResponse(Seconds(config_.reply_timeout_s), OnAlarm::kRecord));
  if (r.kind == Kind::kError) {
    Log("motion")->warn("grbl port={} cannot read the build options ($I): error:{} ({}); taken as a build "
                        "without HOMING_FORCE_SET_ORIGIN", selector_.Describe(), r.code, GrblErrorMeaning(r.code));
    return Ok();
  }
  Log("motion")->info("grbl port={} HOMING_FORCE_SET_ORIGIN={}", selector_.Describe(),
                      force_set_origin_ ? "yes ($I lists Z): travel from machine 0 on the homed side"
                                        : "no: machine space negative after homing");
  return Ok();
}

Status GrblMotor::ReadOffsets() {
  offsets_known_ = false;
  RIG_TRY(Queue("$#"));
  RIG_ASSIGN_OR_RETURN(Line r, AwaitResponse(Seconds(config_.reply_timeout_s), OnAlarm::kRecord));
  if (r.kind == Kind::kError) {
    Log("motion")->warn("grbl port={} cannot read the work offsets ($#): error:{} ({}); the grid is not "
                        "checked against the firmware's travel",
                        selector_.Describe(), r.code, GrblErrorMeaning(r.code));
    return Ok();
  }
  offsets_known_ = true;
  // GRBL sends WCO only in every 10th to 30th status report: until one comes, the offsets
  // read here are the work coordinate offset (G54 + G92; TLO is on Z, not ours).
  for (int i = 0; i < 3; ++i) wco_[i] = g54_[i] + g92_[i];
  Log("motion")->info("grbl port={} G54={:.3f},{:.3f},{:.3f} G92={:.3f},{:.3f},{:.3f}", selector_.Describe(),
                      g54_[0], g54_[1], g54_[2], g92_[0], g92_[1], g92_[2]);
  return Ok();
}

std::array<double, 3> GrblMotor::ToWork(const Pose& pose) const {
  std::array<double, 3> work{};
  work[h_index_] = pose.h_deg * config_.grbl.units_per_degree;
  work[v_index_] = pose.v_deg * config_.grbl.units_per_degree;
  return work;
}

Pose GrblMotor::ToPose(const std::array<double, 3>& work) const {
  return Pose{work[h_index_] / config_.grbl.units_per_degree, work[v_index_] / config_.grbl.units_per_degree};
}

std::string GrblMotor::TravelViolation(const Pose& pose) const {
  auto get = [&](int n) { auto it = settings_.find(n); return it == settings_.end() ? NAN : it->second; };
  // Without homing ($22=0) the firmware's machine space starts wherever the arm stood at
  // power-up; only after homing does it span -$13n .. 0 (limits.c, system.c), or with
  // HOMING_FORCE_SET_ORIGIN 0 .. $13n for an axis homed towards its negative end ($23 bit).
  if (get(22) != 1 || !offsets_known_) return "";
  const int dir = std::isfinite(get(23)) ? static_cast<int>(get(23)) : 0;
  const std::array<double, 3> work = ToWork(pose);
  const double upd = config_.grbl.units_per_degree;
  for (auto [name, index] : {std::pair{"h", h_index_}, std::pair{"v", v_index_}}) {
    const double travel = get(130 + index);
    if (!std::isfinite(travel) || travel <= 0) continue;
    const double offset = g54_[index] + g92_[index];
    const double machine = work[index] + offset;
    const bool positive = force_set_origin_ && (dir & (1 << index));
    const double lo = positive ? 0 : -travel, hi = positive ? travel : 0;
    if (machine <= hi + kPositionToleranceUnits && machine >= lo - kPositionToleranceUnits) continue;
    const std::string axis = index == h_index_ ? config_.grbl.h_axis : config_.grbl.v_axis;
    const double deg = index == h_index_ ? pose.h_deg : pose.v_deg;
    const double rig_min = index == h_index_ ? config_.h_limit_min_deg : config_.v_limit_min_deg;
    const double rig_max = index == h_index_ ? config_.h_limit_max_deg : config_.v_limit_max_deg;
    return fmt::format(
        "{} = {:g} deg is outside the firmware's travel: work {}{:.3f} + work offset {:.3f} (G54 + G92, $#) "
        "= machine {}{:.3f}, but ${}={:g} allows machine {}{:g} .. {:g} after homing{}, so {} can only be "
        "{:.3f} .. {:.3f} deg; the rig's pose limits allow {:g} .. {:g} deg ({}_limit_min_deg, "
        "{}_limit_max_deg). {}",
        name, deg, axis, work[index], offset, axis, machine, 130 + index, travel, axis, lo, hi,
        positive ? " (HOMING_FORCE_SET_ORIGIN, homed towards negative)" : "", name, (lo - offset) / upd,
        (hi - offset) / upd, rig_min, rig_max, name, name,
        get(20) == 1 ? "GRBL would raise ALARM:2 (soft limit, $20=1) and then answer nothing until a reset"
                     : "the arm would run past its travel ($20=0: GRBL does not check)");
  }
  return "";
}

Status GrblMotor::CheckReach(const std::vector<Pose>& poses) {
  std::string first;
  int outside = 0;
  for (const Pose& p : poses) {
    std::string why = TravelViolation(p);
    if (why.empty()) continue;
    if (first.empty()) first = "pose " + p.Name() + ": " + why;
    ++outside;
  }
  if (outside == 0) return Ok();
  return Fail(ErrorCode::kInvalidInput,
              fmt::format("{} of {} poses of the grid lie outside the firmware's travel, refused before "
                          "any move; the first, {}. Change the grid, the pose limits or the firmware's "
                          "$13n/work offset (docs/rig-setup.md)",
                          outside, poses.size(), first));
}

Status GrblMotor::OpenPort() {
  port_.reset();
  outstanding_.clear();
  RIG_ASSIGN_OR_RETURN(port_, SerialPort::Open(selector_));
  return Ok();
}

Status GrblMotor::Open() {
  Close();
  RIG_TRY(OpenPort());
  Status st = [&]() -> Status {
    RIG_TRY(WaitForBannerOrReset());
    RIG_ASSIGN_OR_RETURN(GrblStatus s, QueryStatus());
    RIG_TRY(ReadSettings());
    RIG_TRY(ReadBuildOptions());
    RIG_TRY(ReadOffsets());
    Log("motion")->info("grbl open port={} device={} state={}", selector_.Describe(), port_->device(),
                        s.state);
    return Ok();
  }();
  if (!st.ok()) port_.reset();
  return st;
}

void GrblMotor::Close() {
  port_.reset();
  outstanding_.clear();
}

Status GrblMotor::DoHome() {
  auto it = settings_.find(22);
  if (it != settings_.end() && it->second == 0)
    return Fail(ErrorCode::kUnsupported,
                config_.home_on_start
                    ? "homing is disabled on the controller ($22=0): fit limit switches and set $22=1, or "
                      "set motor.home_on_start = false (then pose 0,0 is where the arm stands at power-up)"
                    : "homing is disabled on the controller ($22=0): without limit switches there is no "
                      "homing cycle; pose 0,0 is where the arm stood at power-up (fit switches and set "
                      "$22=1 to home)");
  pending_alarm_ = 0;
  RIG_TRY(Queue("$H"));
  auto r = AwaitResponse(Seconds(config_.move_timeout_s), OnAlarm::kRecord);
  if (!r.ok()) {
    if (PortLost(r.error())) return r.error();
    fault_ = "homing did not finish: " + r.error().message;
    (void)StopMotion(false);
    return Error{r.error().code, r.error().message + "; soft reset sent", r.error().context};
  }
  if (r->kind == Kind::kError)
    return Fail(ErrorCode::kDevice, fmt::format("homing ($H) refused: error:{} ({})", r->code,
                                                GrblErrorMeaning(r->code)));
  if (pending_alarm_ != 0) {
    // GRBL reports a failed homing cycle as ALARM:N *before* the ok of $H, then resets
    // (banner, "[MSG:'$H'|'$X' to unlock]"). The ok is not a success.
    int code = pending_alarm_;
    fault_ = fmt::format("homing failed with ALARM:{}", code);
    last_pose_.reset();
    (void)AwaitBanner(Seconds(config_.reply_timeout_s));
    return AlarmError(code, "during homing ($H)");
  }
  fault_.clear();
  state_ = "Idle";
  RIG_ASSIGN_OR_RETURN(GrblStatus s, QueryStatus());
  auto w = WorkPosition(s);
  last_pose_ = ToPose(w);
  if (std::fabs(w[h_index_]) > kPositionToleranceUnits || std::fabs(w[v_index_]) > kPositionToleranceUnits)
    Log("motion")->warn("grbl port={} after homing the work position is h={:.3f} v={:.3f} units, not 0: "
                        "set the work offset (G10 L20 P1 X0 Y0) so that home is pose 0,0",
                        selector_.Describe(), w[h_index_], w[v_index_]);
  Log("motion")->info("grbl homed port={}", selector_.Describe());
  return Ok();
}

Status GrblMotor::Home() {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  Status st = DoHome();
  if (!st.ok() && PortLost(st.error())) {
    Log("motion")->warn("grbl port={} lost during homing; reconnecting", selector_.Describe());
    RIG_TRY(Reconnect());
    if (config_.after_reconnect == "home") return Ok();
    st = DoHome();
  }
  return st;
}

Status GrblMotor::Unlock() {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  RIG_TRY(Queue("$X"));
  RIG_ASSIGN_OR_RETURN(Line r, AwaitResponse(Seconds(config_.reply_timeout_s), OnAlarm::kRecord));
  if (r.kind == Kind::kError)
    return Fail(ErrorCode::kDevice, fmt::format("$X refused: error:{} ({})", r.code, GrblErrorMeaning(r.code)));
  RIG_ASSIGN_OR_RETURN(GrblStatus s, QueryStatus());
  if (s.state == "Alarm") return Fail(ErrorCode::kDevice, "still in alarm after $X");
  fault_.clear();
  Log("motion")->warn("grbl port={} alarm lock killed with $X: the position is the controller's, unverified",
                      selector_.Describe());
  return Ok();
}

Status GrblMotor::MoveTo(const Pose& pose) {
  std::string where = "pose " + pose.Name();
  if (const std::string why = SoftLimitViolation(config_, pose); !why.empty())
    return Fail(ErrorCode::kInvalidInput, why).Within(where);
  if (!port_) return Fail(ErrorCode::kFault, "not open").Within(where);
  if (const std::string why = TravelViolation(pose); !why.empty())
    return Fail(ErrorCode::kInvalidInput, why).Within(where);
  if (!fault_.empty())
    return Fail(ErrorCode::kFault, "in fault state (" + fault_ + "): home or reconnect first").Within(where);
  Status st = DoMove(pose);
  if (!st.ok() && PortLost(st.error())) {
    Log("motion")->warn("grbl port={} lost during the move to {}; reconnecting", selector_.Describe(),
                        pose.Name());
    Status rc = Reconnect();
    if (!rc.ok()) return rc.error().Within(where);
    st = DoMove(pose);
  }
  if (!st.ok()) return st.error().Within(where);
  return Ok();
}

Status GrblMotor::DoMove(const Pose& pose) {
  if (state_ == "Alarm") {
    RIG_ASSIGN_OR_RETURN(GrblStatus s, QueryStatus());
    // Retrying or reconnecting cannot clear an alarm lock (a reset keeps it): only $H or $X do.
    if (s.state == "Alarm") return AlarmLocked();
  }
  const double upd = config_.grbl.units_per_degree;
  const std::array<double, 3> target = ToWork(pose);
  std::string line = fmt::format("G90 G1 {}{:.3f} {}{:.3f} F{:.1f}", config_.grbl.h_axis, target[h_index_],
                                 config_.grbl.v_axis, target[v_index_], config_.speed_deg_per_s * 60 * upd);
  const bool dwell = config_.grbl.completion == "dwell";
  pending_alarm_ = 0;
  last_pose_.reset();  // unknown until the move is confirmed
  RIG_TRY(Queue(line));
  // G4 P0 waits for the planner to empty before its ok: sent together with the move, its
  // ok is the completion signal and costs no extra round trip.
  if (dwell) RIG_TRY(Queue("G4 P0"));
  auto r1 = AwaitResponse(Seconds(config_.reply_timeout_s), OnAlarm::kFail);
  if (!r1.ok()) return PortLost(r1.error()) ? r1.error() : AbortMove(pose, r1.error());
  if (r1->kind == Kind::kError) {
    if (dwell) (void)AwaitResponse(Seconds(config_.reply_timeout_s), OnAlarm::kRecord);
    return Fail(ErrorCode::kDevice, fmt::format("'{}' refused: error:{} ({})", line, r1->code,
                                                GrblErrorMeaning(r1->code)));
  }
  if (dwell) {
    auto r2 = AwaitResponse(Seconds(config_.move_timeout_s), OnAlarm::kFail);
    if (!r2.ok()) {
      if (PortLost(r2.error())) return r2.error();
      Error e = r2.error();
      if (e.code == ErrorCode::kTimeout)
        e.message = fmt::format("the move did not complete within {:.1f} s (G4 P0 never acknowledged)",
                                config_.move_timeout_s);
      return AbortMove(pose, e);
    }
    if (r2->kind == Kind::kError)
      return Fail(ErrorCode::kDevice, fmt::format("'G4 P0' refused: error:{} ({})", r2->code,
                                                  GrblErrorMeaning(r2->code)));
  } else {
    Status st = WaitIdleByPolling(pose, target);
    if (!st.ok()) return PortLost(st.error()) ? st.error() : AbortMove(pose, st.error());
  }
  last_pose_ = pose;
  return Ok();
}

Status GrblMotor::WaitIdleByPolling(const Pose& pose, const std::array<double, 3>& target) {
  auto deadline = After(Seconds(config_.move_timeout_s));
  bool seen_motion = false;
  const double upd = config_.grbl.units_per_degree;
  for (;;) {
    auto tick = After(Seconds(config_.grbl.poll_interval_s));
    RIG_ASSIGN_OR_RETURN(GrblStatus s, QueryStatus());
    if (pending_alarm_ != 0) return AlarmError(pending_alarm_, "during the move");
    if (s.state == "Alarm") return Fail(ErrorCode::kDevice, "the controller entered alarm during the move");
    auto w = WorkPosition(s);
    bool there = std::fabs(w[h_index_] - target[h_index_]) <= kPositionToleranceUnits &&
                 std::fabs(w[v_index_] - target[v_index_]) <= kPositionToleranceUnits;
    if (s.state == "Idle") {
      if (there) return Ok();
      // Right after the ok of the move GRBL may not have started the cycle yet.
      if (seen_motion)
        return Fail(ErrorCode::kDevice,
                    fmt::format("the controller went idle at h {:.3f} v {:.3f} deg, short of {}",
                                w[h_index_] / upd, w[v_index_] / upd, pose.Name()));
    } else {
      seen_motion = true;
    }
    if (Clock::now() >= deadline)
      return Fail(ErrorCode::kTimeout,
                  fmt::format("the move did not reach Idle within {:.1f} s (state {}, at h {:.3f} v {:.3f} deg)",
                              config_.move_timeout_s, s.state, w[h_index_] / upd, w[v_index_] / upd));
    // Until the next poll (GRBL asks for at most ~5 Hz), read whatever else it says.
    while (Clock::now() < tick) {
      auto next = NextLine(Left(tick));
      if (!next.ok()) {
        if (next.error().code == ErrorCode::kTimeout) break;
        return next.error();
      }
      if (next->kind == Kind::kAlarm) return AlarmError(next->code, "during the move");
    }
  }
}

Seconds GrblMotor::BrakeWait() const {
  // A feed hold decelerates at the block's acceleration from its speed: v/a seconds over
  // v^2/2a units. Per axis, v is the feed (capped by $11n) and a is $12n; the slowest axis
  // bounds any block's stop. Waited out with a margin before the reset, since a reset
  // before Hold:0 raises ALARM:3 (mc_reset()).
  auto get = [&](int n) { auto it = settings_.find(n); return it == settings_.end() ? NAN : it->second; };
  const double upd = config_.grbl.units_per_degree;
  double t = 0;
  for (int index : {h_index_, v_index_}) {
    double v = config_.speed_deg_per_s * upd;
    if (const double rate = get(110 + index); std::isfinite(rate) && rate > 0) v = std::min(v, rate / 60);
    double a = get(120 + index);
    if (!std::isfinite(a) || a <= 0) a = config_.accel_deg_per_s2 * upd;
    t = std::max(t, v / a);
  }
  return Seconds(1.5 * t + config_.reply_timeout_s);
}

Status GrblMotor::StopMotion(bool unlock) {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  // Feed hold decelerates under control; then a soft reset drops the rest of the planner.
  RIG_TRY(SendRealtime('!'));
  auto deadline = After(BrakeWait());
  while (Clock::now() < deadline) {
    auto s = QueryStatus(false);
    if (!s.ok()) {
      if (PortLost(s.error())) return s.error();
      break;
    }
    if ((s->state == "Hold" && s->substate == 0) || s->state == "Idle" || s->state == "Alarm") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  RIG_TRY(SendRealtime('\x18'));
  outstanding_.clear();
  auto banner_deadline = After(Seconds(std::max(config_.reply_timeout_s, config_.grbl.banner_timeout_s)));
  for (;;) {
    Seconds left = Left(banner_deadline);
    if (left.count() <= 0) return Fail(ErrorCode::kTimeout, "no banner after the soft reset");
    auto next = NextLine(left, false);
    if (!next.ok()) return next.error();
    if (next->kind == Kind::kBanner) break;
  }
  outstanding_.clear();
  if (unlock) {
    // GRBL 1.1h raises ALARM:3 on a reset only in a motion state or while the hold is still
    // decelerating (mc_reset()); after "Hold:0" the reset keeps every step and the state is
    // Idle, with nothing to unlock. An alarm here means the hold did not complete in time:
    // steps may be lost, so the lock stays and the axes must be homed. (Not interruptible:
    // this is how a Ctrl-C leaves the arm.)
    auto s = QueryStatus(false);
    if (s.ok() && s->state == "Alarm") {
      last_pose_.reset();
      fault_ = "reset before the feed hold completed (ALARM:3): the position may be lost";
      Log("motion")->error("grbl port={} {}; home before moving again", selector_.Describe(), fault_);
    }
  }
  return Ok();
}

Error GrblMotor::AbortMove(const Pose& pose, const Error& why) {
  if (why.code == ErrorCode::kInterrupted) {
    Status st = StopMotion(true);
    Error e = why;
    e.message += st.ok() ? "; the move was stopped (feed hold, soft reset)"
                         : "; stopping failed: " + st.error().message;
    return e;
  }
  Status st = StopMotion(false);
  fault_ = fmt::format("move to {} failed: {}", pose.Name(), why.message);
  Error e = why;
  e.message += st.ok() ? "; feed hold and soft reset sent, the axes must be re-homed"
                       : "; stopping failed too: " + st.error().message;
  Log("motion")->error("grbl port={} fault: {}", selector_.Describe(), e.message);
  return e;
}

Result<Pose> GrblMotor::Position() {
  if (!port_) return Fail(ErrorCode::kFault, "not open");
  RIG_ASSIGN_OR_RETURN(GrblStatus s, QueryStatus());
  return ToPose(WorkPosition(s));
}

Status GrblMotor::Stop() {
  if (!port_) return Ok();
  auto s = QueryStatus(false);
  if (!s.ok()) return s.error();
  if (s->state == "Idle" && outstanding_.empty()) return Ok();
  if (s->state == "Alarm") return Ok();
  last_pose_.reset();
  return StopMotion(true);
}

Status GrblMotor::ProbeAfterReopen(bool* was_reset) {
  *was_reset = false;
  // A controller that kept its power answers '?' at once; one reset by the reopen (an
  // Arduino's DTR) swallows it in its bootloader and prints its banner when it is up.
  RIG_TRY(SendRealtime('?'));
  auto deadline = After(Seconds(config_.grbl.banner_timeout_s));
  for (;;) {
    Seconds left = Left(deadline);
    if (left.count() <= 0) break;
    auto next = NextLine(left);
    if (!next.ok()) {
      if (next.error().code == ErrorCode::kTimeout) break;
      return next.error();
    }
    if (next->kind == Kind::kStatus) return Ok();
    if (next->kind == Kind::kBanner) {
      *was_reset = true;
      outstanding_.clear();
      pending_alarm_ = 0;
      return Ok();
    }
  }
  // Silent (no auto-reset and the '?' lost, or a critical alarm that answers nothing): a soft
  // reset. It keeps the position when the controller is idle and raises ALARM:3 when not.
  return WaitForBannerOrReset();
}

Status GrblMotor::AfterReconnect(bool was_reset) {
  if (config_.after_reconnect == "home") return DoHome();
  RIG_ASSIGN_OR_RETURN(GrblStatus s, QueryStatus());
  // The link went, the controller did not: it finishes the moves it had. Wait for Idle.
  auto deadline = After(Seconds(config_.move_timeout_s));
  while ((s.state == "Run" || s.state == "Jog") && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::duration<double>(config_.grbl.poll_interval_s));
    RIG_ASSIGN_OR_RETURN(s, QueryStatus());
  }
  if (was_reset || s.state != "Idle") {
    last_pose_.reset();
    const std::string why =
        was_reset ? fmt::format("the controller was reset when the link came back (it printed its banner; "
                                "state {}): GRBL restarts its position then",
                                s.state)
        : s.state == "Alarm"
            ? fmt::format("the controller is in alarm after the link came back{}",
                          pending_alarm_ ? fmt::format(" (ALARM:{}: {})", pending_alarm_,
                                                       GrblAlarmMeaning(pending_alarm_))
                                         : std::string(" (alarm-locked)"))
            : fmt::format("the controller reports state {} after the link came back, not Idle", s.state);
    fault_ = why + "; its position is not known";
    return Fail(ErrorCode::kFault, fault_ + ": home it ('rig home', or motor.after_reconnect = \"home\")");
  }
  // Idle, no alarm, no reset: GRBL keeps its position through a lost link, so it is known.
  const Pose here = ToPose(WorkPosition(s));
  last_pose_ = here;
  fault_.clear();
  Log("motion")->info("grbl port={} position kept through the lost link: Idle at h {:.3f} v {:.3f} deg",
                      selector_.Describe(), here.h_deg, here.v_deg);
  return Ok();
}

Status GrblMotor::Reconnect() {
  ++reconnects_;
  auto log = Log("motion");
  port_.reset();
  outstanding_.clear();
  Error last = Fail(ErrorCode::kFault, "no attempt made");
  double backoff_s = config_.retry_backoff_s;
  const int attempts = std::max(1, config_.retries);
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    // A replugged board needs time to enumerate again; wait before every attempt.
    auto until = After(Seconds(backoff_s));
    while (Clock::now() < until) {
      if (SerialInterruptRequested()) return Fail(ErrorCode::kInterrupted, "interrupted while reconnecting");
      std::this_thread::sleep_for(std::min<Clock::duration>(until - Clock::now(), std::chrono::milliseconds(20)));
    }
    backoff_s *= 2;
    Status st = OpenPort();
    bool was_reset = false;
    if (st.ok()) st = ProbeAfterReopen(&was_reset);
    if (st.ok()) st = ReadSettings();
    if (st.ok()) st = ReadBuildOptions();
    if (st.ok()) st = ReadOffsets();
    if (st.ok()) {
      st = AfterReconnect(was_reset);
      if (st.ok()) {
        log->warn("grbl port={} reconnected (attempt {} of {}) after_reconnect={}", selector_.Describe(),
                  attempt, attempts, config_.after_reconnect);
        return Ok();
      }
      if (!PortLost(st.error()) && st.error().code != ErrorCode::kTimeout) {
        if (fault_.empty()) fault_ = st.error().message;
        return st;
      }
    }
    if (st.error().code == ErrorCode::kInterrupted) return st;
    last = st.error();
    log->warn("grbl port={} reconnect attempt {} of {} failed: {}", selector_.Describe(), attempt, attempts,
              last.message);
    port_.reset();
  }
  fault_ = fmt::format("the port did not come back after {} attempts ({})", attempts, last.message);
  return Fail(ErrorCode::kFault, fault_);
}

std::unique_ptr<Motor> MakeGrblMotor(const MotorConfig& config) {
  return std::make_unique<GrblMotor>(config);
}

}  // namespace rig
