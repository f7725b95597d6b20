// The status line: one bar at a time on stderr, erased around every console line.
#include "config/console.h"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <vector>

#include <fmt/format.h>

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

struct Task {
  int id = 0;
  std::string label, detail;
  int64_t total = 0, done = 0, done_at_start = 0;
  Clock::time_point start;
};

struct Console {
  std::recursive_mutex mu;
  bool enabled = false;
  bool tty = isatty(STDERR_FILENO) != 0;
  bool drawn = false;  // a bar is on the screen now
  Clock::time_point last_draw{};
  std::vector<Task> tasks;  // innermost last
  int next_id = 1;
};

Console& C() {
  static Console* c = new Console;  // never destroyed: tasks may end during static teardown
  return *c;
}

int Columns() {
  winsize ws{};
  if (ioctl(STDERR_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col >= 20) return ws.ws_col;
  return 100;
}

// A task's time so far, its time left (-1 unknown: from the rate of the work done in this run)
// and its percentage.
struct Timing {
  double elapsed = 0, left = -1;
  int pct = 0;
};
Timing TimingOf(const Task& t) {
  Timing m;
  m.elapsed = std::chrono::duration<double>(Clock::now() - t.start).count();
  const int64_t counted = t.done - t.done_at_start;
  if (counted > 0 && t.total > 0)
    m.left = m.elapsed / static_cast<double>(counted) *
             static_cast<double>(std::max<int64_t>(0, t.total - t.done));
  m.pct = t.total > 0 ? static_cast<int>(100 * std::min(t.done, t.total) / t.total) : 0;
  return m;
}

std::string Render(const Task& t) {
  const Timing m = TimingOf(t);
  const double elapsed = m.elapsed, eta = m.left;
  const int pct = m.pct;
  const int kWidth = 24;
  const int64_t filled = t.total > 0 ? kWidth * std::min(t.done, t.total) / t.total : 0;
  std::string bar(static_cast<size_t>(filled), '#');
  bar.resize(kWidth, '.');
  std::string line = fmt::format("{} [{}] {:3d}% {}/{}", t.label, bar, pct, t.done, t.total);
  if (!t.detail.empty()) line += "  " + t.detail;
  line += fmt::format("  elapsed {}  ETA {}", console_internal::Clock(elapsed),
                      console_internal::Clock(eta));
  return line;
}

// With C().mu held.
void EraseLocked() {
  Console& c = C();
  if (!c.drawn) return;
  std::fputs("\r\033[K", stderr);
  c.drawn = false;
}

// Off a terminal (a pipe, a log file under Snakemake, cron, nohup): one plain line every few
// seconds ($RIG_PROGRESS_EVERY_S, default 5) for the innermost task, once it has run that long.
double LineEverySeconds() {
  static const double every = [] {
    const char* env = std::getenv("RIG_PROGRESS_EVERY_S");
    char* end = nullptr;
    const double v = env ? std::strtod(env, &end) : 0;
    return env && end != env && v > 0 && v < 1e6 ? v : 5.0;
  }();
  return every;
}

std::string PlainLine(const Task& t) {
  const Timing m = TimingOf(t);
  std::string line = fmt::format("progress: {} {}/{} ({}%)", t.label, t.done, t.total, m.pct);
  if (!t.detail.empty()) line += ", " + t.detail;
  return line + fmt::format(", {} elapsed, {} left", console_internal::Clock(m.elapsed),
                            console_internal::Clock(m.left));
}

void PlainLineLocked() {
  Console& c = C();
  const Task& t = c.tasks.back();
  const auto now = Clock::now();
  const auto every = std::chrono::duration<double>(LineEverySeconds());
  if (now - t.start < every || now - c.last_draw < every) return;
  std::fprintf(stderr, "%s\n", PlainLine(t).c_str());
  std::fflush(stderr);
  c.last_draw = now;
}

void DrawLocked(bool force) {
  Console& c = C();
  if (!c.enabled || c.tasks.empty()) return;
  if (!c.tty) return PlainLineLocked();
  auto now = Clock::now();
  if (!force && c.drawn && now - c.last_draw < std::chrono::milliseconds(100)) return;
  std::string line = Render(c.tasks.back());
  // Never wider than the terminal: a wrapped bar could not be erased with "\r".
  const size_t cols = static_cast<size_t>(Columns() - 1);
  if (line.size() > cols) line.resize(cols);
  std::fputs("\r\033[K", stderr);
  std::fputs(line.c_str(), stderr);
  std::fflush(stderr);
  c.drawn = true;
  c.last_draw = now;
}

Task* Find(int id) {
  for (auto& t : C().tasks)
    if (t.id == id) return &t;
  return nullptr;
}

}  // namespace

void EnableProgress(bool on) {
  Console& c = C();
  std::lock_guard lock(c.mu);
  if (!on) EraseLocked();
  c.enabled = on;
}

bool ProgressShown() {
  Console& c = C();
  std::lock_guard lock(c.mu);
  return c.enabled && c.tty;
}

ProgressTask::ProgressTask(std::string label, int64_t total, int64_t done) {
  Console& c = C();
  std::lock_guard lock(c.mu);
  id_ = c.next_id++;
  c.tasks.push_back({id_, std::move(label), "", total, done, done, Clock::now()});
  DrawLocked(true);
}

ProgressTask::~ProgressTask() {
  Console& c = C();
  std::lock_guard lock(c.mu);
  std::erase_if(c.tasks, [&](const Task& t) { return t.id == id_; });
  EraseLocked();
  if (!c.tasks.empty()) DrawLocked(true);
}

void ProgressTask::Advance(int64_t n, const std::string& detail) {
  Console& c = C();
  std::lock_guard lock(c.mu);
  Task* t = Find(id_);
  if (!t) return;
  t->done += n;
  if (!detail.empty()) t->detail = detail;
  DrawLocked(t->done >= t->total);
}

void ProgressTask::Set(int64_t done, const std::string& detail) {
  Console& c = C();
  std::lock_guard lock(c.mu);
  Task* t = Find(id_);
  if (!t) return;
  t->done = done;
  if (!detail.empty()) t->detail = detail;
  DrawLocked(t->done >= t->total);
}

std::string ProgressTask::Line() const {
  Console& c = C();
  std::lock_guard lock(c.mu);
  const Task* t = Find(id_);
  return t ? Render(*t) : "";
}

void ConsoleLine(std::FILE* stream, const std::string& line) {
  console_internal::WithBarErased([&] {
    std::fputs(line.c_str(), stream);
    std::fputc('\n', stream);
    std::fflush(stream);
  });
}

namespace console_internal {

void WithBarErased(const std::function<void()>& write) {
  Console& c = C();
  std::lock_guard lock(c.mu);
  const bool was_drawn = c.drawn;
  if (was_drawn) {
    // What stdout holds must reach the terminal before the bar is erased and redrawn.
    std::fflush(stdout);
    EraseLocked();
  }
  write();
  if (was_drawn) DrawLocked(true);
}

std::string Clock(double s) {
  if (s < 0 || s > 1e7) return "--:--";
  int t = static_cast<int>(s + 0.5);
  if (t >= 3600) return fmt::format("{}:{:02d}:{:02d}", t / 3600, t / 60 % 60, t % 60);
  return fmt::format("{:02d}:{:02d}", t / 60, t % 60);
}

}  // namespace console_internal
}  // namespace rig
