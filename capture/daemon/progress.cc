// Progress bar.
#include "capture/daemon/progress.h"

#include <unistd.h>

#include <cstdio>

#include "config/log.h"

namespace rig {
namespace {

std::string Clock(double s) {
  if (s < 0 || s > 1e7) return "--:--";
  int t = static_cast<int>(s + 0.5);
  if (t >= 3600) return fmt::format("{}:{:02d}:{:02d}", t / 3600, t / 60 % 60, t % 60);
  return fmt::format("{:02d}:{:02d}", t / 60, t % 60);
}

}  // namespace

Progress::Progress(int total_frames, int done_frames)
    : total_(total_frames), done_(done_frames), start_done_(done_frames),
      tty_(isatty(STDERR_FILENO) != 0), start_(std::chrono::steady_clock::now()) {}

Progress::~Progress() { Finish(); }

void Progress::Frame(const std::string& pose, int index, int bracket_size) {
  ++done_;
  if (tty_) Draw(pose, index, bracket_size);
}

void Progress::PoseDone(const std::string& pose) {
  if (tty_) return;
  double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  int captured = done_ - start_done_;
  double remaining = captured > 0 ? elapsed / captured * (total_ - done_) : -1;
  Log("session")->info("pose={} done frames={}/{} elapsed={} remaining={}", pose, done_, total_,
                       Clock(elapsed), Clock(remaining));
}

void Progress::Draw(const std::string& pose, int index, int bracket_size) {
  double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  int captured = done_ - start_done_;
  double remaining = captured > 0 ? elapsed / captured * (total_ - done_) : -1;
  const int kWidth = 30;
  int filled = total_ > 0 ? kWidth * done_ / total_ : kWidth;
  std::string bar(static_cast<size_t>(filled), '#');
  bar.resize(kWidth, '.');
  std::fprintf(stderr, "\r[%s] %3d%%  pose %s  frame %d/%d  %d/%d  elapsed %s  left %s   ",
               bar.c_str(), total_ > 0 ? 100 * done_ / total_ : 100, pose.c_str(), index + 1,
               bracket_size, done_, total_, Clock(elapsed).c_str(), Clock(remaining).c_str());
  std::fflush(stderr);
  drawn_ = true;
}

void Progress::Finish() {
  if (drawn_) {
    std::fprintf(stderr, "\n");
    drawn_ = false;
  }
}

}  // namespace rig
