// Relighting speed: a 1 MP frame from 16 coefficients per channel (SH order 3), beside the
// time it takes just to read those coefficients from memory, in the same run, on the same
// threads; plus several lamps, and an environment map (projection, and importance sampling).
//
//   build/bench/render_bench [--width 1000 --height 1000 --order 3 --repeat 15]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "process/model/harmonic/model.h"
#include "process/model/reflectance_model.h"
#include "process/render/envmap.h"

using Clock = std::chrono::steady_clock;

namespace {

template <typename Fn>
double MedianSeconds(int repeat, Fn&& fn) {
  std::vector<double> t;
  for (int i = 0; i < repeat; ++i) {
    const auto a = Clock::now();
    fn();
    t.push_back(std::chrono::duration<double>(Clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  int width = 1000, height = 1000, order = 3, repeat = 15;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    const int v = std::atoi(argv[i + 1]);
    if (k == "--width") width = v;
    else if (k == "--height") height = v;
    else if (k == "--order") order = v;
    else if (k == "--repeat") repeat = v;
  }
  rig::ModelInfo info;
  rig::Model model(rig::Basis(rig::BasisKind::kSh, order), info, width, height);
  const int terms = model.basis().size();
  std::mt19937 rng(1);
  model.coefficients().clear();
  for (int k = 0; k < terms; ++k) {
    cv::Mat c(height, width, CV_32FC3);
    cv::randu(c, cv::Scalar::all(-1), cv::Scalar::all(1));
    model.coefficients().push_back(c);
  }
  const double bytes = double(terms) * width * height * 3 * sizeof(float);
  const rig::Vec3 dir = rig::LightDirection(45, 20);

  // Peer: read every coefficient once (a vectorised sum per plane, rows split over the same
  // threads OpenCV's parallel_for_ uses for the render).
  volatile float sink = 0;
  const double read_s = MedianSeconds(repeat, [&] {
    std::vector<float> partial(height, 0.f);
    cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& rows) {
      for (int y = rows.start; y < rows.end; ++y) {
        float acc[8] = {0};
        for (int k = 0; k < terms; ++k) {
          const float* p = model.coefficients()[k].ptr<float>(y);
          const int n = width * 3;
          int i = 0;
          for (; i + 8 <= n; i += 8)
            for (int j = 0; j < 8; ++j) acc[j] += p[i + j];
          for (; i < n; ++i) acc[0] += p[i];
        }
        float s = 0;
        for (float a : acc) s += a;
        partial[y] = s;
      }
    });
    float s = 0;
    for (float v : partial) s += v;
    sink = s;
  });
  cv::Mat rho;
  const double render_s = MedianSeconds(repeat, [&] { rho = model.EvaluateRho(dir); });
  cv::Mat sum;
  const double lamps4_s = MedianSeconds(std::max(3, repeat / 3), [&] {
    sum.release();
    for (double h : {10.0, 35.0, 60.0, 85.0}) model.AddLamp(rig::LightDirection(h, 15), {1, 0.8, 0.6}, &sum);
  });
  // An environment map (1024x512, seeded noise over a bright patch: the content does not
  // change the projection's cost), the whole sphere (extrapolate: this model has no lamps).
  cv::Mat env(512, 1024, CV_32FC3);
  cv::randu(env, cv::Scalar::all(0), cv::Scalar::all(1));
  env(cv::Rect(600, 150, 60, 40)) += cv::Scalar::all(50);
  rig::EnvmapOptions eo;
  eo.extrapolate = true;
  auto wrapped = rig::WrapHarmonic(model);
  std::vector<double> prep, pix;
  double env_total_s = MedianSeconds(std::max(3, repeat / 3), [&] {
    auto e = rig::RenderEnvironment(*wrapped, &model, env, eo);
    if (!e.ok()) std::abort();
    prep.push_back(e->prepare_s);
    pix.push_back(e->pixels_s);
  });
  std::sort(prep.begin(), prep.end());
  std::sort(pix.begin(), pix.end());
  eo.force_sampling = true;
  eo.samples = 64;
  int distinct = 0;
  const double sampled_s = MedianSeconds(3, [&] {
    auto e = rig::RenderEnvironment(*wrapped, &model, env, eo);
    if (!e.ok()) std::abort();
    distinct = e->distinct_lamps;
  });
  (void)sink;
  std::printf("relighting %dx%d (%.1f MP), SH order %d: %d coefficients per channel, float, %d threads\n",
              width, height, width * height / 1e6, order, terms, cv::getNumThreads());
  std::printf("  %-46s %9.2f ms  %6.2f GB/s\n", "peer: read the coefficients once", read_s * 1e3,
              bytes / read_s / 1e9);
  std::printf("  %-46s %9.2f ms  %6.2f GB/s  (%.2fx the read)\n", "ours: one lamp (rho for every pixel)",
              render_s * 1e3, bytes / render_s / 1e9, render_s / read_s);
  std::printf("  %-46s %9.2f ms  (%.2f ms per lamp)\n", "ours: four coloured lamps, summed", lamps4_s * 1e3,
              lamps4_s * 1e3 / 4);
  const double mp = width * height / 1e6;
  std::printf("  %-46s %9.2f ms  (%.2f ms per MP; one lamp: %.2f ms per MP)\n",
              "ours: envmap, projection (per-pixel part)", pix[pix.size() / 2] * 1e3,
              pix[pix.size() / 2] * 1e3 / mp, render_s * 1e3 / mp);
  std::printf("  %-46s %9.2f ms  (512x256 working map, %d terms, once per map)\n",
              "ours: envmap, projecting the map", prep[prep.size() / 2] * 1e3, terms);
  std::printf("  %-46s %9.2f ms  (%.2f ms per MP)\n", "ours: envmap, projection, whole render",
              env_total_s * 1e3, env_total_s * 1e3 / mp);
  std::printf("  %-46s %9.2f ms  (%.2f ms per MP; %d distinct lamps of 64 draws)\n",
              "ours: envmap, importance sampling (PCA path)", sampled_s * 1e3, sampled_s * 1e3 / mp,
              distinct);
  return 0;
}
