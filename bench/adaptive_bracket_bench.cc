// Adaptive brackets against the fixed bracket on the simulated rig: frames taken, capture
// time at real latencies (each frame's exposure plus the body's download time; the motor's
// moves are the same for both and left out) and HDR error against the scene's exact radiance,
// per pose and in all (sim/adaptive_eval.h says how each side is run and scored).
//
//   build/bench/adaptive_bracket_bench [--config config/sim.toml] [--width 320 --height 240]
//                                      [--overlap 0.5] [--headroom 1] [--z-lo 24 --z-hi 235]
#include <cstdio>
#include <cstdlib>
#include <string>

#include "config/config.h"
#include "sim/adaptive_eval.h"

int main(int argc, char** argv) {
  std::string config = "config/sim.toml";
  int width = 320, height = 240;
  rig::AdaptiveEvalOptions o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { return i + 1 < argc ? std::string(argv[++i]) : std::string(); };
    if (a == "--config") config = next();
    else if (a == "--width") width = std::atoi(next().c_str());
    else if (a == "--height") height = std::atoi(next().c_str());
    else if (a == "--overlap") o.overlap_stops = std::atof(next().c_str());
    else if (a == "--headroom") o.headroom_stops = std::atof(next().c_str());
    else if (a == "--z-lo") o.z_lo = std::atoi(next().c_str());
    else if (a == "--z-hi") o.z_hi = std::atoi(next().c_str());
    else {
      std::fprintf(stderr, "usage: adaptive_bracket_bench [--config F] [--width W --height H] "
                           "[--overlap S] [--headroom S] [--z-lo Z --z-hi Z]\n");
      return 2;
    }
  }
  auto cfg = rig::LoadConfigOrError(config);
  if (!cfg.ok()) {
    std::fprintf(stderr, "%s\n", cfg.error().ToString().c_str());
    return 2;
  }
  cfg->sim.width = width;
  cfg->sim.height = height;
  auto r = rig::CompareAdaptiveBracket(*cfg, o);
  if (!r.ok()) {
    std::fprintf(stderr, "%s\n", r.error().ToString().c_str());
    return 1;
  }
  std::printf("adaptive_bracket_bench: %s, %dx%d, window levels %d..%d, overlap %.2f stops, "
              "headroom %.2f stops\n\n", config.c_str(), width, height, o.z_lo, o.z_hi,
              o.overlap_stops, o.headroom_stops);
  std::printf("%-10s %6s %6s %10s %10s   %s\n", "pose", "fixed", "adapt", "rms fixed", "rms adapt",
              "adaptive plan");
  for (const auto& p : r->poses) {
    std::printf("%-10s %6d %6d %10.4f %10.4f   %s\n", p.pose.c_str(), p.fixed_frames,
                p.adaptive_frames, p.fixed_rms, p.adaptive_rms, p.plan.c_str());
  }
  std::printf("\n%-28s %10s %10s %8s\n", "", "fixed", "adaptive", "ratio");
  std::printf("%-28s %10d %10d %7.0f%%\n", "frames", r->fixed_frames, r->adaptive_frames,
              100.0 * r->adaptive_frames / r->fixed_frames);
  std::printf("%-28s %10.1f %10.1f %7.0f%%\n", "capture time, s (real latency)", r->fixed_capture_s,
              r->adaptive_capture_s, 100.0 * r->adaptive_capture_s / r->fixed_capture_s);
  std::printf("%-28s %10.4f %10.4f %7.2fx\n", "log-radiance RMS", r->fixed_rms, r->adaptive_rms,
              r->adaptive_rms / r->fixed_rms);
  std::printf("%-28s %10d %10d   (of %d pixel-channels scored; flagged pixels left out of both)\n",
              "pixels flagged", r->fixed_flagged, r->adaptive_flagged, r->scored);
  return 0;
}
