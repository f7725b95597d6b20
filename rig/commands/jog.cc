// rig jog --to H,V: moves the lamp arm to one pose (soft limits checked first) and reports
// where the controller says it is.
#include <cstdio>

#include "capture/devices/signals.h"
#include "rig/backends.h"
#include "rig/commands/bringup.h"
#include "rig/commands/command.h"

namespace rig {

int RunJog(int argc, char** argv) {
  CLI::App app{"Move the lamp arm to one pose (degrees) and report the position the controller "
               "gives back. The configuration's soft limits are checked before anything moves.",
               "rig jog"};
  BringUpOptions o;
  std::string to;
  bool home_first = false;
  app.add_option("--to", to, "target pose H,V in degrees (e.g. 30,10)")->required();
  app.add_flag("--home", home_first, "run the homing cycle first");
  AddBringUpOptions(app, &o);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(o.level)) return *rc;
  auto config = LoadBringUpConfig(o);
  if (!config.ok()) return ReportError("jog", config.error());
  auto pose = ParsePoseArgument(to, "--to");
  if (!pose.ok()) return ReportError("jog", pose.error());
  if (const std::string why = SoftLimitViolation(config->motor, *pose); !why.empty())
    return ReportError("jog", MakeError(ErrorCode::kInvalidInput, "--to " + to, "{}", why));
  auto devices = MakeDevices(*config);
  if (!devices.ok()) return ReportError("jog", devices.error());
  Motor& motor = *devices->motor;
  InstallStopHandlers();
  Status st = motor.Open();
  if (!st.ok()) return ReportError("jog", st.error().Within(motor.Describe()));
  if (home_first) {
    st = motor.Home();
    if (!st.ok()) {
      motor.Close();
      return StopRequested() ? 128 + StopSignal() : ReportError("jog", st.error().Within(motor.Describe()));
    }
  }
  st = motor.MoveTo(*pose);
  if (!st.ok()) {
    (void)motor.Stop();
    motor.Close();
    return StopRequested() ? 128 + StopSignal() : ReportError("jog", st.error().Within(motor.Describe()));
  }
  auto where = motor.Position();
  motor.Close();
  if (!where.ok()) return ReportError("jog", where.error().Within(motor.Describe()));
  std::printf("%s: at h %.3f v %.3f deg (asked %s)\n", motor.Describe().c_str(), where->h_deg,
              where->v_deg, pose->Name().c_str());
  return 0;
}

}  // namespace rig
