// Console progress of a capture session: a bar with pose, frame, elapsed and remaining time
// on a terminal; a log line per pose otherwise.
#pragma once

#include <chrono>
#include <string>

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
  void Draw(const std::string& pose, int index_in_bracket, int bracket_size);
  int total_, done_, start_done_;
  bool tty_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace rig
