// The simulated lamp: on/off with a warm-up time, faults on demand, state in the SimWorld.
//
// On() switches on and waits out lamp.warmup_s * sim.latency_scale before returning (the
// world marks the lamp ready then). Switching numbers count On() and Off() calls from 1 over
// the object's life; those listed in sim.lamp.fail_switch_at fail once with kDevice ("relay
// did not switch"), leaving the lamp as it was. Close() always switches off and never fails.
// Every error's context is "sim lamp".
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "config/config.h"
#include "capture/devices/lamp.h"
#include "sim/world.h"

namespace rig {

class SimLamp final : public Lamp {
 public:
  // Uses config.lamp.warmup_s, config.sim.lamp (faults) and config.sim.latency_scale.
  SimLamp(const Config& config, std::shared_ptr<SimWorld> world);

  std::string Describe() const override;
  Status Open() override;
  Status On() override;
  Status Off() override;
  void Close() override;

  struct Stats {
    int64_t switchings = 0;   // On()/Off() calls (the fault numbering)
    int64_t faults = 0;
    Seconds warmup_time{0};   // simulated (unscaled) warm-up time waited
  };
  Stats stats() const;

 private:
  Status Switch(bool on);

  double warmup_s_;
  SimLampConfig faults_;
  double latency_scale_;
  std::shared_ptr<SimWorld> world_;
  mutable std::mutex mu_;
  bool open_ = false;
  Stats stats_;
};

}  // namespace rig
