// The capture's progress: a bar through config/console.h on a terminal, a log line per pose
// otherwise.
#include "capture/daemon/progress.h"

#include "config/log.h"

namespace rig {

Progress::Progress(int total_frames, int done_frames)
    : total_(total_frames), done_(done_frames), start_done_(done_frames),
      tty_(ProgressShown()), start_(std::chrono::steady_clock::now()) {
  if (tty_ && total_ > 0) task_.emplace("capture", total_, done_);
}

Progress::~Progress() { Finish(); }

void Progress::Frame(const std::string& pose, int index, int bracket_size) {
  ++done_;
  if (task_) task_->Set(done_, fmt::format("pose {} frame {}/{}", pose, index + 1, bracket_size));
}

void Progress::PoseDone(const std::string& pose) {
  if (tty_) return;
  double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  int captured = done_ - start_done_;
  double remaining = captured > 0 ? elapsed / captured * (total_ - done_) : -1;
  Log("session")->info("pose={} done frames={}/{} elapsed={} remaining={}", pose, done_, total_,
                       console_internal::Clock(elapsed), console_internal::Clock(remaining));
}

void Progress::Finish() { task_.reset(); }

}  // namespace rig
