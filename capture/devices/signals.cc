// Signal handling: an async-signal-safe flag.
#include "capture/devices/signals.h"

#include <signal.h>

#include <atomic>
#include <chrono>
#include <thread>

namespace rig {
namespace {

std::atomic<int> g_stop_signal{0};
std::atomic<int> g_caught_signal{0};  // only the handler sets it

extern "C" void OnStopSignal(int sig) {
  int expected = 0;
  if (!g_caught_signal.compare_exchange_strong(expected, sig)) {
    // Second signal: give the user their default action back.
    signal(sig, SIG_DFL);
  }
  expected = 0;
  g_stop_signal.compare_exchange_strong(expected, sig);
}

}  // namespace

void InstallStopHandlers() {
  struct sigaction sa {};
  sa.sa_handler = OnStopSignal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: blocking calls return EINTR and notice the flag
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

int StopSignal() { return g_stop_signal.load(std::memory_order_relaxed); }
void RequestStop(int signal_number) { g_stop_signal.store(signal_number); }
void ClearStopForTesting() {
  g_stop_signal.store(0);
  g_caught_signal.store(0);
}
int CaughtSignal() { return g_caught_signal.load(); }
void ClearRequestedStop() {
  if (g_caught_signal.load() != 0) return;
  g_stop_signal.store(0);
  // A signal caught between the check and the store must not be lost.
  if (int sig = g_caught_signal.load(); sig != 0) g_stop_signal.store(sig);
}

bool SleepUnlessStopped(Seconds d) {
  auto end = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::nanoseconds>(d);
  while (std::chrono::steady_clock::now() < end) {
    if (StopRequested()) return false;
    auto left = end - std::chrono::steady_clock::now();
    std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(left, std::chrono::milliseconds(20)));
  }
  return !StopRequested();
}

}  // namespace rig
