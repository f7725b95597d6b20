// rig check-config FILE: validates a configuration and lists every problem with its place.
#include <cstdio>

#include "capture/plan/bracket.h"
#include "config/config.h"
#include "rig/commands/command.h"
#include "capture/plan/pose.h"

namespace rig {

int RunCheckConfig(int argc, char** argv) {
  CLI::App app{"Validate a rig configuration file; lists every problem with file:line:column.",
               "rig check-config"};
  std::vector<std::string> files;
  bool print = false;
  app.add_option("FILE", files, "configuration file(s) (TOML)")->required();
  app.add_flag("--print", print, "print the resolved configuration (defaults filled in)");
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;

  int rc = 0;
  for (const auto& file : files) {
    ConfigResult r = LoadConfig(file);
    if (!r.ok()) {
      for (const auto& d : r.diagnostics) std::fprintf(stderr, "%s\n", d.ToString().c_str());
      std::fprintf(stderr, "%s: %zu error%s\n", file.c_str(), r.diagnostics.size(),
                   r.diagnostics.size() == 1 ? "" : "s");
      rc = 2;
      continue;
    }
    const Config& c = r.config;
    auto poses = PlanGrid(c.grid);
    auto wanted = WantedExposures(c.bracket);
    std::printf("%s: ok: %zu poses x %zu exposures; camera %s, motor %s, lamp %s\n", file.c_str(),
                poses.size(), wanted.size(), c.camera.backend.c_str(), c.motor.backend.c_str(),
                c.lamp.backend.c_str());
    if (print) std::printf("%s\n", ToToml(c).c_str());
  }
  return rc;
}

}  // namespace rig
