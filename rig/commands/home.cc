// rig home: runs the homing cycle (or, with --unlock, kills GRBL's alarm lock with $X) and
// reports where the controller says the arm is.
#include <cstdio>

#include "capture/devices/signals.h"
#include "rig/backends.h"
#include "rig/commands/bringup.h"
#include "rig/commands/command.h"

namespace rig {

int RunHome(int argc, char** argv) {
  CLI::App app{"Run the lamp arm's homing cycle and report the position. --unlock instead "
               "clears a GRBL alarm lock with $X, keeping the position the controller holds "
               "(only when the arm is known to be where the controller thinks).",
               "rig home"};
  BringUpOptions o;
  bool unlock = false;
  app.add_flag("--unlock", unlock, "send $X (kill the alarm lock) instead of homing");
  AddBringUpOptions(app, &o);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(o.level)) return *rc;
  auto config = LoadBringUpConfig(o);
  if (!config.ok()) return ReportError("home", config.error());
  auto devices = MakeDevices(*config);
  if (!devices.ok()) return ReportError("home", devices.error());
  Motor& motor = *devices->motor;
  InstallStopHandlers();
  Status st = motor.Open();
  if (!st.ok()) return ReportError("home", st.error().Within(motor.Describe()));
  st = unlock ? motor.Unlock() : motor.Home();
  if (!st.ok()) {
    (void)motor.Stop();
    motor.Close();
    return StopRequested() ? 128 + StopSignal() : ReportError("home", st.error().Within(motor.Describe()));
  }
  auto where = motor.Position();
  motor.Close();
  if (!where.ok()) return ReportError("home", where.error().Within(motor.Describe()));
  std::printf("%s: %s; at h %.3f v %.3f deg\n", motor.Describe().c_str(),
              unlock ? "unlocked ($X)" : "homed", where->h_deg, where->v_deg);
  return 0;
}

}  // namespace rig
