// rig shot --exposure S: one frame at one exposure (lamp on), its histogram, clipped and dark
// fractions, and the bracket the scene needs (capture/session/test_shot.h).
#include <cstdio>

#include "capture/devices/signals.h"
#include "capture/session/test_shot.h"
#include "rig/backends.h"
#include "rig/commands/bringup.h"
#include "rig/commands/command.h"

namespace rig {
int RunShot(int argc, char** argv) {
  CLI::App app{"Capture one frame at one exposure with the lamp on (optionally at a pose) and "
               "print its histogram, the clipped and dark fractions, and a bracket for the "
               "scene: the brightest 0.1% of pixels at value 200 in the shortest exposure, the "
               "darkest 1% at 128 in the longest (values taken as sRGB-like), 1-stop steps, "
               "snapped to the body's shutter speeds (docs/rig-setup.md).",
               "rig shot"};
  BringUpOptions o;
  double exposure = 0;
  std::string at, save;
  bool no_lamp = false;
  app.add_option("--exposure", exposure, "exposure time in seconds (snapped to the body's nearest)")
      ->required()->check(CLI::PositiveNumber);
  app.add_option("--at", at, "move the arm to this pose H,V first");
  app.add_option("--save", save, "write the frame to this file (refused if it exists)");
  app.add_flag("--no-lamp", no_lamp, "leave the lamp off (ambient light only)");
  AddBringUpOptions(app, &o);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(o.level)) return *rc;
  auto config = LoadBringUpConfig(o);
  if (!config.ok()) return ReportError("shot", config.error());
  TestShotRequest request;
  request.exposure_s = exposure;
  request.lamp_on = !no_lamp;
  request.save = save;
  if (!at.empty()) {
    auto p = ParsePoseArgument(at, "--at");
    if (!p.ok()) return ReportError("shot", p.error());
    request.pose = *p;
  }
  auto devices = MakeDevices(*config);
  if (!devices.ok()) return ReportError("shot", devices.error());
  Camera& camera = *devices->camera;
  InstallStopHandlers();
  auto shot = TakeTestShot(*config, camera, *devices->lamp, *devices->motor, request);
  if (!shot.ok()) return StopRequested() ? 128 + StopSignal() : ReportError("shot", shot.error());
  const ExposureStats* stats = &shot->stats;
  const BracketAdvice& advice = shot->advice;
  const auto& img = *shot;
  const double t = shot->exposure_s;
  std::printf("%s: %dx%d at %.6g s%s\n", camera.Describe().c_str(), img.width, img.height, t,
              no_lamp ? " (lamp off)" : "");
  std::printf("brightest channel: 1%% %.0f, median %.0f, 99%% %.0f, 99.9%% %.0f\n", stats->p01, stats->p50,
              stats->p99, stats->p999);
  std::printf("histogram (brightest channel, 8 bins of 32):");
  for (double h : stats->histogram) std::printf(" %.1f%%", 100 * h);
  std::printf("\nclipped (a channel >= 250): %.2f%%   dark (<= 5): %.2f%%\n", 100 * stats->clipped_fraction,
              100 * stats->dark_fraction);
  std::printf("suggested bracket: %.6g s .. %.6g s, %d exposures 1 stop apart\n", advice.shortest_s,
              advice.longest_s, advice.count);
  std::printf("[bracket]\ncenter_s = %.6g\nev_step = %.1f\ncount = %d\n", advice.center_s, advice.ev_step,
              advice.count);
  const auto& on_body = shot->on_body;
  if (on_body.ok()) {
    std::printf("on this body:");
    for (Seconds s : *on_body) std::printf(" %.6g", s.count());
    std::printf(" s\n");
  } else {
    std::printf("on this body: %s\n", on_body.error().ToString().c_str());
  }
  if (!advice.note.empty()) std::printf("note: %s\n", advice.note.c_str());
  if (!save.empty()) std::printf("frame written to %s\n", save.c_str());
  return 0;
}

}  // namespace rig
