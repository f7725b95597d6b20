#include "capture/session/test_shot.h"

#include <opencv2/imgcodecs.hpp>

#include "capture/devices/signals.h"
#include "capture/plan/bracket.h"
#include "capture/session/session_store.h"

namespace rig {
namespace {

bool Decodable(const std::string& ext) {
  return ext == "jpg" || ext == "jpeg" || ext == "png" || ext == "tif";
}

Status MoveArm(Motor& motor, const Pose& pose) {
  Status st = motor.Open();
  if (st.ok()) st = motor.MoveTo(pose);
  motor.Close();
  if (!st.ok()) return st.error().Within(motor.Describe());
  return Ok();
}

// The camera opened and configured; its shutter speeds.
Result<std::vector<Seconds>> PrepareCamera(const CameraConfig& cc, Camera& camera) {
  RIG_TRY(camera.Open());
  auto applied = camera.Configure({cc.iso, cc.aperture, cc.white_balance, cc.capture_target, false});
  if (!applied.ok()) return applied.error();
  return camera.ShutterSpeeds();
}

// One capture with the lamp on (or left off); the lamp is off again whatever happened.
Result<CapturedFrame> CaptureLit(Camera& camera, Lamp& lamp, Seconds exposure, bool lamp_on) {
  Status st = lamp.Open();
  if (!st.ok()) return st.error().Within(lamp.Describe());
  if (lamp_on) st = lamp.On();
  Result<CapturedFrame> frame =
      st.ok() ? camera.Capture(exposure) : Result<CapturedFrame>(st.error().Within(lamp.Describe()));
  Status off = lamp.Off();
  lamp.Close();
  if (!frame.ok()) return frame.error().Within(camera.Describe());
  if (!off.ok()) return off.error().Within(lamp.Describe());
  return frame;
}

// The previews with the camera open and the lamp lit; the last preview's file in `last`.
Result<std::vector<Preview>> PreviewLoop(Camera& camera, const PreviewRequest& request,
                                         const std::function<void(const Preview&)>& on_preview,
                                         CapturedFile* last) {
  std::vector<Preview> out;
  auto next = std::chrono::steady_clock::now();
  for (int i = 1; request.count == 0 || i <= request.count; ++i) {
    if (i > 1) {
      next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(request.every);
      const auto wait = next - std::chrono::steady_clock::now();
      if (wait > wait.zero() && !SleepUnlessStopped(std::chrono::duration_cast<Seconds>(wait))) break;
    }
    if (StopRequested()) break;
    RIG_ASSIGN_OR_RETURN(*last, camera.CapturePreview());
    cv::Mat img = cv::imdecode(last->bytes, cv::IMREAD_COLOR);
    if (img.empty())
      return MakeError(ErrorCode::kDevice, camera.Describe(), "preview {} ({} bytes, .{}) cannot be decoded", i,
                       last->bytes.size(), last->extension);
    Preview p;
    p.index = i;
    p.width = img.cols;
    p.height = img.rows;
    RIG_ASSIGN_OR_RETURN(p.focus, AnalyzeFocus(img));
    // The body chose the exposure: only the fractions of the statistics are used.
    RIG_ASSIGN_OR_RETURN(ExposureStats stats, AnalyzeExposure(img, 1.0));
    p.clipped_fraction = stats.clipped_fraction;
    p.dark_fraction = stats.dark_fraction;
    out.push_back(p);
    if (on_preview) on_preview(p);
  }
  return out;
}

}  // namespace

Result<std::vector<Preview>> TakePreviews(const Config& config, Camera& camera, Lamp& lamp, Motor& motor,
                                          const PreviewRequest& request,
                                          const std::function<void(const Preview&)>& on_preview) {
  if (!request.save.empty() && fs::exists(request.save))
    return MakeError(ErrorCode::kInvalidInput, request.save, "exists; nothing is overwritten");
  if (request.count < 0) return MakeError(ErrorCode::kInvalidInput, "preview", "count must be >= 0");
  if (request.pose) {
    if (const std::string why = SoftLimitViolation(config.motor, *request.pose); !why.empty())
      return MakeError(ErrorCode::kInvalidInput, "pose " + request.pose->Name(), "{}", why);
    RIG_TRY(MoveArm(motor, *request.pose));
  }
  const CameraConfig& cc = config.camera;
  Status st = camera.Open();
  if (st.ok()) {
    auto applied = camera.Configure({cc.iso, cc.aperture, cc.white_balance, cc.capture_target, false});
    if (!applied.ok()) st = applied.error();
  }
  if (!st.ok()) {
    camera.Close();
    return st.error().Within(camera.Describe());
  }
  Status lit = lamp.Open();
  if (!lit.ok()) {
    camera.Close();
    return lit.error().Within(lamp.Describe());
  }
  if (request.lamp_on) lit = lamp.On();
  CapturedFile last;
  Result<std::vector<Preview>> previews =
      lit.ok() ? PreviewLoop(camera, request, on_preview, &last)
               : Result<std::vector<Preview>>(lit.error().Within(lamp.Describe()));
  Status off = lamp.Off();
  lamp.Close();
  camera.Close();
  if (!previews.ok()) return previews.error();
  if (!off.ok()) return off.error().Within(lamp.Describe());
  if (!request.save.empty() && !previews->empty())
    RIG_TRY(WriteFileAtomic(request.save, std::span<const uint8_t>(last.bytes), /*overwrite=*/false));
  return previews;
}

Result<TestShot> TakeTestShot(const Config& config, Camera& camera, Lamp& lamp, Motor& motor,
                              const TestShotRequest& request) {
  if (!request.save.empty() && fs::exists(request.save))
    return MakeError(ErrorCode::kInvalidInput, request.save, "exists; nothing is overwritten");
  if (request.pose) {
    if (const std::string why = SoftLimitViolation(config.motor, *request.pose); !why.empty())
      return MakeError(ErrorCode::kInvalidInput, "pose " + request.pose->Name(), "{}", why);
    RIG_TRY(MoveArm(motor, *request.pose));
  }
  TestShot shot;
  auto speeds = PrepareCamera(config.camera, camera);
  auto snapped = speeds.ok() ? SnapToShutterSpeeds({Seconds(request.exposure_s)}, *speeds)
                             : Result<std::vector<Seconds>>(speeds.error());
  auto frame = snapped.ok() ? CaptureLit(camera, lamp, (*snapped)[0], request.lamp_on)
                            : Result<CapturedFrame>(snapped.error().Within(camera.Describe()));
  camera.Close();
  if (!frame.ok()) return frame.error();
  shot.speeds = *speeds;

  const CapturedFile* image = nullptr;
  for (const auto& f : frame->files)
    if (Decodable(f.extension)) image = &f;
  if (image == nullptr)
    return MakeError(ErrorCode::kUnsupported, camera.Describe(),
                     "the frame has no JPEG/PNG/TIFF file to analyse (set camera.capture_raw = false)");
  if (!request.save.empty()) {
    RIG_TRY(WriteFileAtomic(request.save, std::span<const uint8_t>(image->bytes), /*overwrite=*/false));
  }
  cv::Mat img = cv::imdecode(image->bytes, cv::IMREAD_COLOR | cv::IMREAD_ANYDEPTH);
  shot.width = img.cols;
  shot.height = img.rows;
  shot.exposure_s = frame->exposure.count();
  auto stats = AnalyzeExposure(img, shot.exposure_s);
  if (!stats.ok()) return stats.error().Within(camera.Describe());
  shot.stats = *stats;
  shot.advice = SuggestBracket(*stats);
  BracketConfig suggested;
  suggested.center_s = shot.advice.center_s;
  suggested.ev_step = shot.advice.ev_step;
  suggested.count = shot.advice.count;
  shot.on_body = SnapToShutterSpeeds(WantedExposures(suggested), shot.speeds);
  return shot;
}

}  // namespace rig
