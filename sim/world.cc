// The simulated rig's shared state.
#include "sim/world.h"

namespace rig {

SimWorldState SimWorld::State() const {
  std::lock_guard<std::mutex> lock(mu_);
  return s_;
}

void SimWorld::SetPose(double h_deg, double v_deg) {
  std::lock_guard<std::mutex> lock(mu_);
  s_.h_deg = h_deg;
  s_.v_deg = v_deg;
}

void SimWorld::SetMoving(bool moving) {
  std::lock_guard<std::mutex> lock(mu_);
  s_.moving = moving;
}

void SimWorld::SetLamp(bool on) {
  std::lock_guard<std::mutex> lock(mu_);
  s_.lamp_on = on;
  s_.lamp_ready = false;
  s_.lamp_since = std::chrono::steady_clock::now();
  ++s_.lamp_switches;
}

void SimWorld::SetLampReady() {
  std::lock_guard<std::mutex> lock(mu_);
  if (s_.lamp_on) s_.lamp_ready = true;
}

void SimWorld::CountMove() {
  std::lock_guard<std::mutex> lock(mu_);
  ++s_.moves;
}

SimWorldState SimWorld::RecordCapture() {
  std::lock_guard<std::mutex> lock(mu_);
  ++s_.captures;
  if (s_.moving) ++s_.captures_while_moving;
  if (!s_.lamp_on) ++s_.captures_lamp_off;
  else if (!s_.lamp_ready) ++s_.captures_during_warmup;
  return s_;
}

}  // namespace rig
