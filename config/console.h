// The console's status line: progress bars with an ETA that log lines never tear.
//
// A bar is one line on stderr, redrawn in place ("\r", erase to the end of the line). Every
// console log line (config/log.cc's sink) and every ConsoleLine() first erases the bar, writes
// its line, and draws the bar again below it. Nothing is drawn unless progress is enabled for
// the process (the command decides) and stderr is a terminal: piped output carries no escape
// codes. Off a terminal (a pipe, a log under Snakemake, cron or nohup) the same progress is a
// plain line every few seconds instead ("progress: radiance maps 12/40 (30%), 00:12 elapsed,
// 00:25 left"; $RIG_PROGRESS_EVERY_S, default 5), once a task has run that long. Library code
// counts its work with a ProgressTask and never knows how it is shown.
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>

namespace rig {

// Turns drawing on or off for this process (off by default; commands turn it on unless
// --no-progress). Drawing also needs stderr to be a terminal.
void EnableProgress(bool on);
// Whether bars are drawn now (enabled and stderr is a terminal).
bool ProgressShown();

// One long step, `total` units of work, `done` of them already done (they do not count for
// the rate the ETA is computed from). Tasks nest: the innermost one is shown, its outer one
// again when it ends. Thread-safe; the destructor removes it from the screen.
class ProgressTask {
 public:
  ProgressTask(std::string label, int64_t total, int64_t done = 0);
  ~ProgressTask();
  ProgressTask(const ProgressTask&) = delete;
  ProgressTask& operator=(const ProgressTask&) = delete;

  void Advance(int64_t n = 1, const std::string& detail = "");
  void Set(int64_t done, const std::string& detail = "");
  // The line as it would be drawn now (for tests and for a non-terminal caller's own use).
  std::string Line() const;

 private:
  int id_;
};

// Writes `line` and a newline to `stream` (stdout or stderr) under the bar, without tearing it.
void ConsoleLine(std::FILE* stream, const std::string& line);

namespace console_internal {
// For the console log sink: runs `write` with the bar erased, then draws it again.
void WithBarErased(const std::function<void()>& write);
// "00:42", "1:02:03"; "--:--" for unknown (negative) times.
std::string Clock(double seconds);
}  // namespace console_internal

}  // namespace rig
