// The simulated lamp.
#include "sim/sim_lamp.h"

#include <algorithm>
#include <thread>

#include <fmt/format.h>

namespace rig {

SimLamp::SimLamp(const Config& config, std::shared_ptr<SimWorld> world)
    : warmup_s_(config.lamp.warmup_s),
      faults_(config.sim.lamp),
      latency_scale_(config.sim.latency_scale),
      world_(std::move(world)) {
  RIG_CHECK(world_ != nullptr, "SimLamp needs a world");
}

std::string SimLamp::Describe() const { return "sim lamp"; }

Status SimLamp::Open() {
  std::lock_guard<std::mutex> lock(mu_);
  open_ = true;
  return Ok();
}

Status SimLamp::Switch(bool on) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!open_) return Error{ErrorCode::kDevice, "switching before Open()", "sim lamp"};
  const int64_t n = ++stats_.switchings;
  if (std::find(faults_.fail_switch_at.begin(), faults_.fail_switch_at.end(), n) !=
      faults_.fail_switch_at.end()) {
    ++stats_.faults;
    return Error{ErrorCode::kDevice,
                 fmt::format("switching {} ({}): relay did not switch (simulated fault)", n,
                             on ? "on" : "off"),
                 "sim lamp"};
  }
  world_->SetLamp(on);
  if (on) {
    if (latency_scale_ > 0) std::this_thread::sleep_for(Seconds(warmup_s_ * latency_scale_));
    stats_.warmup_time += Seconds(warmup_s_);
    world_->SetLampReady();
  }
  return Ok();
}

Status SimLamp::On() { return Switch(true); }
Status SimLamp::Off() { return Switch(false); }

void SimLamp::Close() {
  std::lock_guard<std::mutex> lock(mu_);
  if (world_->State().lamp_on) world_->SetLamp(false);
  open_ = false;
}

SimLamp::Stats SimLamp::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

}  // namespace rig
