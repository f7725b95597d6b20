// rig shot --exposure S: one frame at one exposure (lamp on), its histogram, clipped and dark
// fractions, and the bracket the scene needs (process/hdr/exposure_advice.h).
#include <cstdio>

#include <opencv2/imgcodecs.hpp>

#include "capture/devices/signals.h"
#include "capture/plan/bracket.h"
#include "capture/session/session_store.h"
#include "process/hdr/exposure_advice.h"
#include "rig/backends.h"
#include "rig/commands/bringup.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

bool Decodable(const std::string& ext) { return ext == "jpg" || ext == "jpeg" || ext == "png" || ext == "tif"; }

}  // namespace

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
  if (!save.empty() && fs::exists(save))
    return ReportError("shot", MakeError(ErrorCode::kInvalidInput, save, "exists; nothing is overwritten"));
  std::optional<Pose> pose;
  if (!at.empty()) {
    auto p = ParsePoseArgument(at, "--at");
    if (!p.ok()) return ReportError("shot", p.error());
    if (const std::string why = SoftLimitViolation(config->motor, *p); !why.empty())
      return ReportError("shot", MakeError(ErrorCode::kInvalidInput, "--at " + at, "{}", why));
    pose = *p;
  }
  auto devices = MakeDevices(*config);
  if (!devices.ok()) return ReportError("shot", devices.error());
  Camera& camera = *devices->camera;
  Lamp& lamp = *devices->lamp;
  Motor& motor = *devices->motor;
  InstallStopHandlers();
  if (pose) {
    Status st = motor.Open();
    if (st.ok()) st = motor.MoveTo(*pose);
    motor.Close();
    if (!st.ok()) return ReportError("shot", st.error().Within(motor.Describe()));
  }
  Status st = camera.Open();
  if (!st.ok()) return ReportError("shot", st.error().Within(camera.Describe()));
  const CameraConfig& cc = config->camera;
  auto applied = camera.Configure({cc.iso, cc.aperture, cc.white_balance, cc.capture_target, false});
  if (!applied.ok()) return ReportError("shot", applied.error().Within(camera.Describe()));
  auto speeds = camera.ShutterSpeeds();
  if (!speeds.ok()) return ReportError("shot", speeds.error().Within(camera.Describe()));
  auto snapped = SnapToShutterSpeeds({Seconds(exposure)}, *speeds);
  if (!snapped.ok()) return ReportError("shot", snapped.error().Within(camera.Describe()));
  st = lamp.Open();
  if (!st.ok()) return ReportError("shot", st.error().Within(lamp.Describe()));
  if (!no_lamp) st = lamp.On();
  Result<CapturedFrame> frame = st.ok() ? camera.Capture((*snapped)[0]) : Result<CapturedFrame>(st.error());
  Status off = lamp.Off();  // the lamp is left off whatever happened
  lamp.Close();
  camera.Close();
  if (!frame.ok()) return StopRequested() ? 128 + StopSignal() : ReportError("shot", frame.error().Within(camera.Describe()));
  if (!off.ok()) return ReportError("shot", off.error().Within(lamp.Describe()));

  const CapturedFile* image = nullptr;
  for (const auto& f : frame->files)
    if (Decodable(f.extension)) image = &f;
  if (image == nullptr)
    return ReportError("shot", MakeError(ErrorCode::kUnsupported, camera.Describe(),
                                         "the frame has no JPEG/PNG/TIFF file to analyse (set camera.capture_raw = false)"));
  if (!save.empty()) {
    Status w = WriteFileAtomic(save, std::span<const uint8_t>(image->bytes), /*overwrite=*/false);
    if (!w.ok()) return ReportError("shot", w.error());
  }
  cv::Mat img = cv::imdecode(image->bytes, cv::IMREAD_COLOR | cv::IMREAD_ANYDEPTH);
  const double t = frame->exposure.count();
  auto stats = AnalyzeExposure(img, t);
  if (!stats.ok()) return ReportError("shot", stats.error().Within(camera.Describe()));
  const BracketAdvice advice = SuggestBracket(*stats);
  std::printf("%s: %dx%d at %.6g s%s\n", camera.Describe().c_str(), img.cols, img.rows, t,
              no_lamp ? " (lamp off)" : "");
  std::printf("brightest channel: 1%% %.0f, median %.0f, 99%% %.0f, 99.9%% %.0f\n", stats->p01, stats->p50,
              stats->p99, stats->p999);
  std::printf("histogram (brightest channel, 8 bins of 32):");
  for (double h : stats->histogram) std::printf(" %.1f%%", 100 * h);
  std::printf("\nclipped (a channel >= 250): %.2f%%   dark (<= 5): %.2f%%\n", 100 * stats->clipped_fraction,
              100 * stats->dark_fraction);
  BracketConfig suggested;
  suggested.center_s = advice.center_s;
  suggested.ev_step = advice.ev_step;
  suggested.count = advice.count;
  std::printf("suggested bracket: %.6g s .. %.6g s, %d exposures 1 stop apart\n", advice.shortest_s,
              advice.longest_s, advice.count);
  std::printf("[bracket]\ncenter_s = %.6g\nev_step = %.1f\ncount = %d\n", advice.center_s, advice.ev_step,
              advice.count);
  auto on_body = SnapToShutterSpeeds(WantedExposures(suggested), *speeds);
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
