// The whole `rig hdr` job (decode, response recovery, merge, EXR written and fsynced) beside
// OpenCV's whole equivalent (cv::imread of each frame, CalibrateDebevec, MergeDebevec,
// cv::imwrite EXR), each a fresh process on the same JPEG bracket on disk, interleaved in one
// run. Usage: hdr_job_bench [--width W --height H --frames N --repeat R --threads T]
//                           [--rig PATH] [--dir DIR] [--ours "ARGS"]... [--before PATH] [--keep]
// Each --ours adds a row: `rig hdr` with those extra arguments (default: one row, no extras);
// --before adds a row of another rig executable (e.g. built from an earlier commit), as it is.
// Internal: hdr_job_bench --opencv-job LIST OUT [--reuse-memory] [--exr-threads N]
//           [--exr-none] runs OpenCV's job once.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/photo.hpp>

#include <ImfThreading.h>

#include "process/hdr/hdr.h"
#include "process/io/exr_io.h"
#include "process/io/image_io.h"
#include "sim/bracket_synth.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// OpenCV's whole job, as a program using OpenCV would write it; prints the stage times in
// the format `rig hdr` prints them. The helps given to it: glibc keeping freed memory (what
// rig does), OpenEXR's global thread pool (cv::imwrite's EXR writer uses it; OpenCV leaves it
// at 0 threads) and no compression (IMWRITE_EXR_COMPRESSION).
int OpenCvJob(const std::string& list, const std::string& out, bool reuse_memory,
              int exr_threads, bool exr_none) {
  if (reuse_memory) rig::ReuseFreedImageMemory();
  if (exr_threads > 0) Imf::setGlobalThreadCount(exr_threads);
  cv::setNumThreads(2);
  auto t0 = Clock::now();
  std::ifstream in(list);
  std::vector<cv::Mat> images;
  std::vector<float> times;
  std::string file;
  double t = 0;
  const fs::path folder = fs::path(list).parent_path();
  while (in >> file >> t) {
    images.push_back(cv::imread((folder / file).string(), cv::IMREAD_COLOR));
    if (images.back().empty()) {
      std::fprintf(stderr, "opencv job: cannot read %s\n", file.c_str());
      return 1;
    }
    times.push_back(float(t));
  }
  const cv::Mat tm(int(times.size()), 1, CV_32F, times.data());
  const double decode_s = Since(t0);
  t0 = Clock::now();
  cv::Mat response, hdr;
  cv::createCalibrateDebevec()->process(images, response, tm);
  const double response_s = Since(t0);
  t0 = Clock::now();
  cv::createMergeDebevec()->process(images, hdr, tm, response);
  const double merge_s = Since(t0);
  t0 = Clock::now();
  std::vector<int> params;
  if (exr_none) params = {cv::IMWRITE_EXR_COMPRESSION, cv::IMWRITE_EXR_COMPRESSION_NO};
  if (!cv::imwrite(out, hdr, params)) {
    std::fprintf(stderr, "opencv job: cannot write %s\n", out.c_str());
    return 1;
  }
  const double write_s = Since(t0);
  std::printf("%s: decode %.3f s, response %.3f s, merge %.3f s, write %.3f s\n", out.c_str(),
              decode_s, response_s, merge_s, write_s);
  return 0;
}

struct Run {
  double wall = 0;
  double stage[4] = {0, 0, 0, 0};  // decode, response, merge, write as the process reports them
};

// Runs a command line, returns its wall-clock time and the stage times it printed.
bool RunJob(const std::string& command, Run* run) {
  const auto t0 = Clock::now();
  FILE* p = ::popen(command.c_str(), "r");
  if (!p) return false;
  std::string text;
  char buf[4096];
  while (size_t n = std::fread(buf, 1, sizeof buf, p)) text.append(buf, n);
  const int rc = ::pclose(p);
  run->wall = Since(t0);
  if (rc != 0) {
    std::fprintf(stderr, "failed (%d): %s\n%s", rc, command.c_str(), text.c_str());
    return false;
  }
  const size_t at = text.find("decode ");
  if (at == std::string::npos ||
      std::sscanf(text.c_str() + at, "decode %lf s, response %lf s, merge %lf s, write %lf s",
                  &run->stage[0], &run->stage[1], &run->stage[2], &run->stage[3]) != 4) {
    std::fprintf(stderr, "no stage times in the output of %s:\n%s", command.c_str(), text.c_str());
    return false;
  }
  return true;
}

struct Row {
  std::string name, command, out;
  std::vector<Run> runs;
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
double Best(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }
std::vector<double> Column(const Row& r, int stage) {  // stage -1: wall
  std::vector<double> v;
  for (const Run& x : r.runs) v.push_back(stage < 0 ? x.wall : x.stage[stage]);
  return v;
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 4 && std::string(argv[1]) == "--opencv-job") {
    bool reuse = false, none = false;
    int exr_threads = 0;
    for (int i = 4; i < argc; ++i) {
      const std::string a = argv[i];
      if (a == "--reuse-memory") reuse = true;
      if (a == "--exr-none") none = true;
      if (a == "--exr-threads" && i + 1 < argc) exr_threads = std::atoi(argv[++i]);
    }
    return OpenCvJob(argv[2], argv[3], reuse, exr_threads, none);
  }
  int width = 3000, height = 2000, frames = 10, repeat = 5, threads = 2;
  std::string rig_path, dir, before;
  std::vector<std::string> ours_args;
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { return i + 1 < argc ? std::string(argv[++i]) : std::string(); };
    if (a == "--width") width = std::atoi(next().c_str());
    else if (a == "--height") height = std::atoi(next().c_str());
    else if (a == "--frames") frames = std::atoi(next().c_str());
    else if (a == "--repeat") repeat = std::max(1, std::atoi(next().c_str()));
    else if (a == "--threads") threads = std::max(1, std::atoi(next().c_str()));
    else if (a == "--rig") rig_path = next();
    else if (a == "--dir") dir = next();
    else if (a == "--ours") ours_args.push_back(next());
    else if (a == "--before") before = next();
    else if (a == "--keep") keep = true;
    else {
      std::fprintf(stderr, "usage: hdr_job_bench [--width W] [--height H] [--frames N] "
                           "[--repeat R] [--threads T] [--rig PATH] [--dir DIR] "
                           "[--ours \"ARGS\"]... [--before PATH] [--keep]\n");
      return 2;
    }
  }
  const fs::path self = fs::canonical("/proc/self/exe");
  if (rig_path.empty()) rig_path = (self.parent_path().parent_path() / "rig" / "rig").string();
  if (!fs::exists(rig_path)) {
    std::fprintf(stderr, "hdr_job_bench: no rig executable at %s (--rig PATH)\n", rig_path.c_str());
    return 2;
  }
  if (ours_args.empty()) ours_args.push_back("");
  // On the disk by default (not a tmpfs: the fsync must cost what it costs).
  const fs::path work = dir.empty() ? fs::current_path() / fmt::format("hdr_job_bench_{}", ::getpid())
                                    : fs::path(dir);
  fs::create_directories(work);

  // The bracket: the synthetic scene through a filmic response with shot and read noise,
  // saved as JPEG q95 (as a camera would), with its list.
  const rig::synth::FilmicResponse film;
  const cv::Mat truth = rig::synth::SyntheticRadiance(width, height);
  const rig::Bracket b = rig::synth::RenderBracket(
      truth, rig::synth::ExposuresFor(0.01, 300.0, frames), film, 7, 5e-5, 2.5e-4, CV_8U, threads);
  const std::string list = (work / "bracket.txt").string();
  {
    std::ofstream l(list);
    for (size_t j = 0; j < b.size(); ++j) {
      const std::string name = fmt::format("frame_{:02d}.jpg", j);
      cv::imwrite((work / name).string(), b[j].image, {cv::IMWRITE_JPEG_QUALITY, 95});
      l << name << ' ' << fmt::format("{:.9g}", b[j].exposure.count()) << '\n';
    }
  }
  // The decoded frames, for the error measure (what both sides read).
  auto decoded = rig::LoadBracketList(list, threads);
  if (!decoded.ok()) {
    std::fprintf(stderr, "%s\n", decoded.error().ToString().c_str());
    return 1;
  }

  std::vector<Row> rows;
  if (!before.empty()) {
    Row r;
    r.name = "before: " + fs::path(before).filename().string() + " hdr";
    r.out = (work / "before.exr").string();
    r.command = fmt::format("{} hdr --list {} --out {} --threads {}", Quote(before), Quote(list),
                            Quote(r.out), threads);
    rows.push_back(r);
  }
  for (size_t k = 0; k < ours_args.size(); ++k) {
    Row r;
    r.name = ours_args[k].empty() ? "rig hdr" : "rig hdr " + ours_args[k];
    r.out = (work / fmt::format("ours_{}.exr", k)).string();
    r.command = fmt::format("{} hdr --list {} --out {} --threads {} {}", Quote(rig_path),
                            Quote(list), Quote(r.out), threads, ours_args[k]);
    rows.push_back(r);
  }
  // OpenCV as it comes (the reference of the ratios), then helped: freed memory kept and
  // OpenEXR's pool on `threads` threads (still ZIP), and the same with no compression.
  const std::pair<const char*, std::string> cv_rows[] = {
      {"OpenCV (its defaults: ZIP, 1 EXR thread)", ""},
      {"OpenCV + memory reuse + EXR threads", fmt::format(" --reuse-memory --exr-threads {}", threads)},
      {"OpenCV + the same, no compression",
       fmt::format(" --reuse-memory --exr-threads {} --exr-none", threads)}};
  const size_t first_cv = rows.size();
  for (size_t k = 0; k < std::size(cv_rows); ++k) {
    Row r;
    r.name = cv_rows[k].first;
    r.out = (work / fmt::format("opencv_{}.exr", k)).string();
    r.command = fmt::format("{} --opencv-job {} {}{}", Quote(self.string()), Quote(list),
                            Quote(r.out), cv_rows[k].second);
    rows.push_back(r);
  }

  std::printf("hdr_job_bench: %dx%d (%.1f MP) x %d JPEG q95 frames in %s, threads %d, %d runs "
              "each, interleaved\n",
              width, height, width * height / 1e6, frames, work.c_str(), threads, repeat);
  std::printf("ours: %s hdr (a fresh process each run: decode, response recovery, merge, EXR "
              "written, fsynced, renamed)\nOpenCV: a fresh process each run: cv::imread x %d, "
              "CalibrateDebevec, MergeDebevec, cv::imwrite (EXR, its defaults)\n\n",
              rig_path.c_str(), frames);
  // Interleaved: every round runs each row once, the order rotating, so that whatever else the
  // machine does falls on all rows alike.
  for (int round = 0; round < repeat; ++round) {
    for (size_t i = 0; i < rows.size(); ++i) {
      Row& r = rows[(i + round) % rows.size()];
      Run run;
      if (!RunJob(r.command, &run)) return 1;
      r.runs.push_back(run);
    }
  }

  const Row& cv_row = rows[first_cv];
  const double cv_best = Best(Column(cv_row, -1)), cv_med = Median(Column(cv_row, -1));
  std::printf("%-44s %7s %7s   %-33s   %-15s   %6s %8s\n", "whole job (wall clock, s)", "best",
              "median", "median decode/response/merge/write", "OpenCV/ours b,m", "EXR MB",
              "log RMS");
  for (const Row& r : rows) {
    const double best = Best(Column(r, -1)), med = Median(Column(r, -1));
    std::string err = "-";
    if (auto img = rig::ReadRgbExr(r.out); img.ok()) {
      err = fmt::format("{:.4f}", rig::synth::LogRmsError(*img, truth, *decoded));
    }
    std::printf("%-44s %7.3f %7.3f   %6.3f / %6.3f / %6.3f / %6.3f   %6.2fx %6.2fx   %6.1f %8s\n",
                r.name.c_str(), best, med, Median(Column(r, 0)), Median(Column(r, 1)),
                Median(Column(r, 2)), Median(Column(r, 3)), cv_best / best, cv_med / med,
                fs::file_size(r.out) / 1e6, err.c_str());
  }
  std::printf("\nwall clock includes process start (loading the libraries) and, for ours, the "
              "fsync; log RMS: log-radiance error against the known radiance (hdr_bench's "
              "measure)\n");

  // Each compression on the map of this bracket, in this process (as `rig` runs: freed memory
  // reused): write (fsync and rename included) and read back, `threads` OpenEXR threads.
  rig::ReuseFreedImageMemory();
  const rig::Bracket one[1] = {*decoded};
  rig::ResponseOptions ro;
  ro.threads = threads;
  rig::MergeOptions mo;
  mo.threads = threads;
  auto response = rig::RecoverResponse(one, ro);
  auto map = response.ok() ? rig::MergeBracket(*decoded, *response, mo)
                           : rig::Result<rig::RadianceMap>(response.error());
  if (!map.ok()) {
    std::fprintf(stderr, "%s\n", map.error().ToString().c_str());
    return 1;
  }
  std::printf("\nEXR COMPRESSION (the map above: R,G,B + flags, %d threads, best of %d; write "
              "includes fsync + rename)\n%-10s %-6s %8s %9s %9s %9s\n",
              threads, repeat, "compression", "pixels", "MB", "write s", "read s", "MB/s written");
  const std::string path = (work / "table.exr").string();
  for (auto type : {rig::ExrPixelType::kFloat, rig::ExrPixelType::kHalf}) {
    for (const std::string& name : rig::ExrCompressionNames()) {
      const rig::ExrCompression c = *rig::ParseExrCompression(name);
      std::vector<double> w, r;
      for (int i = 0; i < repeat; ++i) {
        auto t0 = Clock::now();
        if (auto st = rig::WriteRadianceMap(path, *map, type, threads, c); !st.ok()) {
          std::fprintf(stderr, "%s\n", st.error().ToString().c_str());
          return 1;
        }
        w.push_back(Since(t0));
        t0 = Clock::now();
        if (!rig::ReadExr(path, threads).ok()) return 1;
        r.push_back(Since(t0));
      }
      const double mb = fs::file_size(path) / 1e6;
      std::printf("%-11s %-6s %8.1f %9.3f %9.3f %9.0f\n", name.c_str(),
                  type == rig::ExrPixelType::kHalf ? "half" : "float", mb, Best(w), Best(r),
                  mb / Best(w));
    }
  }
  if (!keep) fs::remove_all(work);
  return 0;
}
