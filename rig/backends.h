// The one place that knows every concrete backend: builds the camera, motor and lamp a
// configuration names (the simulated ones for "sim"), sharing one simulated world.
#pragma once

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "capture/devices/camera.h"
#include "config/config.h"
#include "capture/devices/lamp.h"
#include "capture/devices/motor.h"
#include "capture/plan/pose.h"

namespace rig {

struct Devices {
  std::unique_ptr<Camera> camera;
  std::unique_ptr<Motor> motor;
  std::unique_ptr<Lamp> lamp;
  // Settle time scale: the simulator's latency_scale when the motor is simulated, else 1.
  double settle_scale = 1.0;
  // Set when the camera is simulated: writes the ground truth (truth/) for these poses.
  std::function<Status(const std::filesystem::path& truth_dir, const std::vector<Pose>& poses)>
      write_truth;
  // Keeps shared simulator state alive as long as the devices.
  std::shared_ptr<void> keep_alive;
};

// Builds the devices of `config`; an unknown or not-built backend is a clear error.
Result<Devices> MakeDevices(const Config& config);

// The backends this build contains, e.g. "sim-camera", "gphoto2-camera" (rig --version).
std::vector<std::string> BuiltBackends();

// Makes every backend the simulated one (what `--dry-run` does).
void UseSimulatedBackends(Config* config);

}  // namespace rig
