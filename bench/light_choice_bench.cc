// Next-best-light against an even spread on a real dense capture: for every N, the lights
// `rig lights` chooses and N spread by farthest point; the default .lp model fitted on each
// set alone; PSNR (8-bit sRGB, mean MSE / median) at the lights chosen by neither, the same
// held-out lights for both. Then adaptive N_a against even N_e (--versus, default 24:36) at
// the lights in neither of those. The choice's own wall time is printed per N.
//   light_choice_bench [--lp FILE.lp] [--n 12,18,24,36,48] [--seed 8] [--versus 24:36]
//                      [--working-pixels 65536] [--pixels 16384] [--criterion reduction|largest]
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "process/evaluate/light_subset.h"
#include "process/model/light_choice.h"

namespace {

std::vector<int> Ints(const std::string& s, char sep = ',') {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep)) out.push_back(std::stoi(item));
  return out;
}

std::string Names(const std::vector<int>& lights) {
  std::string s;
  for (int l : lights) s += fmt::format("{}{}", s.empty() ? "" : " ", l + 1);
  return s;
}

// A second even spread: N points of a Fibonacci spiral over the capture's range of heights
// (z from its lowest to its highest light), each snapped to the nearest dense light not yet
// taken; ties to the lower index.
std::vector<int> FibonacciLights(const std::vector<rig::Vec3>& dirs, int n) {
  double zmin = 1, zmax = -1;
  for (const auto& d : dirs) {
    zmin = std::min(zmin, d[2]);
    zmax = std::max(zmax, d[2]);
  }
  const double golden = M_PI * (3 - std::sqrt(5.0));
  std::vector<int> out;
  for (int i = 0; i < n; ++i) {
    const double z = zmax - (zmax - zmin) * (i + 0.5) / n, r = std::sqrt(std::max(0.0, 1 - z * z));
    const rig::Vec3 p = {r * std::cos(golden * i), r * std::sin(golden * i), z};
    int best = -1;
    double best_dot = -2;
    for (int l = 0; l < static_cast<int>(dirs.size()); ++l) {
      if (std::find(out.begin(), out.end(), l) != out.end()) continue;
      const double dot = p[0] * dirs[l][0] + p[1] * dirs[l][1] + p[2] * dirs[l][2];
      if (dot > best_dot) {
        best_dot = dot;
        best = l;
      }
    }
    out.push_back(best);
  }
  return out;
}

// Every k-th light of the .lp's order (k = lights / n, rounded down positions).
std::vector<int> StrideLights(int lights, int n) {
  std::vector<int> out;
  for (int i = 0; i < n; ++i) out.push_back(static_cast<int>(static_cast<long>(i) * lights / n));
  return out;
}

int Fail(const rig::Error& e) {
  std::fprintf(stderr, "%s\n", e.ToString().c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace rig;
  std::string lp = std::string(RIG_SHARED_DIR_FOR_BENCH) + "/data/rti/neuralrti-example/dirs.lp";
  if (const char* env = std::getenv("RIG_SHARED_DIR"))
    lp = std::string(env) + "/data/rti/neuralrti-example/dirs.lp";
  std::vector<int> counts = {12, 18, 24, 36, 48}, versus = {24, 36};
  LightChoiceOptions o;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--lp") lp = v;
    else if (a == "--n") counts = Ints(v);
    else if (a == "--seed") o.seed = std::stoi(v);
    else if (a == "--versus") versus = Ints(v, ':');
    else if (a == "--working-pixels") o.max_working_pixels = std::stoi(v);
    else if (a == "--pixels") o.pixels = std::stoi(v);
    else if (a == "--criterion")
      o.criterion = v == "largest" ? LightCriterion::kLargestError : LightCriterion::kErrorReduction;
    else {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    }
  }
  auto capture = LoadRtiCapture(lp);
  if (!capture.ok()) return Fail(capture.error());
  const int lights = capture->samples.lights();
  std::vector<Vec3> dirs = capture->samples.directions;
  const std::string tmp = (std::filesystem::temp_directory_path() /
                           fmt::format("light_choice_bench_{}", ::getpid())).string();
  std::printf("%s: %d images %dx%d; default model (pca, size chosen inside each subset) fitted "
              "on each subset alone, scored at the lights in neither\n\n",
              lp.c_str(), lights, capture->samples.width, capture->samples.height);
  std::printf("| N | held out | adaptive dB (mean-MSE / median) | even dB | adaptive − even | "
              "choice s | adaptive model | even model |\n|---|---|---|---|---|---|---|---|\n");
  auto adaptive_of = [&](int n, double* seconds) -> Result<std::vector<int>> {
    o.count = n;
    const auto t0 = std::chrono::steady_clock::now();
    RIG_ASSIGN_OR_RETURN(LightChoice c, ChooseLpLights(capture->entries, o));
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return c.Chosen();
  };
  for (int n : counts) {
    double seconds = 0;
    auto adaptive = adaptive_of(n, &seconds);
    if (!adaptive.ok()) return Fail(adaptive.error());
    const std::vector<int> even = FarthestPointLights(dirs, n);
    const std::vector<int> held = LightsInNone(lights, {*adaptive, even});
    auto a = ScoreLightSubset(*capture, *adaptive, held, tmp);
    if (!a.ok()) return Fail(a.error());
    auto e = ScoreLightSubset(*capture, even, held, tmp);
    if (!e.ok()) return Fail(e.error());
    std::printf("| %d | %zu | %.2f / %.2f | %.2f / %.2f | %+.2f | %.2f | %s | %s |\n", n,
                held.size(), a->psnr_mean_mse_db, a->psnr_median_db, e->psnr_mean_mse_db,
                e->psnr_median_db, a->psnr_mean_mse_db - e->psnr_mean_mse_db, seconds,
                a->model.c_str(), e->model.c_str());
    std::printf("|   | adaptive: %s; even: %s | | | | | | |\n", Names(*adaptive).c_str(),
                Names(even).c_str());
    std::fflush(stdout);
  }
  std::printf("\nAgainst two more even spreads (each pair scored at the lights in neither of "
              "its two sets):\n\n| N | vs Fibonacci: held out, chosen / even dB (mean-MSE), "
              "difference | vs every k-th of the .lp: held out, chosen / even dB, difference |\n"
              "|---|---|---|\n");
  for (int n : counts) {
    double seconds = 0;
    auto adaptive = adaptive_of(n, &seconds);
    if (!adaptive.ok()) return Fail(adaptive.error());
    std::string row = fmt::format("| {} |", n);
    for (const auto& even : {FibonacciLights(dirs, n), StrideLights(lights, n)}) {
      const std::vector<int> held = LightsInNone(lights, {*adaptive, even});
      auto a = ScoreLightSubset(*capture, *adaptive, held, tmp);
      if (!a.ok()) return Fail(a.error());
      auto e = ScoreLightSubset(*capture, even, held, tmp);
      if (!e.ok()) return Fail(e.error());
      row += fmt::format(" {}, {:.2f} / {:.2f}, {:+.2f} |", held.size(), a->psnr_mean_mse_db,
                         e->psnr_mean_mse_db, a->psnr_mean_mse_db - e->psnr_mean_mse_db);
    }
    std::printf("%s\n", row.c_str());
    std::fflush(stdout);
  }
  if (versus.size() == 2) {
    double seconds = 0;
    auto adaptive = adaptive_of(versus[0], &seconds);
    if (!adaptive.ok()) return Fail(adaptive.error());
    const std::vector<int> even = FarthestPointLights(dirs, versus[1]);
    const std::vector<int> held = LightsInNone(lights, {*adaptive, even});
    auto a = ScoreLightSubset(*capture, *adaptive, held, tmp);
    if (!a.ok()) return Fail(a.error());
    auto e = ScoreLightSubset(*capture, even, held, tmp);
    if (!e.ok()) return Fail(e.error());
    std::printf("\nadaptive %d against even %d at the %zu lights in neither: %.2f / %.2f dB "
                "against %.2f / %.2f dB (%+.2f)\n",
                versus[0], versus[1], held.size(), a->psnr_mean_mse_db, a->psnr_median_db,
                e->psnr_mean_mse_db, e->psnr_median_db, a->psnr_mean_mse_db - e->psnr_mean_mse_db);
  }
  std::filesystem::remove_all(tmp);
  return 0;
}
