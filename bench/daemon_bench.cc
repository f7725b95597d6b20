// The capture daemon's own share of a session's time. Runs whole dry-run sessions in this
// process with every simulated device latency scaled to zero (so the devices take only the
// time the simulator needs to render and encode a frame) and prints, per frame and per pose,
// where the time goes: the simulator's rendering (what a real camera does for us), storage
// (write + fsync of the frame, journal record + fdatasync) and everything else the daemon
// does (planning, bookkeeping, progress). Two peers in the same run for scale: the bare cost
// of writing the same bytes to a file with fsync, and the sim camera's own rendering time.
//
//   build/bench/daemon_bench [--width 320 --height 240 --count 7 --runs 3]
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include "config/config.h"
#include "config/log.h"
#include "rig/backends.h"
#include "capture/daemon/daemon.h"
#include "capture/session/session_store.h"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

struct Args {
  int width = 320, height = 240, count = 7, runs = 3;
};

Args Parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    std::string k = argv[i];
    int v = std::atoi(argv[i + 1]);
    if (k == "--width") a.width = v;
    else if (k == "--height") a.height = v;
    else if (k == "--count") a.count = v;
    else if (k == "--runs") a.runs = v;
  }
  return a;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = Parse(argc, argv);
  rig::SetLogLevel("warn");
  const char* src = std::getenv("RIG_SOURCE_DIR");
  fs::path source = src ? fs::path(src) : fs::path(RIG_SOURCE_DIR_FOR_BENCH);
  rig::ConfigResult cr = rig::LoadConfig((source / "config/sim.toml").string());
  if (!cr.ok()) {
    for (const auto& d : cr.diagnostics) std::fprintf(stderr, "%s\n", d.ToString().c_str());
    return 2;
  }
  rig::Config config = cr.config;
  rig::UseSimulatedBackends(&config);
  config.sim.latency_scale = 0;
  config.sim.width = args.width;
  config.sim.height = args.height;
  config.bracket.count = args.count;

  const fs::path root = fs::temp_directory_path() / ("rig_daemon_bench_" + std::to_string(getpid()));
  fs::remove_all(root);
  std::vector<double> total, camera, storage, own, bytes_per_frame;
  int frames = 0, poses = 0;
  for (int run = 0; run < args.runs; ++run) {
    auto session = rig::Session::Create(root / ("s" + std::to_string(run)), config);
    if (!session.ok()) {
      std::fprintf(stderr, "%s\n", session.error().ToString().c_str());
      return 1;
    }
    auto devices = rig::MakeDevices(config);
    if (!devices.ok()) {
      std::fprintf(stderr, "%s\n", devices.error().ToString().c_str());
      return 1;
    }
    rig::CaptureOptions options;
    options.settle_scale = 0;
    options.process = false;
    options.progress = false;
    rig::CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, options);
    rig::CaptureSummary s;
    rig::Status st = daemon.Run(&s);
    if (!st.ok()) {
      std::fprintf(stderr, "%s\n", st.error().ToString().c_str());
      return 1;
    }
    frames = s.frames;
    poses = s.poses;
    total.push_back(s.total_s);
    camera.push_back(s.camera_s);
    storage.push_back(s.storage_s);
    own.push_back(std::max(0.0, s.total_s - s.camera_s - s.storage_s - s.motion_s - s.settle_s -
                                    s.lamp_s - s.queue_wait_s));
    uintmax_t b = 0;
    for (const auto& e : fs::recursive_directory_iterator(session->layout().root / "frames"))
      if (e.is_regular_file()) b += e.file_size();
    bytes_per_frame.push_back(static_cast<double>(b) / s.frames);
  }

  // Peer: writing the same number of bytes per frame to a new file with fsync, plus one
  // small appended line with fdatasync (the least any durable journaled store can do).
  std::vector<double> bare;
  {
    const size_t n = static_cast<size_t>(Median(bytes_per_frame));
    std::vector<char> buf(n, 'x');
    fs::create_directories(root / "bare");
    int jfd = ::open((root / "bare" / "journal").c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    auto t0 = Clock::now();
    for (int i = 0; i < frames; ++i) {
      int fd = ::open((root / "bare" / std::to_string(i)).c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd < 0 || ::write(fd, buf.data(), n) != static_cast<ssize_t>(n)) return 1;
      ::fsync(fd);
      ::close(fd);
      const char line[] = "{\"event\":\"frame\"}\n";
      if (::write(jfd, line, sizeof line - 1) < 0) return 1;
      ::fdatasync(jfd);
    }
    bare.push_back(std::chrono::duration<double>(Clock::now() - t0).count());
    ::close(jfd);
  }
  fs::remove_all(root);

  const double ms = 1000.0;
  std::printf("daemon overhead, dry run with device latencies 0: %d poses x %d exposures, %dx%d, "
              "median of %d runs\n",
              poses, frames / std::max(1, poses), args.width, args.height, args.runs);
  std::printf("  %-44s %12s %12s\n", "", "per frame", "per pose");
  auto row = [&](const char* name, double seconds) {
    std::printf("  %-44s %9.3f ms %9.3f ms\n", name, seconds * ms / frames, seconds * ms / poses);
  };
  row("whole session", Median(total));
  row("simulated camera (render + encode)", Median(camera));
  row("storage (frame write+fsync, journal)", Median(storage));
  row("peer: bare write+fsync of same bytes", Median(bare));
  row("daemon's own (the rest)", Median(own));
  std::printf("  frame size %.0f bytes\n", Median(bytes_per_frame));
  return 0;
}
