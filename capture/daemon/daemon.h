// The capture daemon: home, then for every pose move → settle → lamp on → bracket → lamp
// off; every frame stored and journaled before the next step; finished brackets handed to
// the processor while the rig moves on. Also continues an interrupted session (resume).
#pragma once

#include <string>

#include "capture/devices/camera.h"
#include "capture/devices/lamp.h"
#include "capture/devices/motor.h"
#include "capture/daemon/processor.h"
#include "capture/session/session_store.h"

namespace rig {

struct CaptureOptions {
  // Scales settle time (the simulator's latency_scale in a dry run; 1 on real hardware).
  double settle_scale = 1.0;
  bool process = true;   // hand brackets to the HDR processor
  bool progress = true;  // progress bar / per-pose log lines
};

struct CaptureSummary {
  int poses = 0, frames = 0;             // planned
  int frames_captured = 0;               // in this run
  int frames_verified = 0;               // already stored and verified (resume)
  int frames_redone = 0;                 // stored but damaged or unjournaled: moved aside, redone
  int retries = 0;
  int faults = 0;
  double total_s = 0, motion_s = 0, settle_s = 0, lamp_s = 0, camera_s = 0, exposure_s = 0,
         storage_s = 0, queue_wait_s = 0, processing_tail_s = 0;
  ProcessingSummary processing;
  // Printable multi-line summary.
  std::string ToString() const;
};

class CaptureDaemon {
 public:
  CaptureDaemon(Session& session, Camera& camera, Motor& motor, Lamp& lamp,
                CaptureOptions options = {});

  // Runs or continues the session. On SIGINT/SIGTERM: finishes the frame in hand, lamp off,
  // motor stopped, journal synced; returns kInterrupted. When retries cannot clear a device
  // fault: the same parking, a "fault" journal record, and kFault naming device and pose.
  // `summary` is filled in either way.
  Status Run(CaptureSummary* summary);

 private:
  Session& session_;
  Camera& camera_;
  Motor& motor_;
  Lamp& lamp_;
  CaptureOptions options_;
};

}  // namespace rig
