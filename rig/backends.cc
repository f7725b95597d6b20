// The one place that knows every concrete backend.
#include "rig/backends.h"

#include "build_info.h"
#include "sim/sim_camera.h"
#include "sim/sim_lamp.h"
#include "sim/sim_motor.h"
#include "sim/truth.h"
#include "sim/world.h"
#if RIG_WITH_GPHOTO2
#define RIG_HAVE_GPHOTO2_BACKEND 1
#include "capture/devices/gphoto2_camera.h"
#endif
#if RIG_WITH_SERIALPORT
#define RIG_HAVE_SERIAL_BACKEND 1
#include "capture/devices/grbl_motor.h"
#include "capture/devices/maestro_motor.h"
#endif
#if RIG_WITH_GPIOD
#define RIG_HAVE_GPIOD_BACKEND 1
#include "capture/devices/gpiod_lamp.h"
#endif

namespace rig {
namespace {

// A real motor in a rig whose camera is simulated: the simulated camera must see the lamp
// where the real arm put it, and know when it moves.
class WorldTrackingMotor final : public Motor {
 public:
  WorldTrackingMotor(std::unique_ptr<Motor> inner, std::shared_ptr<SimWorld> world)
      : inner_(std::move(inner)), world_(std::move(world)) {}
  std::string Describe() const override { return inner_->Describe(); }
  Status Open() override { return inner_->Open(); }
  void Close() override { inner_->Close(); }
  Status Home() override { return Track([&] { return inner_->Home(); }); }
  Status MoveTo(const Pose& pose) override { return Track([&] { return inner_->MoveTo(pose); }); }
  Result<Pose> Position() override { return inner_->Position(); }
  Status Stop() override { return inner_->Stop(); }
  Status Reconnect() override { return Track([&] { return inner_->Reconnect(); }); }
  Status Unlock() override { return inner_->Unlock(); }
  Status CheckReach(const std::vector<Pose>& poses) override { return inner_->CheckReach(poses); }

 private:
  template <typename F>
  Status Track(F&& f) {
    world_->SetMoving(true);
    Status st = f();
    world_->SetMoving(false);
    auto where = inner_->Position();
    if (where.ok()) world_->SetPose(where->h_deg, where->v_deg);
    return st;
  }
  std::unique_ptr<Motor> inner_;
  std::shared_ptr<SimWorld> world_;
};

// A real lamp in a rig whose camera is simulated: the simulated camera sees it switch.
class WorldTrackingLamp final : public Lamp {
 public:
  WorldTrackingLamp(std::unique_ptr<Lamp> inner, std::shared_ptr<SimWorld> world)
      : inner_(std::move(inner)), world_(std::move(world)) {}
  std::string Describe() const override { return inner_->Describe(); }
  Status Open() override { return inner_->Open(); }
  Status On() override {
    Status st = inner_->On();
    if (st.ok()) {
      world_->SetLamp(true);
      world_->SetLampReady();
    }
    return st;
  }
  Status Off() override {
    Status st = inner_->Off();
    if (st.ok()) world_->SetLamp(false);
    return st;
  }
  void Close() override {
    inner_->Close();
    world_->SetLamp(false);
  }

 private:
  std::unique_ptr<Lamp> inner_;
  std::shared_ptr<SimWorld> world_;
};

[[maybe_unused]] Error NotBuilt(const std::string& what, const char* library) {
  return MakeError(ErrorCode::kUnsupported, what,
                   "this build of rig has no {} backend ({} was not found at build time; "
                   "'rig --version' lists the backends built in)",
                   what, library);
}

}  // namespace

std::vector<std::string> BuiltBackends() {
  std::vector<std::string> b = {"sim-camera", "sim-motor", "sim-lamp"};
#if RIG_HAVE_GPHOTO2_BACKEND
  b.push_back("gphoto2-camera");
#endif
#if RIG_HAVE_SERIAL_BACKEND
  b.push_back("grbl-motor");
  b.push_back("maestro-motor");
#endif
#if RIG_HAVE_GPIOD_BACKEND
  b.push_back("gpiod-lamp");
#endif
  return b;
}

void UseSimulatedBackends(Config* config) {
  config->camera.backend = "sim";
  config->motor.backend = "sim";
  config->lamp.backend = "sim";
}

Result<Devices> MakeDevices(const Config& config) {
  Devices d;
  auto world = std::make_shared<SimWorld>();
  d.keep_alive = world;
  const bool sim_camera = config.camera.backend == "sim";

  if (sim_camera) {
    RIG_ASSIGN_OR_RETURN(std::unique_ptr<SimCamera> cam, SimCamera::Create(config, world));
    d.write_truth = [config](const std::filesystem::path& truth_dir, const std::vector<Pose>&) {
      return WriteTruth(truth_dir.string(), config);
    };
    d.camera = std::move(cam);
  } else if (config.camera.backend == "gphoto2") {
#if RIG_HAVE_GPHOTO2_BACKEND
    d.camera = MakeGPhoto2Camera(config.camera);
#else
    return NotBuilt("gphoto2 camera", "libgphoto2");
#endif
  } else {
    return MakeError(ErrorCode::kInvalidInput, "camera.backend", "unknown backend '{}'", config.camera.backend);
  }

  std::unique_ptr<Motor> motor;
  if (config.motor.backend == "sim") {
    motor = std::make_unique<SimMotor>(config, world);
    d.settle_scale = config.sim.latency_scale;
  } else if (config.motor.backend == "grbl" || config.motor.backend == "maestro") {
#if RIG_HAVE_SERIAL_BACKEND
    motor = config.motor.backend == "grbl" ? MakeGrblMotor(config.motor) : MakeMaestroMotor(config.motor);
    if (sim_camera) motor = std::make_unique<WorldTrackingMotor>(std::move(motor), world);
#else
    return NotBuilt(config.motor.backend + " motor", "libserialport");
#endif
  } else {
    return MakeError(ErrorCode::kInvalidInput, "motor.backend", "unknown backend '{}'", config.motor.backend);
  }
  d.motor = std::move(motor);

  if (config.lamp.backend == "sim") {
    d.lamp = std::make_unique<SimLamp>(config, world);
  } else if (config.lamp.backend == "gpiod") {
#if RIG_HAVE_GPIOD_BACKEND
    d.lamp = MakeGpiodLamp(config.lamp);
    if (sim_camera) d.lamp = std::make_unique<WorldTrackingLamp>(std::move(d.lamp), world);
#else
    return NotBuilt("gpiod lamp", "libgpiod");
#endif
  } else {
    return MakeError(ErrorCode::kInvalidInput, "lamp.backend", "unknown backend '{}'", config.lamp.backend);
  }
  return d;
}

}  // namespace rig
