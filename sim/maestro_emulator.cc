// MaestroEmulator: command packets in, replies out, servo outputs updated every 10 ms.
#include "sim/maestro_emulator.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rig {
namespace {

// Bytes in a compact-protocol packet, command byte included; 0: unknown command.
size_t PacketLength(const std::string& p) {
  switch (static_cast<uint8_t>(p[0])) {
    case 0x84: case 0x87: case 0x89: return 4;  // set target / speed / acceleration
    case 0x90: return 2;                        // get position
    case 0x93: case 0xA1: case 0xA2: return 1;  // moving state, errors, go home
    case 0x9F: return p.size() < 2 ? 2 : 3 + 2 * static_cast<size_t>(static_cast<uint8_t>(p[1]));
  }
  return 0;
}

constexpr uint16_t kSerialProtocolError = 1u << 4;

}  // namespace

MaestroEmulator::MaestroEmulator(MaestroEmulatorOptions options)
    : PtyEmulator(options.time_scale), options_(std::move(options)) {
  ch_.resize(static_cast<size_t>(std::max(1, options_.channels)));
}

MaestroEmulator::~MaestroEmulator() { Stop(); }

void MaestroEmulator::SetOptions(const MaestroEmulatorOptions& options) {
  std::lock_guard<std::mutex> lock(mu_);
  options_ = options;
}

int MaestroEmulator::target(int c) const {
  std::lock_guard<std::mutex> lock(mu_);
  return ch_.at(static_cast<size_t>(c)).target;
}
int MaestroEmulator::position(int c) const {
  std::lock_guard<std::mutex> lock(mu_);
  return static_cast<int>(std::lround(ch_.at(static_cast<size_t>(c)).position));
}
int MaestroEmulator::speed(int c) const {
  std::lock_guard<std::mutex> lock(mu_);
  return ch_.at(static_cast<size_t>(c)).speed;
}
int MaestroEmulator::acceleration(int c) const {
  std::lock_guard<std::mutex> lock(mu_);
  return ch_.at(static_cast<size_t>(c)).accel;
}
uint16_t MaestroEmulator::errors() const {
  std::lock_guard<std::mutex> lock(mu_);
  return errors_;
}
void MaestroEmulator::SetErrors(uint16_t bits) {
  std::lock_guard<std::mutex> lock(mu_);
  errors_ |= bits;
}
int MaestroEmulator::set_target_count() const {
  std::lock_guard<std::mutex> lock(mu_);
  return set_targets_;
}
std::vector<double> MaestroEmulator::motion_times_s() const {
  std::lock_guard<std::mutex> lock(mu_);
  return motion_times_;
}

void MaestroEmulator::OnPowerUp() {
  // Power-up: outputs off (no pulses), speed and acceleration back to unlimited.
  std::fill(ch_.begin(), ch_.end(), Channel{});
  errors_ = 0;
  packet_.clear();
  pololu_ = false;
  in_motion_ = false;
  next_update_ = Now();
}

void MaestroEmulator::OnInput(std::string_view bytes) {
  for (char ch : bytes) {
    uint8_t b = static_cast<uint8_t>(ch);
    if (b & 0x80) {
      // A command byte interrupting an unfinished packet is a protocol error.
      if (!packet_.empty()) errors_ |= kSerialProtocolError;
      packet_.assign(1, static_cast<char>(b));
      pololu_ = b == 0xAA;
      if (!pololu_ && PacketLength(packet_) == 0) {
        errors_ |= kSerialProtocolError;
        packet_.clear();
        continue;
      }
    } else {
      if (packet_.empty()) {
        errors_ |= kSerialProtocolError;  // a data byte without a command
        continue;
      }
      packet_ += static_cast<char>(b);
      if (pololu_) {
        // 0xAA, device number, command with its top bit cleared, data: the same packet.
        if (packet_.size() < 3) continue;
        if (packet_.size() == 3) {
          if (static_cast<uint8_t>(packet_[1]) != options_.device_number) {
            packet_.clear();  // for another device on the line: ignore what follows
            pololu_ = false;
            continue;
          }
          packet_ = std::string(1, static_cast<char>(static_cast<uint8_t>(packet_[2]) | 0x80));
          pololu_ = false;
          if (PacketLength(packet_) == 0) {
            errors_ |= kSerialProtocolError;
            packet_.clear();
            continue;
          }
        }
      }
    }
    if (!pololu_ && !packet_.empty() && packet_.size() >= PacketLength(packet_)) {
      Execute();
      packet_.clear();
      if (!PluggedLocked()) return;
    }
  }
}

void MaestroEmulator::Execute() {
  const auto p = [&](size_t i) { return static_cast<uint8_t>(packet_[i]); };
  const uint8_t cmd = p(0);
  auto channel_ok = [&](int c) {
    if (c >= 0 && c < static_cast<int>(ch_.size())) return true;
    errors_ |= kSerialProtocolError;
    return false;
  };
  auto set_target = [&](int c, int v) {
    if (!channel_ok(c)) return;
    int n = ++set_targets_;
    if (options_.disconnect_at_target == n) {
      UnplugLocked(options_.replug_after_s, !options_.reset_on_replug);
      return;
    }
    if (options_.error_at_target == n) errors_ |= options_.error_bits;
    Channel& k = ch_[static_cast<size_t>(c)];
    if (v != 0) v = std::clamp(v, static_cast<int>(std::lround(options_.min_us * 4)),
                               static_cast<int>(std::lround(options_.max_us * 4)));
    k.target = v;
    k.stalled = false;
    k.stall_at = 0;
    // An output that was off has no known position: it jumps to the new target.
    if (v != 0 && k.position == 0) k.position = v;
    if (options_.stall_at_target == n && k.position != v) k.stall_at = k.position + (v - k.position) / 2;
    if (!in_motion_ && AnyMoving()) {
      in_motion_ = true;
      motion_start_ = Now();
    }
  };
  switch (cmd) {
    case 0x84:
      set_target(p(1), p(2) | (p(3) << 7));
      break;
    case 0x9F: {
      int num = p(1), first = p(2);
      for (int i = 0; i < num; ++i) set_target(first + i, p(3 + 2 * i) | (p(4 + 2 * i) << 7));
      break;
    }
    case 0x87:
      if (channel_ok(p(1))) ch_[p(1)].speed = p(2) | (p(3) << 7);
      break;
    case 0x89:
      if (channel_ok(p(1))) ch_[p(1)].accel = std::min(255, p(2) | (p(3) << 7));
      break;
    case 0x90: {
      if (!channel_ok(p(1))) break;
      int v = static_cast<int>(std::lround(ch_[p(1)].position));
      char r[2] = {static_cast<char>(v & 0xFF), static_cast<char>((v >> 8) & 0xFF)};
      Send(std::string_view(r, 2));
      break;
    }
    case 0x93: {
      char r = AnyMoving() ? 1 : 0;
      Send(std::string_view(&r, 1));
      break;
    }
    case 0xA1: {
      char r[2] = {static_cast<char>(errors_ & 0xFF), static_cast<char>(errors_ >> 8)};
      Send(std::string_view(r, 2));
      errors_ = 0;  // cleared on read
      break;
    }
    case 0xA2:
      for (auto& k : ch_) k = Channel{0, 0, 0, k.speed, k.accel};  // home mode "off"
      break;
  }
}

bool MaestroEmulator::AnyMoving() const {
  for (const auto& k : ch_)
    if (k.target != 0 && std::lround(k.position) != k.target) return true;
  return false;
}

void MaestroEmulator::Update10ms() {
  for (auto& k : ch_) {
    if (k.target == 0) {
      k.position = 0;
      k.velocity = 0;
      continue;
    }
    if (k.stalled) continue;
    double diff = k.target - k.position;
    if (diff == 0) {
      k.velocity = 0;
      continue;
    }
    double dir = diff > 0 ? 1 : -1, dist = std::fabs(diff);
    double vmax = k.speed > 0 ? k.speed : std::numeric_limits<double>::infinity();
    double step;
    if (k.accel == 0) {
      step = std::min(vmax, dist);
    } else {
      // Velocity changes by `accel` every 80 ms, i.e. accel/8 per 10 ms update; slow down
      // when the remaining distance is what it takes to stop.
      double a = k.accel / 8.0;
      double v = k.velocity;
      if (v * v / (2 * a) >= dist)
        v = std::max(v - a, a);
      else
        v = std::min(v + a, vmax);
      k.velocity = v;
      step = std::min(v, dist);
    }
    k.position += dir * step;
    if (step >= dist) {
      k.position = k.target;
      k.velocity = 0;
    }
    if (k.stall_at != 0 && dir * (k.position - k.stall_at) >= 0) {
      k.position = k.stall_at;
      k.stalled = true;
    }
  }
}

void MaestroEmulator::OnTick() {
  const double now = Now();
  // After a long gap (unplugged), do not replay it update by update.
  if (now - next_update_ > 60) next_update_ = now;
  while (next_update_ <= now) {
    Update10ms();
    next_update_ += 0.010;
    if (in_motion_ && !AnyMoving()) {
      in_motion_ = false;
      motion_times_.push_back(next_update_ - motion_start_);
    }
  }
}

Result<std::unique_ptr<MaestroEmulator>> StartMaestroEmulator(const MaestroEmulatorOptions& options,
                                                              const std::string& link_path) {
  auto e = std::make_unique<MaestroEmulator>(options);
  RIG_TRY(e->Start(link_path));
  return e;
}

}  // namespace rig
