// The streamed PCA fit (FitPcaStreaming) on synthetic captures of 1, 6 and 24 MP × 72 lights:
// wall time, time per MP, and peak RSS of each size measured in a child process of its own
// (fork per size, so each peak is that size's). Optionally the in-memory path (LoadRtiCapture
// + FitPcaAuto + Save) beside it, on the sizes that fit, with the files compared byte for byte.
//
//   build-stream/bench/pca_stream_bench [--sizes 1,6,24] [--lights 72] [--dir /tmp]
//       [--band-rows 16] [--threads 2] [--memory-up-to MP] [--keep]
//
// The captures are JPEG q95 (YCbCr 4:4:4), generated band by band with the project's
// JpegWriter (two images at a time), seeded and deterministic: a textured Lambertian + Phong
// height field with a wall casting a shadow; deleted at the end unless --keep.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "process/io/jpeg_io.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/pca/pca_stream.h"
#include "process/model/any/rti_fit.h"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double Seconds(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

std::vector<rig::Vec3> Lights(int n) {
  std::vector<rig::Vec3> d;
  for (int i = 0; i < n; ++i) {
    const double el = (15.0 + 65.0 * i / std::max(1, n - 1)) * M_PI / 180.0;
    const double az = i * 2.39996322972865332;
    d.push_back({std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el)});
  }
  return d;
}

uint32_t Hash(uint32_t x, uint32_t y, uint32_t seed) {
  uint32_t h = x * 0x8da6b343u ^ y * 0xd8163841u ^ seed * 0xcb1ab31fu;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  return h ^ (h >> 15);
}

// One image of the scene, written band by band: per-column and per-row tables keep it cheap.
rig::Status WriteImage(const std::string& path, int w, int h, const rig::Vec3& l, uint32_t seed) {
  RIG_ASSIGN_OR_RETURN(auto writer, rig::JpegWriter::Open(path, w, h, 3, rig::JpegColor::kYcbcr, 95));
  // sRGB encoding of radiance 0..2 in 8192 steps.
  static const std::vector<uint8_t> lut = [] {
    std::vector<uint8_t> t(8192);
    for (int i = 0; i < 8192; ++i) {
      const double r = std::min(1.0, i / 4096.0);
      const double s = r <= 0.0031308 ? 12.92 * r : 1.055 * std::pow(r, 1 / 2.4) - 0.055;
      t[i] = static_cast<uint8_t>(std::lround(255 * s));
    }
    return t;
  }();
  const double fx = 2 * M_PI / 97, fy = 2 * M_PI / 61, amp = 6.0;
  std::vector<double> sx(w), cx(w), sy(h), cy(h);
  for (int x = 0; x < w; ++x) sx[x] = std::sin(fx * x), cx[x] = std::cos(fx * x);
  for (int y = 0; y < h; ++y) sy[y] = std::sin(fy * y), cy[y] = std::cos(fy * y);
  const int wall_x = w * 2 / 5;
  const double shadow_len = l[0] < 0 ? 60.0 * (-l[0]) / l[2] : 0;
  const double tint[3] = {1.0, 0.82, 0.6};
  const int band = 64;
  cv::Mat rows(band, w, CV_8UC3);
  for (int y0 = 0; y0 < h; y0 += band) {
    const int n = std::min(band, h - y0);
    for (int dy = 0; dy < n; ++dy) {
      const int y = y0 + dy;
      uint8_t* out = rows.ptr<uint8_t>(dy);
      for (int x = 0; x < w; ++x) {
        // h = amp·sin(fx x)·sin(fy y): the normal from its gradient.
        const double hx = amp * fx * cx[x] * sy[y], hy = amp * fy * sx[x] * cy[y];
        const double inv = 1 / std::sqrt(hx * hx + hy * hy + 1);
        const double nx = -hx * inv, ny = -hy * inv, nz = inv;
        const double ndl = std::max(0.0, nx * l[0] + ny * l[1] + nz * l[2]);
        const double rz = 2 * ndl * nz - l[2];
        double spec = std::max(0.0, rz);
        for (int i = 0; i < 5; ++i) spec *= spec;  // exponent 32
        const bool checker = ((x >> 5) + (y >> 5)) & 1;
        const double ks = checker ? 0.9 : 0.15;
        const double grain = 0.85 + 0.3 * (Hash(x, y, seed) & 1023) / 1023.0;
        const bool shadow = x > wall_x && x < wall_x + shadow_len;
        for (int c = 0; c < 3; ++c) {
          const double albedo = (checker ? 0.55 : 0.3) * tint[c] * grain;
          const double r = shadow ? 0.008 : albedo * ndl + ks * spec + 0.004;
          out[x * 3 + c] = lut[std::min(8191, static_cast<int>(r * 4096))];
        }
      }
    }
    RIG_TRY(writer->Write(rows.rowRange(0, n)));
  }
  return writer->Finish();
}

int Generate(const fs::path& dir, int w, int h, int lights, int threads) {
  fs::create_directories(dir);
  const auto dirs = Lights(lights);
  std::ofstream lp(dir / "capture.lp");
  lp << lights << "\n";
  for (int l = 0; l < lights; ++l)
    lp << fmt::format("light_{:02d}.jpg {:.6f} {:.6f} {:.6f}\n", l, dirs[l][0], dirs[l][1], dirs[l][2]);
  lp.close();
  std::vector<std::thread> pool;
  std::vector<int> failed(threads, 0);
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      for (int l = t; l < lights; l += threads) {
        auto s = WriteImage((dir / fmt::format("light_{:02d}.jpg", l)).string(), w, h, dirs[l], 14);
        if (!s.ok()) {
          std::fprintf(stderr, "%s\n", s.error().ToString().c_str());
          failed[t] = 1;
          return;
        }
      }
    });
  }
  for (auto& th : pool) th.join();
  return std::count(failed.begin(), failed.end(), 1) ? 1 : 0;
}

long VmHwmKb() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::atol(line.c_str() + 6);
  return -1;
}

// Runs body in a child; returns its exit status and its peak RSS (KB, from wait4).
int InChild(const std::function<int()>& body, long* maxrss_kb) {
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid == 0) std::_Exit(body());
  int status = 0;
  rusage ru{};
  wait4(pid, &status, 0, &ru);
  *maxrss_kb = ru.ru_maxrss;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

std::string Bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes = {1, 6, 24};
  int lights = 72, band_rows = 16, threads = 2;
  double memory_up_to = 0;
  std::string root = fs::temp_directory_path().string();
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { return i + 1 < argc ? std::string(argv[++i]) : std::string(); };
    if (a == "--sizes") {
      sizes.clear();
      std::string s = next();
      for (size_t p = 0; p < s.size();) {
        const size_t q = s.find(',', p);
        sizes.push_back(std::atoi(s.substr(p, q - p).c_str()));
        p = q == std::string::npos ? s.size() : q + 1;
      }
    } else if (a == "--lights") {
      lights = std::atoi(next().c_str());
    } else if (a == "--dir") {
      root = next();
    } else if (a == "--band-rows") {
      band_rows = std::atoi(next().c_str());
    } else if (a == "--threads") {
      threads = std::atoi(next().c_str());
    } else if (a == "--memory-up-to") {
      memory_up_to = std::atof(next().c_str());
    } else if (a == "--keep") {
      keep = true;
    } else {
      std::fprintf(stderr, "usage: %s [--sizes 1,6,24] [--lights 72] [--dir DIR] [--band-rows N] "
                           "[--threads N] [--memory-up-to MP] [--keep]\n", argv[0]);
      return 2;
    }
  }
  struct Row {
    int mp, w, h;
    double gen_s, wall_s, gather_s, choice_s, write_s;
    long peak_kb;
    std::string model;
    double mem_wall_s = -1;
    long mem_peak_kb = -1;
    std::string identical = "-";
  };
  std::vector<Row> table;
  for (int mp : sizes) {
    // 3:2 frames: 1 MP 1224x816, 6 MP 3000x2000, 24 MP 6000x4000.
    const int w = static_cast<int>(std::lround(std::sqrt(mp * 1e6 * 1.5) / 8)) * 8;
    const int h = w * 2 / 3;
    const fs::path dir = fs::path(root) / fmt::format("rig_pca_stream_bench_{}_{}mp", getpid(), mp);
    Row row{mp, w, h, 0, 0, 0, 0, 0, 0, ""};
    std::printf("%d MP (%dx%d x %d lights): generating in %s...\n", mp, w, h, lights, dir.c_str());
    long gen_kb = 0;
    auto tg = Clock::now();
    if (InChild([&] { return Generate(dir, w, h, lights, threads); }, &gen_kb) != 0) {
      std::fprintf(stderr, "generation failed\n");
      fs::remove_all(dir);
      return 1;
    }
    row.gen_s = Seconds(tg);
    std::printf("  generated in %.1f s (peak RSS %.0f MB), %.0f MB on disk\n", row.gen_s,
                gen_kb / 1024.0, [&] {
                  double b = 0;
                  for (const auto& e : fs::directory_iterator(dir)) b += e.file_size();
                  return b / (1 << 20);
                }());
    // The streamed fit in a child; its numbers back through a pipe.
    int fd[2];
    if (pipe(fd) != 0) return 1;
    const auto t0 = Clock::now();
    long fit_kb = 0;
    const int rc = InChild(
        [&] {
          close(fd[0]);
          auto entries = rig::ReadLp((dir / "capture.lp").string());
          if (!entries.ok()) return 1;
          rig::PcaStreamOptions so;
          so.band_rows = band_rows;
          so.threads = threads;
          auto fit = rig::FitPcaStreaming(*entries, rig::PcaChoiceOptions{}, (dir / "model").string(), so);
          if (!fit.ok()) {
            std::fprintf(stderr, "%s\n", fit.error().ToString().c_str());
            return 1;
          }
          const auto& o = fit->choice.options;
          const std::string msg = fmt::format("{} {} {} {} k={} grid={} q={}\n", fit->gather_s,
                                              fit->choice_s, fit->write_s, VmHwmKb(), o.components,
                                              o.grid_resolution, o.jpeg_quality);
          if (write(fd[1], msg.data(), msg.size()) < 0) return 1;
          close(fd[1]);
          return 0;
        },
        &fit_kb);
    row.wall_s = Seconds(t0);
    close(fd[1]);
    char buf[512] = {0};
    const ssize_t got = read(fd[0], buf, sizeof(buf) - 1);
    close(fd[0]);
    if (rc != 0 || got <= 0) {
      std::fprintf(stderr, "the streamed fit failed (status %d)\n", rc);
      if (!keep) fs::remove_all(dir);
      return 1;
    }
    long hwm = 0;
    char model[128] = {0};
    std::sscanf(buf, "%lf %lf %lf %ld %127[^\n]", &row.gather_s, &row.choice_s, &row.write_s, &hwm,
                model);
    row.model = model;
    row.peak_kb = std::max(hwm, fit_kb);
    std::printf("  streamed: %.1f s (sample %.1f, choice %.1f, planes %.1f), peak RSS %.0f MB, %s\n",
                row.wall_s, row.gather_s, row.choice_s, row.write_s, row.peak_kb / 1024.0, model);
    if (mp <= memory_up_to) {
      long mem_kb = 0;
      const auto t1 = Clock::now();
      const int mrc = InChild(
          [&] {
            auto cap = rig::LoadRtiCapture((dir / "capture.lp").string());
            if (!cap.ok()) return 1;
            auto fit = rig::FitPcaAuto(cap->samples, nullptr, rig::PcaChoiceOptions{});
            if (!fit.ok()) return 1;
            return fit->model.Save((dir / "model_memory").string()).ok() ? 0 : 1;
          },
          &mem_kb);
      row.mem_wall_s = Seconds(t1);
      row.mem_peak_kb = mem_kb;
      if (mrc == 0) {
        bool same = true;
        for (const auto& e : fs::directory_iterator(dir / "model_memory"))
          same = same && Bytes(e.path()) == Bytes(dir / "model" / e.path().filename());
        row.identical = same ? "yes" : "NO";
      } else {
        row.identical = fmt::format("in-memory failed ({})", mrc);
      }
      std::printf("  in memory: %.1f s, peak RSS %.0f MB, files identical: %s\n", row.mem_wall_s,
                  mem_kb / 1024.0, row.identical.c_str());
    }
    if (!keep) fs::remove_all(dir);
    table.push_back(row);
  }
  std::printf("\n| MP | size | wall s | s/MP | sample s | choice s | planes s | peak RSS MB | model "
              "| in-memory s | in-memory peak MB | identical |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& r : table) {
    const double mpx = r.w * static_cast<double>(r.h) / 1e6;
    std::printf("| %d | %dx%d | %.1f | %.2f | %.1f | %.1f | %.1f | %.0f | %s | %s | %s | %s |\n",
                r.mp, r.w, r.h, r.wall_s, r.wall_s / mpx, r.gather_s, r.choice_s, r.write_s,
                r.peak_kb / 1024.0, r.model.c_str(),
                r.mem_wall_s < 0 ? "-" : fmt::format("{:.1f}", r.mem_wall_s).c_str(),
                r.mem_peak_kb < 0 ? "-" : fmt::format("{:.0f}", r.mem_peak_kb / 1024.0).c_str(),
                r.identical.c_str());
  }
  return 0;
}
