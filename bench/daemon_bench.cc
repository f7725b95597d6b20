// The capture daemon's own share of a session's time. Runs whole dry-run sessions in this
// process with every simulated device latency scaled to zero (so the devices take only the
// time the simulator needs to render and encode a frame) and prints, per frame and per pose,
// where the time goes: the simulator's rendering (what a real camera does for us), storage
// (write + fsync of the frame, journal record + fdatasync) and everything else the daemon
// does (planning, bookkeeping, progress). Two peers in the same run for scale: the bare cost
// of writing the same bytes to a file with fsync, and the sim camera's own rendering time.
//
// Then the daemon's own time against the hardware time it waits on (motion, settle, lamp,
// camera: the simulator at real device latencies, latency_scale = 1, on a smaller grid):
// run directly, and run as `rig daemon` runs it, through the HTTP service with a client
// polling /api/status at --poll-hz (goal: own time at most 2% of the hardware time).
//
//   build/bench/daemon_bench [--width 320 --height 240 --count 7 --runs 3]
//                            [--real-h-max 30 --real-v-max 10 --real-runs 1 --poll-hz 10]
//                            [--real-runs 0: skip the real-latency part]
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <thread>

#include "config/config.h"
#include "config/log.h"
#include "rig/backends.h"
#include "capture/daemon/daemon.h"
#include "capture/session/session_store.h"
#include "capture/service/client.h"
#include "capture/service/http_server.h"
#include "capture/service/service.h"
#include "rig/commands/daemon_client.h"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

struct Args {
  int width = 320, height = 240, count = 7, runs = 3;
  int real_h_max = 30, real_v_max = 10, real_runs = 1, poll_hz = 10;
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
    else if (k == "--real-h-max") a.real_h_max = v;
    else if (k == "--real-v-max") a.real_v_max = v;
    else if (k == "--real-runs") a.real_runs = v;
    else if (k == "--poll-hz") a.poll_hz = v;
  }
  return a;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

double CpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

// One session's split at real latencies: what the devices took, storage, the daemon's own.
struct RealRun {
  int frames = 0;
  double total = 0, hardware = 0, storage = 0, own = 0, cpu = 0;
  int polls = 0;
  double poll_ms = 0;  // mean time of one GET /api/status
};

RealRun FromTiming(double total, double motion, double settle, double lamp, double camera,
                   double storage, double queue_wait, int frames) {
  RealRun r;
  r.frames = frames;
  r.total = total;
  r.hardware = motion + settle + lamp + camera;
  r.storage = storage;
  r.own = std::max(0.0, total - r.hardware - storage - queue_wait);
  return r;
}

// Directly: the daemon in this thread, nothing else running.
RealRun RunDirect(const rig::Config& config, const fs::path& dir) {
  auto session = rig::Session::Create(dir, config);
  auto devices = rig::MakeDevices(config);
  if (!session.ok() || !devices.ok()) std::exit(1);
  rig::CaptureOptions options;
  options.settle_scale = devices->settle_scale;
  options.process = false;
  options.progress = false;
  rig::CaptureDaemon daemon(*session, *devices->camera, *devices->motor, *devices->lamp, options);
  rig::CaptureSummary s;
  const double cpu0 = CpuSeconds();
  // As the service does before its run (so that the CPU times compare): the ground truth.
  if (devices->write_truth &&
      !devices->write_truth(session->layout().truth(), rig::PlanGrid(config.grid)).ok())
    std::exit(1);
  if (!daemon.Run(&s).ok()) std::exit(1);
  RealRun r = FromTiming(s.total_s, s.motion_s, s.settle_s, s.lamp_s, s.camera_s, s.storage_s,
                         s.queue_wait_s, s.frames);
  r.cpu = CpuSeconds() - cpu0;
  return r;
}

// As `rig daemon` runs it: a job submitted over HTTP, a client polling the status.
RealRun RunThroughService(const rig::Config& config, const fs::path& dir, int poll_hz) {
  rig::ServiceOptions options;
  options.sessions_root = dir.parent_path();  // the daemon writes under its sessions root only
  rig::CaptureService service(rig::DaemonHooks(), options);
  rig::HttpOptions o;
  o.port = 0;
  rig::HttpServer http(service, o);
  if (!http.Start().ok()) std::exit(1);
  service.Start();
  rig::DaemonAddress a;
  a.port = http.port();
  rig::DaemonClient client(a);
  const double cpu0 = CpuSeconds();
  auto job = client.Post("/api/jobs", {{"kind", "capture"}, {"session", dir.string()},
                                       {"config_toml", rig::ToToml(config)}, {"process", false}});
  if (!job.ok()) {
    std::fprintf(stderr, "%s\n", job.error().ToString().c_str());
    std::exit(1);
  }
  std::atomic<bool> done{false};
  int polls = 0;
  double poll_s = 0;
  std::thread poller([&] {
    rig::DaemonClient c(a);
    auto next = Clock::now();
    while (!done) {
      auto t0 = Clock::now();
      if (c.Get("/api/status").ok()) {
        ++polls;
        poll_s += std::chrono::duration<double>(Clock::now() - t0).count();
      }
      next += std::chrono::microseconds(1000000 / std::max(1, poll_hz));
      std::this_thread::sleep_until(next);
    }
  });
  nlohmann::json j;
  for (;;) {
    auto r = client.Get("/api/jobs/" + std::to_string((*job)["id"].get<int>()));
    if (!r.ok()) std::exit(1);
    j = *r;
    if (j["state"] != "queued" && j["state"] != "running") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  done = true;
  poller.join();
  const double cpu = CpuSeconds() - cpu0;
  service.Shutdown();
  http.Stop();
  if (j["state"] != "done" || !j.contains("timing")) {
    std::fprintf(stderr, "job %s\n", j.dump().c_str());
    std::exit(1);
  }
  const auto& t = j["timing"];
  RealRun r = FromTiming(t["total_s"], t["motion_s"], t["settle_s"], t["lamp_s"], t["camera_s"],
                         t["storage_s"], t["queue_wait_s"], t["frames"]);
  r.cpu = cpu;
  r.polls = polls;
  r.poll_ms = polls ? poll_s * 1000 / polls : 0;
  return r;
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

  if (args.real_runs <= 0) {
    fs::remove_all(root);
    return 0;
  }
  rig::Config real = config;
  real.sim.latency_scale = 1;
  real.grid.h_max_deg = args.real_h_max;
  real.grid.v_max_deg = args.real_v_max;
  std::vector<RealRun> direct, served;
  for (int run = 0; run < args.real_runs; ++run) {
    direct.push_back(RunDirect(real, root / ("direct" + std::to_string(run))));
    served.push_back(RunThroughService(real, root / ("served" + std::to_string(run)), args.poll_hz));
  }
  fs::remove_all(root);
  auto med = [](const std::vector<RealRun>& v, double RealRun::*f) {
    std::vector<double> x;
    for (const auto& r : v) x.push_back(r.*f);
    return Median(x);
  };
  const int rf = direct.front().frames;
  std::printf("\ndaemon overhead at real device latencies (latency_scale 1): %d frames, median of %d "
              "run(s)\n",
              rf, args.real_runs);
  std::printf("  %-44s %14s %14s\n", "per frame", "direct", "HTTP service");
  auto row2 = [&](const char* name, double RealRun::*f) {
    std::printf("  %-44s %11.3f ms %11.3f ms\n", name, med(direct, f) * ms / rf,
                med(served, f) * ms / rf);
  };
  row2("whole session", &RealRun::total);
  row2("hardware (motion, settle, lamp, camera)", &RealRun::hardware);
  row2("storage (frame write+fsync, journal)", &RealRun::storage);
  row2("daemon's own (the rest)", &RealRun::own);
  row2("process CPU time (all threads)", &RealRun::cpu);
  auto pct = [&](const std::vector<RealRun>& v, double RealRun::*f) {
    return 100.0 * med(v, f) / std::max(1e-9, med(v, &RealRun::hardware));
  };
  std::printf("  %-44s %12.3f %% %12.3f %%\n", "daemon's own / hardware time (goal <= 2%)",
              pct(direct, &RealRun::own), pct(served, &RealRun::own));
  std::printf("  %-44s %12.3f %% %12.3f %%\n", "storage / hardware time", pct(direct, &RealRun::storage),
              pct(served, &RealRun::storage));
  std::printf("  status polls during the served run: %d at %d Hz, %.2f ms each (mean)\n",
              served.back().polls, args.poll_hz, served.back().poll_ms);
  return 0;
}
