// Decoding camera files into BGR frames (in parallel over a bracket) and reading bracket lists.
#include "process/io/image_io.h"
#include "process/io/raw_io.h"

#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "config/atomic_file.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

bool EndsWithJpegEoi(const std::vector<uchar>& bytes) {
  // Some bodies pad the file after the end-of-image marker; look at the last few bytes.
  const size_t n = bytes.size();
  const size_t from = n > 64 ? n - 64 : 0;
  for (size_t i = n; i-- > from + 1;) {
    if (bytes[i - 1] == 0xFF && bytes[i] == 0xD9) return true;
  }
  return false;
}

bool HasPngIend(const std::vector<uchar>& bytes) {
  // The IEND chunk is 12 bytes: length 0, "IEND", CRC.
  if (bytes.size() < 20) return false;
  const size_t n = bytes.size();
  const size_t from = n > 64 ? n - 64 : 0;
  for (size_t i = from; i + 4 <= n; ++i) {
    if (std::memcmp(&bytes[i], "IEND", 4) == 0) return true;
  }
  return false;
}

Result<std::vector<uchar>> ReadAll(const std::string& path) {
  std::error_code ec;
  if (path.find('\0') != std::string::npos)
    return MakeError(ErrorCode::kInvalidInput, path, "a file name with a NUL byte");
  if (!fs::exists(path, ec)) return MakeError(ErrorCode::kNotFound, path, "no such file");
  // A folder opens as a stream whose size reads as 2^63 - 1 (found by tests/fuzz/list).
  if (!fs::is_regular_file(path, ec))
    return MakeError(ErrorCode::kInvalidInput, path, "not a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    return MakeError(ErrorCode::kIo, path, "cannot open: {}", std::strerror(errno));
  }
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  in.seekg(0, std::ios::beg);
  if (size <= 0) return MakeError(ErrorCode::kInvalidInput, path, "empty file");
  std::vector<uchar> bytes(static_cast<size_t>(size));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), size)) {
    return MakeError(ErrorCode::kIo, path, "read failed");
  }
  return bytes;
}

// Parses an exposure time: "0.004", "4e-3" or "1/250" (seconds).
bool ParseExposure(const std::string& text, double* seconds) {
  auto parse = [](const std::string& s, double* v) {
    const char* end = s.data() + s.size();
    auto r = std::from_chars(s.data(), end, *v);
    return r.ec == std::errc() && r.ptr == end;
  };
  const size_t slash = text.find('/');
  if (slash == std::string::npos) return parse(text, seconds);
  double num = 0, den = 0;
  if (!parse(text.substr(0, slash), &num) || !parse(text.substr(slash + 1), &den) || den == 0) {
    return false;
  }
  *seconds = num / den;
  return true;
}

}  // namespace

void ParallelFor(int n, int threads, const std::function<void(int, int)>& fn, int min_chunk) {
  if (n <= 0) return;
  threads = std::clamp(threads, 1, 64);
  min_chunk = std::max(min_chunk, 1);
  if (threads == 1 || n <= min_chunk) {
    fn(0, n);
    return;
  }
  // Several chunks per thread: the machine is shared, so a thread that is descheduled does
  // not hold the whole job back.
  // Rounded down: ten frames on two threads go one at a time (rounded up, in pairs, one
  // thread decoded six of them while the other waited).
  const int chunk = std::max(min_chunk, n / (threads * 4));
  std::atomic<int> next{0};
  auto work = [&] {
    for (;;) {
      const int b = next.fetch_add(chunk);
      if (b >= n) return;
      fn(b, std::min(n, b + chunk));
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
}

Status WriteImageFile(const std::string& path, const cv::Mat& image, const std::vector<int>& params) {
  const std::string ext = fs::path(path).extension().string();
  if (ext.empty()) return MakeError(ErrorCode::kInvalidInput, path, "no extension to choose the format");
  std::vector<uchar> bytes;
  try {
    if (!cv::imencode(ext, image, bytes, params))
      return MakeError(ErrorCode::kIo, path, "cannot encode the picture as {}", ext);
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kIo, path, "cannot encode the picture as {}: {}", ext, e.what());
  }
  return WriteFileAtomic(path, std::span<const uint8_t>(bytes.data(), bytes.size()));
}

Result<cv::Mat> DecodeImage(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(std::vector<uchar> bytes, ReadAll(path));
  return DecodeImageBytes(bytes, path);
}

Result<cv::Mat> DecodeImageBytes(const std::vector<uchar>& bytes, const std::string& path) {
  // A DNG is a TIFF: decoded as one it would give the undemosaiced mosaic. RAW goes through
  // LibRaw, by name (the camera's own extension), to linear 16-bit values.
  if (IsRawPath(path)) return DecodeRawBytes(std::span<const uint8_t>(bytes.data(), bytes.size()), path);
  const bool jpeg = bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
  const bool png = bytes.size() >= 8 && std::memcmp(bytes.data(), "\x89PNG\r\n\x1a\n", 8) == 0;
  // libjpeg decodes a truncated file with a warning and grey rows at the bottom; libpng may
  // too. A missing end marker is the reliable sign.
  if (jpeg && !EndsWithJpegEoi(bytes)) {
    return MakeError(ErrorCode::kCorrupt, path, "truncated JPEG (no end-of-image marker)");
  }
  if (png && !HasPngIend(bytes)) {
    return MakeError(ErrorCode::kCorrupt, path, "truncated PNG (no IEND chunk)");
  }
  cv::Mat img;
  try {
    img = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kCorrupt, path, "cannot decode: {}", e.what());
  }
  if (img.empty()) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "cannot decode (not a JPEG/PNG/TIFF image, or damaged)");
  }
  if (img.depth() != CV_8U && img.depth() != CV_16U) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "unsupported sample type (depth {}): 8- or 16-bit integers are needed",
                     img.depth());
  }
  if (img.channels() == 1) {
    cv::cvtColor(img, img, cv::COLOR_GRAY2BGR);
  } else if (img.channels() == 4) {
    cv::cvtColor(img, img, cv::COLOR_BGRA2BGR);
  } else if (img.channels() != 3) {
    return MakeError(ErrorCode::kInvalidInput, path, "{} channels (1, 3 or 4 are supported)",
                     img.channels());
  }
  return img;
}

Result<Bracket> DecodeFrames(const std::vector<std::string>& files,
                             const std::vector<Seconds>& exposures, int threads) {
  RIG_CHECK(files.size() == exposures.size(), "one exposure per file");
  const int n = static_cast<int>(files.size());
  Bracket frames(n);
  std::vector<std::optional<Error>> errors(n);
  ParallelFor(n, threads, [&](int b, int e) {
    for (int i = b; i < e; ++i) {
      frames[i].source = files[i];
      frames[i].exposure = exposures[i];
      auto img = DecodeImage(files[i]);
      if (img.ok()) {
        frames[i].image = std::move(img).value();
      } else {
        errors[i] = img.error();
      }
    }
  });
  for (auto& e : errors) {
    if (e) return *e;
  }
  return frames;
}

Result<Bracket> LoadBracketList(const std::string& list_path, int threads) {
  std::ifstream in(list_path);
  if (!in) {
    std::error_code ec;
    return MakeError(fs::exists(list_path, ec) ? ErrorCode::kIo : ErrorCode::kNotFound, list_path,
                     "cannot open bracket list");
  }
  const fs::path folder = fs::path(list_path).parent_path();
  std::vector<std::string> files;
  std::vector<Seconds> exposures;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream ss(line);
    std::string image, exposure, extra;
    if (!(ss >> image)) continue;
    const std::string where = list_path + ":" + std::to_string(line_no);
    if (!(ss >> exposure)) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "expected '<image> <exposure_s>', found only '{}'", image);
    }
    if (ss >> extra) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "unexpected '{}' after the exposure time (paths with spaces are not "
                       "supported)",
                       extra);
    }
    double t = 0;
    if (!ParseExposure(exposure, &t) || !(t > 0) || !std::isfinite(t)) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "exposure time '{}' is not a positive number of seconds", exposure);
    }
    fs::path p(image);
    if (p.is_relative()) p = folder / p;
    files.push_back(p.lexically_normal().string());
    exposures.push_back(Seconds(t));
  }
  if (files.empty()) {
    return MakeError(ErrorCode::kInvalidInput, list_path, "bracket list names no images");
  }
  return DecodeFrames(files, exposures, threads);
}

void ReuseFreedImageMemory() {
  mallopt(M_MMAP_THRESHOLD, 1 << 30);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
  mallopt(M_TOP_PAD, 64 << 20);
}

}  // namespace rig
