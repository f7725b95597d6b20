// rig lamp on|off|blink: switches the lamp relay by hand; the lamp is always left off (also
// on Ctrl-C).
#include <cstdio>

#include "capture/devices/signals.h"
#include "rig/backends.h"
#include "rig/commands/bringup.h"
#include "rig/commands/command.h"

namespace rig {

int RunLamp(int argc, char** argv) {
  CLI::App app{"Switch the lamp: 'on' holds it on for --for seconds (0: until Ctrl-C), 'off' "
               "switches it off, 'blink' switches it on and off --times times. The lamp is "
               "always left off, also on Ctrl-C.",
               "rig lamp"};
  BringUpOptions o;
  std::string action;
  int times = 3;
  double on_s = 1.0, off_s = 1.0, for_s = 0;
  app.add_option("ACTION", action, "on, off or blink")->required()->check(CLI::IsMember({"on", "off", "blink"}));
  app.add_option("--times", times, "blink: how many times (default 3)")->check(CLI::Range(1, 10000));
  app.add_option("--on-s", on_s, "blink: seconds on, after the warm-up (default 1)")->check(CLI::Range(0.0, 3600.0));
  app.add_option("--off-s", off_s, "blink: seconds off (default 1)")->check(CLI::Range(0.0, 3600.0));
  app.add_option("--for", for_s, "on: seconds to hold it on (default 0: until Ctrl-C)")->check(CLI::Range(0.0, 86400.0));
  AddBringUpOptions(app, &o);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(o.level)) return *rc;
  auto config = LoadBringUpConfig(o);
  if (!config.ok()) return ReportError("lamp", config.error());
  auto devices = MakeDevices(*config);
  if (!devices.ok()) return ReportError("lamp", devices.error());
  Lamp& lamp = *devices->lamp;
  InstallStopHandlers();
  Status st = lamp.Open();
  if (!st.ok()) return ReportError("lamp", st.error().Within(lamp.Describe()));
  // Whatever happens from here, the lamp ends off.
  auto leave = [&](int rc) {
    Status off = lamp.Off();
    lamp.Close();
    if (!off.ok()) return ReportError("lamp", off.error().Within(lamp.Describe()));
    std::printf("%s: off\n", lamp.Describe().c_str());
    return StopRequested() ? 128 + StopSignal() : rc;
  };
  if (action == "off") return leave(0);
  if (action == "on") {
    st = lamp.On();
    if (!st.ok()) return leave(ReportError("lamp", st.error().Within(lamp.Describe())));
    std::printf("%s: on%s\n", lamp.Describe().c_str(), for_s > 0 ? "" : " (Ctrl-C switches it off)");
    std::fflush(stdout);
    if (for_s > 0) {
      SleepUnlessStopped(Seconds(for_s));
    } else {
      while (SleepUnlessStopped(Seconds(3600))) {
      }
    }
    return leave(0);
  }
  for (int i = 1; i <= times && !StopRequested(); ++i) {
    st = lamp.On();
    if (!st.ok()) return leave(ReportError("lamp", st.error().Within(lamp.Describe())));
    std::printf("%s: on (%d of %d)\n", lamp.Describe().c_str(), i, times);
    std::fflush(stdout);
    if (!SleepUnlessStopped(Seconds(on_s))) break;
    st = lamp.Off();
    if (!st.ok()) return leave(ReportError("lamp", st.error().Within(lamp.Describe())));
    if (i < times && !SleepUnlessStopped(Seconds(off_s))) break;
  }
  return leave(0);
}

}  // namespace rig
