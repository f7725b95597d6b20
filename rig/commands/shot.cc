// rig shot --exposure S: one frame at one exposure (lamp on), its histogram, clipped and dark
// fractions, and the bracket the scene needs; rig shot --preview: live-view frames for framing
// and focus, each with its sharpness (capture/session/test_shot.h).
#include <cstdio>

#include "capture/devices/signals.h"
#include "capture/session/test_shot.h"
#include "rig/backends.h"
#include "rig/commands/bringup.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

constexpr const char* kTileNames[9] = {"top left", "top",    "top right",    "left",  "centre",
                                       "right",    "bottom left", "bottom", "bottom right"};

void PrintPreview(const Preview& p) {
  std::printf("preview %d: %dx%d  focus %.1f (sharpest %s %.1f, centre %.1f)  clipped %.2f%%  dark %.2f%%\n",
              p.index, p.width, p.height, p.focus.whole, kTileNames[p.focus.sharpest_tile],
              p.focus.tiles[p.focus.sharpest_tile], p.focus.tiles[4], 100 * p.clipped_fraction,
              100 * p.dark_fraction);
  std::fflush(stdout);
}

int RunPreview(const Config& config, Devices& devices, const PreviewRequest& request) {
  InstallStopHandlers();
  std::printf("%s: live view%s; focus is the variance of the Laplacian of luminance (higher is "
              "sharper; compare previews of one scene)\n",
              devices.camera->Describe().c_str(), request.lamp_on ? "" : " (lamp off)");
  auto previews = TakePreviews(config, *devices.camera, *devices.lamp, *devices.motor, request, PrintPreview);
  if (!previews.ok()) return ReportError("shot", previews.error());
  if (!request.save.empty() && !previews->empty())
    std::printf("last preview written to %s\n", request.save.c_str());
  return StopRequested() ? 128 + StopSignal() : 0;
}

}  // namespace

int RunShot(int argc, char** argv) {
  CLI::App app{"Capture one frame at one exposure with the lamp on (optionally at a pose) and "
               "print its histogram, the clipped and dark fractions, and a bracket for the "
               "scene: the brightest 0.1% of pixels at value 200 in the shortest exposure, the "
               "darkest 1% at 128 in the longest (values taken as sRGB-like), 1-stop steps, "
               "snapped to the body's shutter speeds (docs/rig-setup.md). With --preview: "
               "live-view frames at the body's own exposure for framing and focus, each with "
               "its sharpness.",
               "rig shot"};
  BringUpOptions o;
  double exposure = 0;
  std::string at, save;
  bool no_lamp = false, preview = false;
  int repeat = 1;
  double every_s = 0.5;
  auto* exposure_opt =
      app.add_option("--exposure", exposure, "exposure time in seconds (snapped to the body's nearest)")
          ->check(CLI::PositiveNumber);
  auto* preview_opt =
      app.add_flag("--preview", preview,
                   "live view instead (libgphoto2's preview capture): framing and focus, not stored")
          ->excludes(exposure_opt);
  app.add_option("--repeat", repeat, "with --preview: previews to take, 0 until Ctrl-C")
      ->check(CLI::NonNegativeNumber)->needs(preview_opt);
  app.add_option("--every", every_s, "with --preview: seconds between previews")
      ->check(CLI::PositiveNumber)->needs(preview_opt);
  app.add_option("--at", at, "move the arm to this pose H,V first");
  app.add_option("--save", save, "write the frame to this file (refused if it exists)");
  app.add_flag("--no-lamp", no_lamp, "leave the lamp off (ambient light only)");
  AddBringUpOptions(app, &o);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(o.level)) return *rc;
  if (!preview && exposure <= 0) {
    std::fprintf(stderr, "rig shot: --exposure S or --preview is required (rig shot --help)\n");
    return 2;
  }
  auto config = LoadBringUpConfig(o);
  if (!config.ok()) return ReportError("shot", config.error());
  std::optional<Pose> pose;
  if (!at.empty()) {
    auto p = ParsePoseArgument(at, "--at");
    if (!p.ok()) return ReportError("shot", p.error());
    pose = *p;
  }
  if (preview) {
    auto devices = MakeDevices(*config);
    if (!devices.ok()) return ReportError("shot", devices.error());
    return RunPreview(*config, *devices,
                      PreviewRequest{pose, !no_lamp, save, repeat, Seconds(every_s)});
  }
  TestShotRequest request;
  request.exposure_s = exposure;
  request.lamp_on = !no_lamp;
  request.save = save;
  request.pose = pose;
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
