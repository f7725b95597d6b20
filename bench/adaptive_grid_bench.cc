// The adaptive grid against the full grid and an even spread, on the simulator (issue 36):
// for each scene, dry-run sessions through the capture daemon — the full grid (every pose),
// an even spread of N poses (grid.mode = "adaptive" with a seed of N: the farthest-point
// spread, no choice), and the adaptive grid of N poses (a seed of 8, then the next-best-light
// choice per second of the rig's time) — each session's default model fitted from its maps
// (FitSessionModel, as `rig capture` does), relit at lamp poses none of them took (the truth
// of a grid offset by half a step: the cells' centres) and scored as hdr_model_bench scores:
// relative RMS error, one scale per channel removed, on all pixels, always-lit and shadowed
// ones. Capture time is estimated from the configuration at real speeds: each pose's cost
// (settle, lamp warm-up, exposures, 1 s transfer a frame) plus the moves in visiting order
// from home (0, 0) (MoveSeconds). Also the adaptive grid with its default stop (grid.target)
// up to the whole grid: where it stops, and what it reaches there.
//
//   build/bench/adaptive_grid_bench [--dir /tmp/adaptive_grid_bench] [--scenes full,gloss]
//       [--counts 12,16,20,24] [--families harmonic,pca] [--width 320 --height 240]
//       [--config FILE] [--fresh]
// Each session is run once per model family (process.model_family): the session default
// (harmonic: SH, order chosen by leave-one-out) and PCA with its interpolated light basis.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "capture/daemon/adaptive_grid.h"
#include "capture/daemon/session_model.h"
#include "capture/plan/bracket.h"
#include "capture/plan/pose.h"
#include "capture/session/session_store.h"
#include "config/builtin_config.h"
#include "process/io/exr_io.h"
#include "process/model/any/load_model.h"
#include "process/model/light_direction.h"
#include "sim/dry_session.h"
#include "sim/truth.h"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "adaptive_grid_bench: %s\n", what.c_str());
  std::exit(1);
}
template <class T>
T Must(rig::Result<T> r) {
  if (!r.ok()) Die(r.error().ToString());
  return std::move(*r);
}
void Must(const rig::Status& s) {
  if (!s.ok()) Die(s.error().ToString());
}
std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> out;
  size_t i = 0;
  while (!s.empty()) {
    const size_t j = s.find(sep, i);
    out.push_back(s.substr(i, j == std::string::npos ? std::string::npos : j - i));
    if (j == std::string::npos) break;
    i = j + 1;
  }
  return out;
}

struct Args {
  fs::path dir = "/tmp/adaptive_grid_bench";
  std::string config;
  std::vector<std::string> scenes = {"full", "gloss", "sharp", "matte"};
  std::vector<int> counts = {12, 16, 20, 24};
  std::vector<std::string> families = {"harmonic", "pca"};
  int width = 0, height = 0;
  bool fresh = false;
};

Args ParseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) Die(k + " needs a value");
      return argv[++i];
    };
    if (k == "--dir") a.dir = next();
    else if (k == "--config") a.config = next();
    else if (k == "--scenes") a.scenes = Split(next(), ',');
    else if (k == "--families") a.families = Split(next(), ',');
    else if (k == "--counts") {
      a.counts.clear();
      for (const auto& s : Split(next(), ',')) a.counts.push_back(std::stoi(s));
    } else if (k == "--width") a.width = std::stoi(next());
    else if (k == "--height") a.height = std::stoi(next());
    else if (k == "--fresh") a.fresh = true;
    else Die("unknown option " + k);
  }
  return a;
}

struct Truth {
  std::vector<rig::Pose> poses;  // the offset grid's
  std::vector<cv::Mat> radiance;
  cv::Mat shadowed;              // 1: zero in some channel at some pose of the full grid
};

struct Score {
  double all = 0, lit = 0, shadowed = 0;
};

Score ScoreModel(const rig::ReflectanceModel& m, const Truth& truth) {
  double pt[3][3] = {}, pp[3][3] = {}, tt[3][3] = {};
  for (size_t k = 0; k < truth.poses.size(); ++k) {
    cv::Mat sum;
    m.AddLamp(rig::LightDirection(truth.poses[k].h_deg, truth.poses[k].v_deg, m.light_frame()),
              {1, 1, 1}, &sum);
    for (int y = 0; y < sum.rows; ++y)
      for (int x = 0; x < sum.cols; ++x) {
        const cv::Vec3f p = sum.at<cv::Vec3f>(y, x), t = truth.radiance[k].at<cv::Vec3f>(y, x);
        const int sub = truth.shadowed.at<uint8_t>(y, x) ? 2 : 1;
        for (int c = 0; c < 3; ++c)
          for (int s : {0, sub}) {
            pt[s][c] += double(p[c]) * t[c];
            pp[s][c] += double(p[c]) * p[c];
            tt[s][c] += double(t[c]) * t[c];
          }
      }
  }
  double rel[3];
  for (int s = 0; s < 3; ++s) {
    double err = 0, ref = 0;
    for (int c = 0; c < 3; ++c) {
      const double scale = pp[0][c] > 0 ? pt[0][c] / pp[0][c] : 0;
      err += scale * scale * pp[s][c] - 2 * scale * pt[s][c] + tt[s][c];
      ref += tt[s][c];
    }
    rel[s] = ref > 0 ? std::sqrt(std::max(0.0, err) / ref) : 0;
  }
  return {rel[0], rel[1], rel[2]};
}

struct Run {
  std::vector<rig::Pose> visited;  // in order
  std::string stop;                // grid_done's reason (adaptive)
  double fit_order = -1;
};

// One dry-run session and its default model; the poses in the order the journal took them.
Run Session(const rig::Config& config, const fs::path& dir, bool fresh) {
  if (fresh || !fs::exists(dir / "model" / "report.md")) {
    fs::remove_all(dir);
    Must(rig::RunSimulatedSession(config, dir));
    Must(rig::FitSessionModel(Must(rig::Session::OpenExisting(dir))));
  }
  Run run;
  std::ifstream in(dir / "journal.jsonl");
  std::string line;
  while (std::getline(in, line)) {
    const auto r = nlohmann::json::parse(line, nullptr, false);
    if (r.is_discarded()) continue;
    const std::string ev = r.value("event", "");
    if (ev == "pose_done") run.visited.push_back(Must(rig::ParsePoseName(r.at("pose").get<std::string>())));
    if (ev == "grid_done") run.stop = r.value("reason", "");
  }
  return run;
}

std::vector<double> Exposures(const rig::Config& config) {
  std::vector<double> e;
  for (auto s : rig::WantedExposures(config.bracket)) e.push_back(s.count());
  return e;
}

double CaptureSeconds(const rig::Config& config, const std::vector<rig::Pose>& visited) {
  const double pose = rig::AdaptivePoseCost(config, Exposures(config));
  double t = 0;
  rig::Pose at{0, 0};
  for (const auto& p : visited) {
    t += pose + rig::MoveSeconds(config.motor, at, p);
    at = p;
  }
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = ParseArgs(argc, argv);
  rig::ConfigResult cfg = rig::LoadConfigOrBuiltIn(a.config);
  if (!cfg.ok()) Die(cfg.AsError().ToString());
  rig::Config base = cfg.config;
  if (a.width > 0) base.sim.width = a.width;
  if (a.height > 0) base.sim.height = a.height;
  fs::create_directories(a.dir);
  const int allowed = static_cast<int>(rig::PlanGrid(base.grid).size());
  std::printf("grid %d poses allowed; %dx%d; capture time at real speeds (estimated: pose cost "
              "%.2f s + moves)\n",
              allowed, base.sim.width, base.sim.height,
              rig::AdaptivePoseCost(base, Exposures(base)));
  for (const std::string& scene : a.scenes) {
  for (const std::string& family : a.families) {
    rig::Config config = base;
    config.sim.scene = scene;
    config.process.model_family = family;
    const fs::path sd = a.dir / scene / family;
    // The truth at the offset grid's poses, and the shadow mask of the full grid's.
    rig::Config off = config;
    off.grid.h_min_deg += off.grid.h_step_deg / 2;
    off.grid.h_max_deg -= off.grid.h_step_deg / 2;
    off.grid.v_min_deg += off.grid.v_step_deg / 2;
    off.grid.v_max_deg -= off.grid.v_step_deg / 2;
    if (a.fresh || !fs::exists(sd / "offset" / "scene.json")) {
      fs::remove_all(sd / "offset");
      Must(rig::WriteTruth((sd / "offset").string(), off));
    }
    Truth truth;
    for (const rig::Pose& p : rig::PlanGrid(off.grid)) {
      truth.poses.push_back(p);
      truth.radiance.push_back(Must(rig::ReadRgbExr((sd / "offset" / "radiance" / (p.Name() + ".exr")).string())));
    }
    const Run full = Session(config, sd / "full", a.fresh);
    for (const rig::Pose& p : rig::PlanGrid(config.grid)) {
      cv::Mat t = Must(rig::ReadRgbExr((sd / "full" / "truth" / "radiance" / (p.Name() + ".exr")).string()));
      if (truth.shadowed.empty()) truth.shadowed = cv::Mat::zeros(t.size(), CV_8U);
      for (int y = 0; y < t.rows; ++y)
        for (int x = 0; x < t.cols; ++x) {
          const cv::Vec3f v = t.at<cv::Vec3f>(y, x);
          if (v[0] <= 0 || v[1] <= 0 || v[2] <= 0) truth.shadowed.at<uint8_t>(y, x) = 1;
        }
    }
    auto row = [&](const std::string& name, const fs::path& dir, const Run& run, double ref) {
      const fs::path exr = dir / "model" / "model.exr";
      auto model = Must(rig::LoadReflectanceModel((fs::exists(exr) ? exr : dir / "model" / "pca").string()));
      const Score s = ScoreModel(*model, truth);
      std::printf("%-7s %-8s %-22s %5zu %8.4f %8.4f %8.4f %7.2fx %8.0f s  %s\n", scene.c_str(),
                  family.c_str(), name.c_str(), run.visited.size(), s.all, s.lit, s.shadowed,
                  ref > 0 ? s.all / ref : 1.0, CaptureSeconds(config, run.visited),
                  model->Describe().c_str());
      std::fflush(stdout);
      return s.all;
    };
    std::printf("\n%-7s %-8s %-22s %5s %8s %8s %8s %8s %10s  %s\n", "scene", "family", "grid", "poses",
                "rel.err", "lit", "shadowed", "vs full", "capture", "model");
    const double ref = row("full", sd / "full", full, 0);
    for (int n : a.counts) {
      if (n > allowed) continue;
      rig::Config even = config;
      even.grid.mode = "adaptive";
      even.grid.max_poses = n;
      even.grid.seed_poses = n;
      even.grid.target = 0;
      const fs::path ed = sd / fmt::format("even{}", n);
      row(fmt::format("even spread {}", n), ed, Session(even, ed, a.fresh), ref);
      rig::Config adaptive = config;
      adaptive.grid.mode = "adaptive";
      adaptive.grid.max_poses = n;
      adaptive.grid.target = 0;
      const fs::path ad = sd / fmt::format("adaptive{}", n);
      row(fmt::format("adaptive {}", n), ad, Session(adaptive, ad, a.fresh), ref);
    }
    rig::Config stop = config;
    stop.grid.mode = "adaptive";
    stop.grid.max_poses = allowed;
    const fs::path td = sd / "adaptive-target";
    const Run r = Session(stop, td, a.fresh);
    row(fmt::format("adaptive, target {:.0f}%", 100 * stop.grid.target), td, r, ref);
    std::printf("        stopped: %s\n", r.stop.c_str());
  }
  }
  return 0;
}
