// Running a session end to end: devices, ground truth, capture daemon, model, summary.
#include "rig/commands/session_run.h"

#include <chrono>
#include <cstdio>

#include "config/console.h"
#include "config/log.h"
#include "rig/backends.h"
#include "rig/commands/command.h"
#include "capture/daemon/daemon.h"
#include "capture/devices/signals.h"
#include "capture/daemon/session_model.h"

namespace rig {

int RunSession(Session& session, bool resuming, bool process, bool progress) {
  auto log = Log("session");
  const Config& config = session.config();
  auto devices = MakeDevices(config);
  if (!devices.ok()) return ReportError(resuming ? "resume" : "capture", devices.error());
  const SessionLayout& layout = session.layout();
  if (devices->write_truth && !fs::exists(layout.truth() / "scene.json")) {
    Status st = devices->write_truth(layout.truth(), PlanGrid(config.grid));
    if (!st.ok()) return ReportError("capture", st.error().Within("truth"));
  }
  EnableProgress(progress);
  CaptureOptions options;
  options.settle_scale = devices->settle_scale;
  options.process = process;
  options.progress = progress;
  CaptureDaemon daemon(session, *devices->camera, *devices->motor, *devices->lamp, options);
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  const auto t_last = std::chrono::steady_clock::now();
  std::printf("%s\n", summary.ToString().c_str());
  if (!st.ok()) {
    // A first run that stored nothing (no camera found, a wrong port) leaves no session
    // behind: `rig capture` can simply run again with the right configuration.
    if (!resuming && summary.frames_captured == 0 && session.RemoveIfNothingStored()) {
      if (st.error().code == ErrorCode::kInterrupted) return 128 + StopSignal();
      ReportError("capture", st.error());
      std::fprintf(stderr, "rig: nothing was captured; the session folder %s was removed\n",
                   layout.root.string().c_str());
      return st.error().code == ErrorCode::kInvalidInput ? 2 : 1;
    }
    if (st.error().code == ErrorCode::kInterrupted) return 128 + StopSignal();
    ReportError(resuming ? "resume" : "capture", st.error());
    std::fprintf(stderr, "rig: nothing captured is lost; fix the device and run 'rig resume %s'\n",
                 layout.root.string().c_str());
    return st.error().code == ErrorCode::kInvalidInput ? 2 : 1;
  }
  int rc = summary.processing.failed.empty() ? 0 : 1;
  if (process && rc == 0) {
    Status fit = FitSessionModel(session, daemon.map_store().get());
    if (fit.ok()) {
      Log("session")->info("model written {:.2f} s after the capture's end (the processing tail "
                           "included: {:.2f} s)",
                           std::chrono::duration<double>(std::chrono::steady_clock::now() - t_last).count(),
                           summary.processing_tail_s);
    }
    if (!fit.ok()) {
      ReportError("process", fit.error());
      rc = 1;
    }
  }
  std::printf("session %s: %s\n", layout.root.string().c_str(), rc == 0 ? "complete" : "captured; processing failed");
  return rc;
}

}  // namespace rig
