// One test frame at one exposure, as `rig shot` takes it: the arm moved to a pose (optional),
// the camera configured, the lamp on (unless asked not), one capture, the lamp off whatever
// happened; then the frame's histogram and the bracket the scene needs
// (process/hdr/exposure_advice.h).
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "capture/devices/camera.h"
#include "capture/devices/lamp.h"
#include "capture/devices/motor.h"
#include "capture/plan/pose.h"
#include "config/config.h"
#include "config/result.h"
#include "process/hdr/exposure_advice.h"
#include "process/hdr/focus.h"

namespace rig {

struct TestShotRequest {
  double exposure_s = 0;    // snapped to the body's nearest shutter speed
  std::optional<Pose> pose; // checked against the motor's soft limits before anything moves
  bool lamp_on = true;
  std::string save;         // write the frame's file here (refused if it exists); empty: no
};

struct TestShot {
  int width = 0, height = 0;
  double exposure_s = 0;             // as the body applied it
  ExposureStats stats;
  BracketAdvice advice;
  std::vector<Seconds> speeds;       // the body's shutter speeds
  Result<std::vector<Seconds>> on_body = std::vector<Seconds>{};  // the advice snapped to them
};

// Errors name the device (or the file, the pose); a stop request (Ctrl-C) ends the capture
// with the capture's error after the lamp is off (the caller checks StopRequested()).
Result<TestShot> TakeTestShot(const Config& config, Camera& camera, Lamp& lamp, Motor& motor,
                              const TestShotRequest& request);

// `rig shot --preview`: live-view frames for framing and focus (Camera::CapturePreview), at the
// body's own exposure, with the lamp on (unless asked not) for as long as they last.
struct PreviewRequest {
  std::optional<Pose> pose;  // checked against the motor's soft limits before anything moves
  bool lamp_on = true;
  std::string save;          // write the last preview here (refused if it exists); empty: no
  int count = 1;             // previews to take; 0: until a stop request (Ctrl-C)
  Seconds every{0.5};        // between the starts of two previews
};

struct Preview {
  int index = 0;             // from 1
  int width = 0, height = 0;
  FocusStats focus;
  double clipped_fraction = 0, dark_fraction = 0;  // as ExposureStats counts them
};

// Errors name the device, the file or the pose; the lamp is off again whatever happened. A
// stop request ends the previews without an error: the ones taken are returned (and the last
// saved). `on_preview` is called as each one arrives.
Result<std::vector<Preview>> TakePreviews(const Config& config, Camera& camera, Lamp& lamp, Motor& motor,
                                          const PreviewRequest& request,
                                          const std::function<void(const Preview&)>& on_preview = {});

}  // namespace rig
