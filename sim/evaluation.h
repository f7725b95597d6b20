// The `rig evaluate` harness: speed against accuracy for every processing choice on the same
// data — every reflectance model (process/evaluate), every HDR method (ours and OpenCV's) —
// on a stored session or on freshly simulated ones, with tables, charts and a report. In sim/
// because it reads the simulator's truth, renders synthetic brackets and runs dry sessions.
#pragma once

#include <filesystem>
#include <functional>
#include <string>

#include "config/result.h"

namespace rig {

struct EvaluationRequest {
  // A session with radiance maps (its truth/ used when simulated); ignored with dry_run.
  std::filesystem::path session;
  // Simulate sessions instead (every scene; the configuration's [sim] at width x height)
  // under out/sessions/<scene>; sessions left by an interrupted evaluation are reused.
  bool dry_run = false;
  std::string config_path;  // empty: the built-in config/sim.toml (works from any folder)
  int width = 160, height = 120;
  // Real HDR images (.exr, .hdr) used as HDR truth (docs/data.md names public ones); empty:
  // none (the synthetic radiance image only); a folder that does not exist is a warning.
  std::filesystem::path hdr_images;
  bool quick = false;  // fewer scenes and HDR trials
  // Every fit, render and HDR merge timed this many times and the median kept, so that the
  // same machine draws the same charts whatever else it is running.
  int timing_runs = 3;
  // The report folder (created); refused (kInvalidInput) if it holds a report.md already.
  std::filesystem::path out;
  // Called at the start of each stage with one line ("evaluating HDR methods..."); may be null.
  std::function<void(const std::string& line)> progress;
};

struct EvaluationReport {
  std::string findings;         // Markdown bullet lines, also in the report
  std::filesystem::path report;  // out/report.md
};

// Writes methods.csv/.md, the charts (PNG), hdr_methods.csv and report.md into request.out.
Result<EvaluationReport> RunEvaluation(const EvaluationRequest& request);

}  // namespace rig
