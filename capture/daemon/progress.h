// Console progress of a capture session: a bar with pose, frame, elapsed time and ETA on a
// terminal (config/console.h: log lines never tear it); a log line per pose otherwise.
#pragma once

#include <chrono>
#include <optional>
#include <string>

#include "config/console.h"

namespace rig {

class Progress {
 public:
  // `total_frames` in the session, `done_frames` already stored (resume).
  Progress(int total_frames, int done_frames);
  ~Progress();
  void Frame(const std::string& pose, int index_in_bracket, int bracket_size);
  void PoseDone(const std::string& pose);
  void Finish();

 private:
  int total_, done_, start_done_;
  bool tty_;
  std::chrono::steady_clock::time_point start_;
  std::optional<ProgressTask> task_;
};

}  // namespace rig
