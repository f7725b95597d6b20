// A dry-run session in this process, with the simulated devices built here (what
// rig/backends.cc builds for an all-"sim" configuration).
#include "sim/dry_session.h"

#include <memory>

#include "capture/daemon/daemon.h"
#include "capture/plan/pose.h"
#include "capture/session/session_store.h"
#include "sim/sim_camera.h"
#include "sim/sim_lamp.h"
#include "sim/sim_motor.h"
#include "sim/truth.h"
#include "sim/world.h"

namespace rig {

Status RunSimulatedSession(const Config& base, const std::filesystem::path& dir) {
  Config config = base;
  config.camera.backend = "sim";
  config.motor.backend = "sim";
  config.lamp.backend = "sim";
  config.sim.latency_scale = 0;
  RIG_ASSIGN_OR_RETURN(Session session, Session::Create(dir, config));
  auto world = std::make_shared<SimWorld>();
  RIG_ASSIGN_OR_RETURN(std::unique_ptr<SimCamera> camera, SimCamera::Create(config, world));
  SimMotor motor(config, world);
  SimLamp lamp(config, world);
  RIG_TRY(WriteTruth(session.layout().truth().string(), config));
  CaptureOptions options;
  options.settle_scale = 0;
  options.progress = false;
  CaptureDaemon daemon(session, *camera, motor, lamp, options);
  CaptureSummary summary;
  RIG_TRY(daemon.Run(&summary));
  if (!summary.processing.failed.empty()) {
    return MakeError(ErrorCode::kFault, dir.string(), "{} poses failed to merge",
                     summary.processing.failed.size());
  }
  return Ok();
}

}  // namespace rig
