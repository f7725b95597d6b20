// The reflectance fit's speed and memory. (1) Throughput of applying the fit (coefficients =
// P · samples, every pixel at once) beside a plain BLAS-style GEMM of the same shape (Eigen,
// float, same threads), in the same run. (2) The streamed fit of a whole session of radiance
// EXRs at 1, 6 (and with --max-mp 24, 24) megapixels x 40 poses: time and the peak resident
// memory of the process that fits (a child process, so the data generation is not counted).
//
// (3) The model at the last frame: the same sessions' maps kept in memory as they are written
// (MapStore::Add, what the capture does after each merge), then the model fitted from memory
// the moment the last map is in, beside the fit from the files, and the two models compared.
//
// With --families sh,pca (default sh), the same for the PCA family's session model
// (FitPcaHdrFromBands, what a session with [process] model_family = "pca" fits): from the
// maps in memory and from the files, the folders compared byte for byte, and its stages.
//
//   build/bench/fit_bench [--max-mp 6] [--dir /tmp] [--only-last-frame]
//                         [--scenes smooth,glossy] [--compressions zip,none] [--families sh,pca]
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "config/log.h"
#include "process/io/exr_io.h"
#include "process/io/image_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/session/map_store.h"
#include "process/model/session/model_stream.h"
#include "process/model/session/pca_session.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

// Dirty page-cache memory waiting to be written to the disk (/proc/meminfo), MB.
double DirtyMb() {
  std::FILE* f = std::fopen("/proc/meminfo", "r");
  if (f == nullptr) return -1;
  char line[256];
  double kb = -1;
  while (std::fgets(line, sizeof line, f) != nullptr)
    if (std::sscanf(line, "Dirty: %lf kB", &kb) == 1) break;
  std::fclose(f);
  return kb / 1024;
}

double Seconds(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

template <typename Fn>
double Median(int repeat, Fn&& fn) {
  std::vector<double> t;
  for (int i = 0; i < repeat; ++i) {
    const auto a = Clock::now();
    fn();
    t.push_back(Seconds(a));
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

std::vector<rig::Vec3> GridDirections(std::vector<double>* h, std::vector<double>* v) {
  std::vector<rig::Vec3> d;
  for (int vv = 0; vv <= 30; vv += 10)
    for (int hh = 0; hh <= 90; hh += 10) {
      d.push_back(rig::LightDirection(hh, vv));
      h->push_back(hh);
      v->push_back(vv);
    }
  return d;
}


// Largest |a - b| over every channel of two EXR files of one size (read in bands of rows).
double MaxDifference(const std::string& a_path, const std::string& b_path) {
  Imf::InputFile a(a_path.c_str(), 2), b(b_path.c_str(), 2);
  const Imath::Box2i dw = a.header().dataWindow();
  const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
  std::vector<std::string> names;
  for (auto it = a.header().channels().begin(); it != a.header().channels().end(); ++it)
    names.push_back(it.name());
  double worst = 0;
  const int band = 64;
  std::vector<float> ba, bb;
  for (int y0 = 0; y0 < h; y0 += band) {
    const int rows = std::min(band, h - y0);
    const size_t plane = size_t(w) * rows;
    ba.assign(plane * names.size(), 0.f);
    bb.assign(plane * names.size(), 0.f);
    Imf::FrameBuffer fa, fb;
    for (size_t c = 0; c < names.size(); ++c) {
      char* pa = reinterpret_cast<char*>(ba.data() + c * plane) - (ptrdiff_t(y0) * w) * 4;
      char* pb = reinterpret_cast<char*>(bb.data() + c * plane) - (ptrdiff_t(y0) * w) * 4;
      fa.insert(names[c], Imf::Slice(Imf::FLOAT, pa, 4, 4 * size_t(w)));
      fb.insert(names[c], Imf::Slice(Imf::FLOAT, pb, 4, 4 * size_t(w)));
    }
    a.setFrameBuffer(fa);
    b.setFrameBuffer(fb);
    a.readPixels(y0, y0 + rows - 1);
    b.readPixels(y0, y0 + rows - 1);
    for (size_t i = 0; i < ba.size(); ++i) worst = std::max(worst, double(std::fabs(ba[i] - bb[i])));
  }
  return worst;
}

// The process's peak resident memory (VmHWM), MB.
double PeakRssMb() {
  double hwm_kb = 0;
  if (std::FILE* st = std::fopen("/proc/self/status", "r")) {
    char line[256];
    while (std::fgets(line, sizeof line, st))
      if (std::sscanf(line, "VmHWM: %lf kB", &hwm_kb) == 1) break;
    std::fclose(st);
  }
  return hwm_kb / 1024.0;
}

// A glossy session's map at lamp direction l: Lambertian on random normals plus a Phong lobe
// (so the order choice goes past 1), as BGR float radiance.
cv::Mat GlossyMap(const cv::Mat& nx, const cv::Mat& ny, const cv::Mat& nz, const rig::Vec3& l) {
  cv::Mat ndl = nx * float(l[0]) + ny * float(l[1]) + nz * float(l[2]);
  cv::Mat lobe = cv::max(2.0f * ndl.mul(nz) - float(l[2]), 0.0f), spec;
  cv::pow(lobe, 12.0, spec);
  cv::Mat r = cv::max(ndl, 0.0f) * 0.6f + spec * 0.8f + 0.02f;
  cv::Mat rgb;
  cv::merge(std::vector<cv::Mat>{r, r * 0.9f + spec * 0.1f, r * 0.8f + spec * 0.2f}, rgb);
  return rgb;
}

// Writes `image` (every channel as half) with one compression; returns seconds.
double WriteWith(const rig::ExrImage& image, const std::string& path, Imf::Compression c, int zip_level) {
  const auto t = Clock::now();
  Imf::Header header(image.width, image.height, 1.0f, Imath::V2f(0, 0), 1.0f, Imf::INCREASING_Y, c);
  if (zip_level > 0) header.zipCompressionLevel() = zip_level;
  std::vector<cv::Mat> halves(image.channels.size());
  Imf::FrameBuffer fb;
  for (size_t i = 0; i < image.channels.size(); ++i) {
    header.channels().insert(image.channel_names[i], Imf::Channel(Imf::HALF));
    image.channels[i].convertTo(halves[i], CV_16F);
    fb.insert(image.channel_names[i], Imf::Slice(Imf::HALF, reinterpret_cast<char*>(halves[i].data), 2,
                                                 2 * size_t(image.width)));
  }
  {
    Imf::OutputFile out(path.c_str(), header, 2);
    out.setFrameBuffer(fb);
    out.writePixels(image.height);
  }
  return Seconds(t);
}

std::string FileBytes(const fs::path& p) {
  std::FILE* f = std::fopen(p.c_str(), "rb");
  if (f == nullptr) return {};
  std::string out;
  char buf[1 << 16];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) out.append(buf, n);
  std::fclose(f);
  return out;
}

// Whether two folders hold the same files, byte for byte.
bool SameFolders(const fs::path& a, const fs::path& b) {
  size_t na = 0, nb = 0;
  for (const auto& e : fs::directory_iterator(a)) {
    ++na;
    if (FileBytes(e.path()) != FileBytes(b / e.path().filename())) return false;
  }
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(b)) ++nb;
  return na == nb && na > 0;
}

// The PCA family's session model at the last frame: from the maps in memory (timed from the
// last map), then from the files; one table row.
bool PcaLastFrame(const rig::MapStore& store, const std::vector<std::string>& keys,
                  const rig::StreamFitInput& in, const fs::path& folder, int mp,
                  const std::string& scene) {
  rig::PcaHdrChoiceOptions o;
  o.threads = 2;
  if (std::getenv("RIG_BENCH_NO_SYNC") == nullptr) ::sync();
  auto t = Clock::now();
  auto bands = store.Bands(keys);
  if (!bands.ok()) return false;
  auto mem = rig::FitPcaHdrFromBands(**bands, in.directions, in.lamp_radiance_rgb, in.light_frame, o,
                                     (folder / "pca-memory").string());
  const double after_last = Seconds(t);
  if (!mem.ok()) {
    std::fprintf(stderr, "%s\n", mem.error().ToString().c_str());
    return false;
  }
  const double rss = PeakRssMb();
  if (std::getenv("RIG_BENCH_NO_SYNC") == nullptr) ::sync();
  t = Clock::now();
  auto files_bands = rig::OpenMapFiles(in.paths);
  if (!files_bands.ok()) return false;
  auto files = rig::FitPcaHdrFromBands(**files_bands, in.directions, in.lamp_radiance_rgb,
                                       in.light_frame, o, (folder / "pca-files").string());
  const double batch = Seconds(t);
  if (!files.ok()) return false;
  const bool same = SameFolders(folder / "pca-memory", folder / "pca-files");
  double bytes = 0;
  for (const auto& e : fs::directory_iterator(folder / "pca-memory")) bytes += double(e.file_size());
  const double pixels = double(mem->width) * mem->height;
  std::printf("  %-7s %-7s pca k%-2d %5.2f B/px  after last map %7.2f s (choice %.2f on %dx%d, sample "
              "%.2f, planes %.2f: codes %.2f solve %.2f JPEG %.2f)  from files %7.2f s  same bytes: %s  peak RSS %.0f MB\n",
              (std::to_string(mp) + " MP").c_str(), scene.c_str(), mem->components, bytes / pixels,
              after_last, mem->choice_s, mem->choice_region.width, mem->choice_region.height,
              mem->gather_s, mem->write_s, mem->planes.source_s, mem->planes.solve_s,
              mem->planes.encode_s, batch, same ? "yes" : "NO", rss);
  std::fflush(stdout);
  fs::remove_all(folder / "pca-files");
  fs::remove_all(folder / "pca-memory");
  return same;
}

}  // namespace

// The child: fits the session in `folder` (a separate process, started with exec, so that
// its peak memory is its own; fork() alone would inherit thread pools mid-use).
int FitOnly(const std::string& folder, const char* label) {
  std::vector<double> hs, vs;
  const auto dirs = GridDirections(&hs, &vs);
  rig::StreamFitInput in;
  for (size_t i = 0; i < dirs.size(); ++i) in.paths.push_back(folder + "/pose" + std::to_string(i) + ".exr");
  in.directions = dirs;
  in.weights = rig::GridQuadratureWeights(hs, vs);
  rig::FitOptions o;
  o.threads = 2;
  const auto t0 = Clock::now();
  auto out = rig::FitModelStreaming(in, o, folder + "/model.exr", rig::ExrPixelType::kHalf);
  if (!out.ok()) {
    std::fprintf(stderr, "%s\n", out.error().ToString().c_str());
    return 1;
  }
  (void)label;
  std::FILE* f = std::fopen((folder + "/time.txt").c_str(), "w");
  if (!f) return 1;
  // VmHWM: this process image's own peak resident memory (ru_maxrss would also count what
  // the parent held when it started us).
  std::fprintf(f, "%.3f %.0f\n", Seconds(t0), PeakRssMb() * 1024.0);
  std::fclose(f);
  return 0;
}

extern char** environ;

int main(int argc, char** argv) {
  if (argc == 4 && std::string(argv[1]) == "--fit-only") {
    rig::SetLogLevel("warn");
    return FitOnly(argv[2], argv[3]);
  }
  int max_mp = 6;
  bool only_last_frame = false;
  std::vector<std::string> scenes = {"smooth", "glossy"}, compressions = {"zip", "none"},
                           families = {"sh"};
  auto split = [](const std::string& list) {
    std::vector<std::string> out;
    std::string item;
    for (char c : list + ",") {
      if (c != ',') {
        item += c;
      } else if (!item.empty()) {
        out.push_back(item);
        item.clear();
      }
    }
    return out;
  };
  std::string dir = fs::temp_directory_path().string();
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--only-last-frame") {
      only_last_frame = true;
      continue;
    }
    if (i + 1 >= argc) break;
    if (k == "--max-mp") max_mp = std::atoi(argv[++i]);
    if (k == "--dir") dir = argv[++i];
    if (k == "--scenes") scenes = split(argv[++i]);
    if (k == "--compressions") compressions = split(argv[++i]);
    if (k == "--families") families = split(argv[++i]);
  }
  const bool with_sh = std::find(families.begin(), families.end(), "sh") != families.end();
  const bool with_pca = std::find(families.begin(), families.end(), "pca") != families.end();
  rig::SetLogLevel(std::getenv("RIG_LOG_LEVEL") ? "" : "warn");
  rig::ReuseFreedImageMemory();  // as rig itself does at start
  std::vector<double> hs, vs;
  const auto dirs = GridDirections(&hs, &vs);
  const auto weights = rig::GridQuadratureWeights(hs, vs);
  const int poses = static_cast<int>(dirs.size());

  // ---- (1) applying the fit against a GEMM of the same shape ----
  if (!only_last_frame) {
    const int order = 3;
    const rig::Basis basis(rig::BasisKind::kSh, order);
    auto pr = rig::BuildProjector(basis, dirs, weights, rig::FitMethod::kRls, 1e-4, 1e12);
    if (!pr.ok()) return 1;
    const Eigen::Index cols = 1'000'000 * 3;  // 1 MP x 3 channels
    rig::SampleMatrix samples(poses, cols), coefficients;
    samples.setRandom();
    std::vector<uint8_t> missing, valid;
    const double ours = Median(5, [&] {
      rig::ApplyProjector(*pr, dirs, weights, 1e12, samples, missing, &coefficients, &valid);
    });
    Eigen::MatrixXf p = pr->p.cast<float>();
    rig::SampleMatrix out(basis.size(), cols);
    const double gemm = Median(5, [&] { out.noalias() = p * samples; });
    const double flops = 2.0 * basis.size() * poses * cols;
    std::printf("applying the fit: %d terms x %d poses x 1 MP x 3 channels (float, %d Eigen threads)\n",
                basis.size(), poses, Eigen::nbThreads());
    std::printf("  %-36s %8.1f ms  %6.2f GFLOP/s\n", "peer: GEMM of the same shape", gemm * 1e3, flops / gemm / 1e9);
    std::printf("  %-36s %8.1f ms  %6.2f GFLOP/s  (%.2fx the GEMM)\n", "ours: ApplyProjector", ours * 1e3,
                flops / ours / 1e9, ours / gemm);
  }

  // ---- (2) streamed fits of whole sessions ----
  std::printf("\nstreamed fit of a 40-pose session of half-float radiance EXRs (order auto, rls)\n");
  std::printf("  %-10s %12s %12s %14s %14s\n", "size", "input GB", "fit s", "peak RSS MB", "in-memory GB");
  for (int mp : {1, 6, 24}) {
    if (mp > max_mp || only_last_frame) break;
    const int width = mp == 1 ? 1200 : mp == 6 ? 3000 : 6000;
    const int height = mp == 1 ? 834 : mp == 6 ? 2000 : 4000;
    const fs::path folder = fs::path(dir) / ("rig_fit_bench_" + std::to_string(mp) + "mp_" + std::to_string(getpid()));
    fs::create_directories(folder);
    std::vector<std::string> paths;
    double bytes = 0;
    // Smooth radiance varying with the lamp: a Lambertian-like field, cheap to generate.
    cv::Mat nx(height, width, CV_32F), ny(height, width, CV_32F);
    cv::randu(nx, -0.4, 0.4);
    cv::randu(ny, -0.4, 0.4);
    for (int i = 0; i < poses; ++i) {
      cv::Mat r = 0.5f + nx * static_cast<float>(dirs[i][0]) + ny * static_cast<float>(dirs[i][1]);
      cv::Mat rgb;
      cv::merge(std::vector<cv::Mat>{r, r * 0.9f, r * 0.8f}, rgb);
      const std::string p = (folder / ("pose" + std::to_string(i) + ".exr")).string();
      if (!rig::WriteRgbExr(p, rgb, {}, rig::ExrPixelType::kHalf).ok()) return 1;
      paths.push_back(p);
      bytes += static_cast<double>(fs::file_size(p));
    }
    const double in_memory = double(width) * height * 3 * 4 * poses / 1e9;
    std::fflush(stdout);
    const std::string self = fs::read_symlink("/proc/self/exe").string();
    const std::string label = std::to_string(mp) + " MP";
    const std::string folder_s = folder.string();
    char* child_argv[] = {const_cast<char*>(self.c_str()), const_cast<char*>("--fit-only"),
                          const_cast<char*>(folder_s.c_str()), const_cast<char*>(label.c_str()), nullptr};
    pid_t child = 0;
    if (posix_spawn(&child, self.c_str(), nullptr, nullptr, child_argv, environ) != 0) return 1;
    int status = 0;
    waitpid(child, &status, 0);
    double fit_s = 0, hwm_kb = 0;
    if (std::FILE* f = std::fopen((folder / "time.txt").c_str(), "r")) {
      if (std::fscanf(f, "%lf %lf", &fit_s, &hwm_kb) != 2) fit_s = 0;
      std::fclose(f);
    }
    std::printf("  %-10s %12.2f %12.2f %14.0f %14.2f\n", label.c_str(), bytes / 1e9, fit_s, hwm_kb / 1024.0,
                in_memory);
    fs::remove_all(folder);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) return 1;
  }

  // ---- (3) the model at the last frame ----
  std::printf("\nthe model at the last frame: 40-pose sessions, maps written as half EXRs and kept in "
              "memory as they arrive (order auto, rls, 2 threads;\n'after last map': from the last map "
              "in memory to the model renamed into place; 'from files': the same fit reading the "
              "maps back)\n");
  std::printf("  %-7s %-7s %-9s %6s %10s %9s %9s %16s %13s %11s %12s\n", "size", "scene", "model file",
              "terms", "keep s/map", "store GB", "dirty MB", "after last map s", "from files s",
              "max |diff|", "peak RSS MB");
  for (int mp : {1, 6, 24}) {
    if (mp > max_mp) break;
    const int width = mp == 1 ? 1200 : mp == 6 ? 3000 : 6000;
    const int height = mp == 1 ? 834 : mp == 6 ? 2000 : 4000;
    for (const std::string& scene : scenes) {
      const fs::path folder = fs::path(dir) / ("rig_fit_bench_last_" + std::to_string(mp) + "mp_" + std::to_string(getpid()));
      fs::create_directories(folder);
      // "smooth": the field of the streamed-fit table above (the same ±0.4 slopes); "glossy":
      // random normals (±0.5 tilt) under a Lambertian term and a Phong lobe.
      const float tilt = scene == "smooth" ? 0.4f : 0.5f;
      cv::Mat nx(height, width, CV_32F), ny(height, width, CV_32F), nz;
      cv::randu(nx, -tilt, tilt);
      cv::randu(ny, -tilt, tilt);
      cv::sqrt(1.0f - nx.mul(nx) - ny.mul(ny), nz);
      rig::MapStore store(rig::ExrPixelType::kHalf, dirs.size(), rig::MapStore::DefaultMaxBytes());
      // As a session plans it: the selection's Gram matrix accumulated as the maps arrive.
      std::map<std::string, rig::Vec3> planned;
      for (int i = 0; i < poses; ++i) planned["pose" + std::to_string(i)] = dirs[i];
      rig::StreamFitInput in;
      store.PlanSelectionGram(planned, in.lamp_radiance_rgb, rig::FitOptions{}.transform, in.light_frame);
      in.directions = dirs;
      in.weights = weights;
      std::vector<std::string> keys;
      double keep_s = 0;
      for (int i = 0; i < poses; ++i) {
        cv::Mat rgb;
        if (scene == "smooth") {
          cv::Mat r = 0.5f + nx * static_cast<float>(dirs[i][0]) + ny * static_cast<float>(dirs[i][1]);
          cv::merge(std::vector<cv::Mat>{r, r * 0.9f, r * 0.8f}, rgb);
        } else {
          rgb = GlossyMap(nx, ny, nz, dirs[i]);
        }
        const std::string p = (folder / ("pose" + std::to_string(i) + ".exr")).string();
        if (!rig::WriteRgbExr(p, rgb, {}, rig::ExrPixelType::kHalf).ok()) return 1;
        const auto t = Clock::now();
        if (!store.Add("pose" + std::to_string(i), rgb, cv::Mat()).ok()) return 1;
        keep_s += Seconds(t);
        in.paths.push_back(p);
        keys.push_back("pose" + std::to_string(i));
      }
      if (store.off()) {
        std::printf("  %-7s the maps do not fit in memory here: %s\n", (std::to_string(mp) + " MP").c_str(),
                    store.off_reason().c_str());
        fs::remove_all(folder);
        continue;
      }
      rig::FitOptions o;
      o.threads = 2;
      if (with_pca && !PcaLastFrame(store, keys, in, folder, mp, scene)) return 1;
      for (const std::string& compression : (with_sh ? compressions : std::vector<std::string>{})) {
        in.compression = *rig::ParseExrCompression(compression, /*lossy=*/true);
        const std::string from_memory = (folder / "memory.exr").string(), from_files = (folder / "files.exr").string();
        // The maps' files written just now are still being written back to the disk; in a
        // session they were written over minutes of capture. Let the disk catch up first, so
        // that the model's write is not throttled by the maps' (RIG_BENCH_NO_SYNC=1: don't).
        const double dirty_mb = DirtyMb();
        if (std::getenv("RIG_BENCH_NO_SYNC") == nullptr) ::sync();
        auto t = Clock::now();
        auto bands = store.Bands(keys);
        if (!bands.ok()) return 1;
        auto mem = rig::FitModelFromBands(**bands, in, o, from_memory, rig::ExrPixelType::kHalf);
        const double after_last = Seconds(t);
        if (!mem.ok()) {
          std::fprintf(stderr, "%s\n", mem.error().ToString().c_str());
          return 1;
        }
        if (std::getenv("RIG_BENCH_NO_SYNC") == nullptr) ::sync();
        t = Clock::now();
        auto files = rig::FitModelStreaming(in, o, from_files, rig::ExrPixelType::kHalf);
        const double batch = Seconds(t);
        if (!files.ok()) return 1;
        const double diff = MaxDifference(from_memory, from_files);
        std::printf("  %-7s %-7s %-9s %6d %10.3f %9.2f %9.0f %16.2f %13.2f %11.3g %12.0f\n",
                    (std::to_string(mp) + " MP").c_str(), scene.c_str(), compression.c_str(),
                    mem->selection.projector.basis.size(), keep_s / poses, store.bytes() / 1e9,
                    dirty_mb, after_last, batch, diff, PeakRssMb());
        std::fflush(stdout);
        fs::remove(from_files);
      }
      const std::string from_memory = (folder / "memory.exr").string();
      if (mp == 1 && scene == scenes.back() && with_sh) {
        // What the model's compression costs: the same coefficients written with each of
        // OpenEXR's lossless compressions for half (2 threads), and read back.
        auto model = rig::ReadExr(from_memory, 2);
        if (!model.ok()) return 1;
        std::printf("\n  the 1 MP model (%zu half channels) written with each lossless compression, 2 threads:\n",
                    model->channels.size());
        std::printf("  %-14s %10s %10s %10s %10s\n", "compression", "MB", "write s", "MB/s in", "read s");
        const double raw_mb = double(model->width) * model->height * model->channels.size() * 2 / 1e6;
        const struct {
          const char* name;
          Imf::Compression c;
          int level;
        } kinds[] = {{"none", Imf::NO_COMPRESSION, 0}, {"rle", Imf::RLE_COMPRESSION, 0},
                     {"zips", Imf::ZIPS_COMPRESSION, 0}, {"zip", Imf::ZIP_COMPRESSION, 0},
                     {"zip level 1", Imf::ZIP_COMPRESSION, 1}, {"zip level 4", Imf::ZIP_COMPRESSION, 4},
                     {"piz", Imf::PIZ_COMPRESSION, 0}, {"pxr24", Imf::PXR24_COMPRESSION, 0}};
        const std::string out = (folder / "compressed.exr").string();
        rig::SetExrThreads(2);
        for (const auto& k : kinds) {
          double w = 1e30, r = 1e30;
          for (int rep = 0; rep < 2; ++rep) {
            w = std::min(w, WriteWith(*model, out, k.c, k.level));
            const auto t0 = Clock::now();
            if (!rig::ReadExr(out, 2).ok()) return 1;
            r = std::min(r, Seconds(t0));
          }
          std::printf("  %-14s %10.1f %10.3f %10.0f %10.3f\n", k.name, fs::file_size(out) / 1e6, w,
                      raw_mb / w, r);
        }
      }
      fs::remove_all(folder);
    }
  }
  return 0;
}
