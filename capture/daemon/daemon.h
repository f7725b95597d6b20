// The capture daemon: home, then for every pose move → settle → lamp on → bracket → lamp
// off; every frame stored and journaled before the next step; finished brackets handed to
// the processor while the rig moves on. Also continues an interrupted session (resume).
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "capture/devices/camera.h"
#include "capture/devices/lamp.h"
#include "capture/devices/motor.h"
#include "capture/daemon/processor.h"
#include "capture/plan/pose.h"
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
  // open_s: opening camera, motor and lamp, a controller's start-up (an Arduino's reset
  // and banner after the port opens) included: the devices' time, not the rig's.
  double total_s = 0, open_s = 0, motion_s = 0, settle_s = 0, lamp_s = 0, camera_s = 0, exposure_s = 0,
         storage_s = 0, queue_wait_s = 0, processing_tail_s = 0;
  ProcessingSummary processing;
  bool processing_collected = false;     // `processing` holds the processor's final count
  std::string storage_error;             // a frame that could not be stored (a full disk)
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

  // The radiance maps of the session kept in memory as they were merged (and, on a resume,
  // read from the maps merged before), for fitting the model at the last frame without
  // reading them back; null when nothing was processed. Valid after Run().
  std::shared_ptr<const MapStore> map_store() const { return store_; }

 private:
  // One run's state (defined in daemon.cc): what is stored, the plan, which devices are
  // open, the pose in hand, the processor and the progress bar.
  struct RunState;
  // The images just captured at the pose in hand: bracket index -> (file, bytes as captured).
  using FreshImages = std::map<int, std::pair<fs::path, std::vector<uint8_t>>>;

  // The protocol's steps, in the order Run() takes them.
  Status VerifyStored(RunState& run);
  Status OpenDevices(RunState& run);
  Status Plan(RunState& run);
  void StartProcessing(RunState& run);
  Status Home(RunState& run);
  Status VisitPose(RunState& run, const Pose& pose);
  Status Finish(RunState& run);
  Status VisitAdaptiveGrid(RunState& run);

  // Parts of the steps.
  void ReadJournal(RunState& run);
  Status VerifyIndex(RunState& run, const std::string& pose, int index,
                     std::set<fs::path>& known_files);
  Status MoveAsideUnjournaled(RunState& run, const std::set<fs::path>& known_files);
  Status CheckPlan(RunState& run, const std::vector<std::string>& pose_names);
  Status CheckStoredAgainstPlans(RunState& run);
  Status MeterAndPlan(RunState& run, const Pose& pose, FreshImages& fresh);
  Status MoveTo(RunState& run, const Pose& pose);
  Status Settle(RunState& run);
  Status LampOn(RunState& run);
  Status LampOff(RunState& run);
  Status CaptureFrame(RunState& run, const Pose& pose, int index, double exposure_s,
                      FreshImages& fresh);
  Status StoreFiles(RunState& run, const Pose& pose, int index, double exposure_s,
                    CapturedFrame& frame, FreshImages& fresh);
  void HandOff(RunState& run, const Pose& pose, FreshImages& fresh);
  void Submit(RunState& run, BracketJob job);
  std::vector<int> WorkingIndices(const RunState& run) const;
  Result<cv::Mat> WorkingFrame(RunState& run, const Pose& pose);

  // Leaving safely, and retrying.
  void Park(RunState& run);
  Status Fault(RunState& run, const Error& e, const std::string& device);
  Status Interrupted(RunState& run);
  Status WithRetries(RunState& run, int retries, double backoff_s,
                     const std::function<Status()>& op, const std::function<void()>& recover);

  Session& session_;
  Camera& camera_;
  Motor& motor_;
  Lamp& lamp_;
  CaptureOptions options_;
  std::shared_ptr<MapStore> store_;
};

}  // namespace rig
