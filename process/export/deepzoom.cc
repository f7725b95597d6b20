// Deep-zoom pyramids: each plane file decoded once, halved level by level, tiles encoded in
// memory and written without a per-tile fsync; files in parallel.
#include "process/export/deepzoom.h"
#include "config/atomic_file.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "config/console.h"
#include "process/io/jpeg_io.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

// A tile or descriptor: not fsync'd one by one (a level holds thousands); the folder they are
// in is published whole (rig view, rig export --format relight).
Status WriteBytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  return WriteFileAtomic(path, std::span<const uint8_t>(bytes.data(), bytes.size()),
                         /*overwrite=*/true, /*sync=*/false);
}

// The 2×2 box average, rounded; an odd last row/column averages what there is.
cv::Mat Halve(const cv::Mat& in) {
  const int w = (in.cols + 1) / 2, h = (in.rows + 1) / 2, ch = in.channels();
  cv::Mat out(h, w, in.type());
  for (int y = 0; y < h; ++y) {
    const uint8_t* r0 = in.ptr<uint8_t>(2 * y);
    const uint8_t* r1 = in.ptr<uint8_t>(std::min(2 * y + 1, in.rows - 1));
    const int ny = 2 * y + 1 < in.rows ? 2 : 1;
    uint8_t* o = out.ptr<uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      const int x0 = 2 * x, x1 = std::min(2 * x + 1, in.cols - 1), nx = 2 * x + 1 < in.cols ? 2 : 1;
      const int n = nx * ny;
      for (int k = 0; k < ch; ++k) {
        int s = r0[x0 * ch + k] + (nx == 2 ? r0[x1 * ch + k] : 0);
        if (ny == 2) s += r1[x0 * ch + k] + (nx == 2 ? r1[x1 * ch + k] : 0);
        o[x * ch + k] = static_cast<uint8_t>((s + n / 2) / n);
      }
    }
  }
  return out;
}

Result<long> TileOne(const fs::path& plane, const DeepZoomOptions& o, int* levels_out) {
  const std::string stem = plane.stem().string();
  const fs::path dzi = plane.parent_path() / (stem + ".dzi");
  const fs::path files = plane.parent_path() / (stem + "_files");
  std::error_code ec;
  if (fs::exists(dzi, ec) || fs::exists(files, ec)) {
    return MakeError(ErrorCode::kInvalidInput, dzi.string(), "exists (nothing is overwritten)");
  }
  RIG_ASSIGN_OR_RETURN(auto reader, JpegReader::Open(plane.string()));
  const int W = reader->width(), H = reader->height();
  cv::Mat image;
  RIG_TRY(reader->Read(H, &image));
  const JpegColor color = image.channels() == 1 ? JpegColor::kGray : JpegColor::kYcbcr;
  // The plane's own colour space is kept: RGB-space planes (an Adobe marker) stay RGB.
  const bool rgb_space = reader->channels() == 3 && reader->rgb_space();
  const int max_level = static_cast<int>(std::ceil(std::log2(std::max(W, H))));
  *levels_out = max_level + 1;
  long count = 0;
  cv::Mat level = image;
  for (int L = max_level; L >= 0; --L) {
    if (L != max_level) level = Halve(level);
    const fs::path dir = files / std::to_string(L);
    fs::create_directories(dir, ec);
    if (ec) return MakeError(ErrorCode::kIo, dir.string(), "cannot create: {}", ec.message());
    const int T = o.tile_size, ov = o.overlap;
    for (int ty = 0; ty * T < level.rows; ++ty)
      for (int tx = 0; tx * T < level.cols; ++tx) {
        const int x0 = std::max(0, tx * T - ov), y0 = std::max(0, ty * T - ov);
        const int x1 = std::min(level.cols, (tx + 1) * T + ov), y1 = std::min(level.rows, (ty + 1) * T + ov);
        const cv::Mat tile = level(cv::Rect(x0, y0, x1 - x0, y1 - y0)).clone();
        RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes,
                             EncodeJpeg(tile, rgb_space ? JpegColor::kRgb : color, o.quality));
        RIG_TRY(WriteBytes(dir / fmt::format("{}_{}.jpg", tx, ty), bytes));
        ++count;
      }
  }
  const std::string xml = fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
      "<Image xmlns=\"http://schemas.microsoft.com/deepzoom/2008\" Format=\"jpg\" Overlap=\"{}\" "
      "TileSize=\"{}\">\n  <Size Width=\"{}\" Height=\"{}\"/>\n</Image>\n",
      o.overlap, o.tile_size, W, H);
  RIG_TRY(WriteBytes(dzi, std::vector<uint8_t>(xml.begin(), xml.end())));
  return count;
}

}  // namespace

bool WantsDeepZoom(int width, int height) { return std::max(width, height) > 4096; }

Result<DeepZoomReport> WriteDeepZoom(const std::string& folder, const DeepZoomOptions& o) {
  if (o.tile_size < 16 || o.tile_size > 4096 || o.overlap < 0 || o.overlap > 16) {
    return MakeError(ErrorCode::kInvalidInput, folder, "tile size {} / overlap {} outside 16..4096 / 0..16",
                     o.tile_size, o.overlap);
  }
  const auto start = std::chrono::steady_clock::now();
  std::vector<fs::path> planes;
  for (int j = 0; fs::exists(fs::path(folder) / fmt::format("plane_{}.jpg", j)); ++j)
    planes.push_back(fs::path(folder) / fmt::format("plane_{}.jpg", j));
  if (planes.empty()) return MakeError(ErrorCode::kNotFound, folder, "no plane_0.jpg to tile");
  DeepZoomReport report;
  report.files = static_cast<int>(planes.size());
  std::vector<Result<long>> results(planes.size(), MakeError(ErrorCode::kInternal, folder, "not tiled"));
  std::vector<int> levels(planes.size(), 0);
  std::atomic<size_t> next{0};
  // A bar on a terminal, a line every few seconds elsewhere (the planes of a 24 MP model take
  // minutes).
  ProgressTask task("deep-zoom tiles", static_cast<int64_t>(planes.size()));
  auto work = [&] {
    for (size_t i; (i = next++) < planes.size();) {
      results[i] = TileOne(planes[i], o, &levels[i]);
      task.Advance(1, planes[i].filename().string());
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, o.threads); ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  for (auto& r : results) {
    if (!r.ok()) return r.error();
    report.tiles += *r;
  }
  report.levels = levels[0];
  report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace rig
