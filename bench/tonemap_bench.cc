// Tone mapping a 6 MP radiance map: Ward (ours), linear, and OpenCV's Reinhard, Drago and
// Mantiuk on the same image in the same run; plus exposure rendering. Prints ms per image.
//
//   tonemap_bench [IMAGE.hdr] [--threads N]
// Default image: ../shared/data/hdr/mpi_atrium_3.hdr next to the source tree, upscaled to
// 3000 x 2000.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "process/render/exposure_render.h"
#include "process/render/tonemap.h"

namespace {

namespace fs = std::filesystem;

// Median wall time in ms of `runs` calls, after one warm-up call.
double MedianMs(int runs, const std::function<void()>& f) {
  f();
  std::vector<double> ms;
  for (int i = 0; i < runs; ++i) {
    const auto start = std::chrono::steady_clock::now();
    f();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  std::string path;
  int threads = -1;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--threads") == 0 && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else {
      path = argv[i];
    }
  }
  if (path.empty()) {
    const char* shared = std::getenv("RIG_SHARED_DIR");
    fs::path dir = shared ? fs::path(shared)
                          : fs::path(__FILE__).parent_path().parent_path() / ".." / "shared";
    path = (dir / "data" / "hdr" / "mpi_atrium_3.hdr").string();
  }
  cv::Mat source = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_COLOR);
  if (source.empty() || source.type() != CV_32FC3) {
    std::fprintf(stderr, "tonemap_bench: cannot read %s as a float RGB image\n", path.c_str());
    return 2;
  }
  if (threads > 0) cv::setNumThreads(threads);
  cv::Mat radiance;
  cv::resize(source, radiance, cv::Size(3000, 2000), 0, 0, cv::INTER_LINEAR);
  std::printf("image: %s upscaled to %dx%d (%.1f MP), OpenCV threads %d, %d cores\n",
              path.c_str(), radiance.cols, radiance.rows, radiance.total() / 1e6,
              cv::getNumThreads(), cv::getNumberOfCPUs());
  std::printf("%-32s %10s %6s\n", "method", "ms/image", "runs");

  struct Row {
    const char* name;
    rig::ToneMapMethod method;
    int runs;
  };
  const Row rows[] = {
      {"ward (ours, histogram + ceiling)", rig::ToneMapMethod::kWard, 9},
      {"linear (ours, 99th pct → white)", rig::ToneMapMethod::kLinear, 9},
      {"opencv reinhard", rig::ToneMapMethod::kReinhard, 3},
      {"opencv drago", rig::ToneMapMethod::kDrago, 3},
      {"opencv mantiuk", rig::ToneMapMethod::kMantiuk, 1},
  };
  for (const Row& row : rows) {
    rig::ToneMapOptions o;
    o.method = row.method;
    bool ok = true;
    const double ms = MedianMs(row.runs, [&] { ok = rig::ToneMap(radiance, o).ok() && ok; });
    std::printf("%-32s %10.1f %6d%s\n", row.name, ms, row.runs, ok ? "" : "  (FAILED)");
  }
  {
    // Ward's stages alone: the encoding (shared by every method) against the mapping.
    rig::ToneMapOptions o;
    cv::Mat pixels = rig::ToneMapLinearPixels(radiance, o).value();
    const double map_ms = MedianMs(9, [&] { (void)rig::ToneMapLinearPixels(radiance, o); });
    const double enc_ms = MedianMs(9, [&] { (void)rig::EncodeForDisplay(pixels, o); });
    std::printf("%-32s %10.1f %6d\n", "  ward mapping to linear pixels", map_ms, 9);
    std::printf("%-32s %10.1f %6d\n", "  display encoding (LUT)", enc_ms, 9);
  }
  {
    std::array<std::vector<double>, 3> g;
    for (int c = 0; c < 3; ++c) {
      for (int z = 0; z < 256; ++z) g[c].push_back(2.2 * std::log((z + 0.5) / 256));
    }
    bool ok = true;
    const double ms =
        MedianMs(9, [&] { ok = rig::RenderExposure(radiance, 1.0 / 60, g).ok() && ok; });
    std::printf("%-32s %10.1f %6d%s\n", "exposure rendering (ours)", ms, 9, ok ? "" : "  (FAILED)");
  }
  return 0;
}
