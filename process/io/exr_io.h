// OpenEXR reading and writing: named float channels plus string attributes in the header,
// so that metadata (pose, exposures, response id, basis, order ...) travels with pixels.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

enum class ExrPixelType { kHalf, kFloat };

// How the pixels are compressed in the file (docs/hdr.md has the lossless ones' size and speed
// on a 6 MP radiance map; docs/model.md the lossy ones' on model files). OpenEXR compresses
// blocks of lines independently, on its thread pool (the `threads` of the writers below).
enum class ExrCompression {
  kNone,     // raw: the fastest to write and read, the largest file
  kRle,      // run lengths: fast; shrinks the flags channel, float radiance barely
  kZips,     // zlib per line
  kZip,      // zlib per 16 lines (OpenEXR's level 6): small, slow to write
  kZipFast,  // ZIP at zlib level 1: on float radiance only 10-15% faster, 1% larger
  kPiz,      // wavelet + Huffman per 32 lines: the smallest on the measured maps
  // Lossy, for model files only (never a capture's radiance maps): OpenEXR's DWA codec, a DCT
  // of 8x8 blocks of half channels named R, G, B (after the last '.') at quantisation level 45,
  // other channels (a model's 'valid') losslessly; per 32 lines (dwaa) or 256 (dwab).
  kDwaa,
  kDwab,
};
// "none" | "rle" | "zips" | "zip" | "zip-fast" | "piz", and with `lossy` also "dwaa" | "dwab";
// an unknown name is an error that lists the choices.
Result<ExrCompression> ParseExrCompression(const std::string& name, bool lossy = false);
const char* ExrCompressionName(ExrCompression c);
bool ExrCompressionIsLossy(ExrCompression c);
// The lossless names ParseExrCompression accepts, in the order above.
const std::vector<std::string>& ExrCompressionNames();
// The same followed by the lossy ones: what a model file may be written with.
const std::vector<std::string>& ExrModelCompressionNames();
// For writers that build their own OpenEXR header: the Imf::Compression value of a choice, the
// zlib level to set (0: OpenEXR's default) and the DWA level (0: none).
struct ExrCompressionCode {
  int imf_compression = 0;
  int zip_level = 0;
  float dwa_level = 0;
};
// The DWA quantisation level rig writes (OpenEXR's default, 45: "visually lossless" for images).
inline constexpr float kExrDwaLevel = 45.0f;
ExrCompressionCode ExrCompressionCodeOf(ExrCompression c);

// What ReadExr accepts before allocating (docs/robustness.md); larger files are refused as
// damaged input (exit 2).
inline constexpr int64_t kMaxExrSide = 1 << 16;
inline constexpr int64_t kMaxExrPixels = int64_t{1} << 28;   // 16384 x 16384
inline constexpr int64_t kMaxExrSamples = int64_t{1} << 31;  // pixels x channels

struct ExrImage {
  int width = 0, height = 0;
  std::vector<std::string> channel_names;  // e.g. "R", "G", "B" or "c00.R", "c01.R" ...
  std::vector<cv::Mat> channels;           // each CV_32FC1, height x width
  std::map<std::string, std::string> attributes;  // string attributes of the header
  // OpenEXR's chromaticities attribute (red, green, blue, white xy), when the file has one.
  std::optional<std::array<double, 8>> chromaticities;
};

// Writes atomically (temporary file in the same folder, then rename): a reader never sees a
// partial file under `path`. `threads` is OpenEXR's compression thread count.
Status WriteExr(const std::string& path, const ExrImage& image,
                ExrPixelType type = ExrPixelType::kFloat, int threads = 2,
                ExrCompression compression = ExrCompression::kZip);
Result<ExrImage> ReadExr(const std::string& path, int threads = 2);
// The string attributes of the header alone (no pixels read).
Result<std::map<std::string, std::string>> ReadExrAttributes(const std::string& path);

// The same, for images that are not held as float planes: `fill(y0, y1, out)` writes rows
// [y0, y1) of every channel, interleaved, as float (out[(y - y0) * width * n + x * n + i]).
// The file is written in stripes of a few lines through one small reused buffer.
using ExrStripeFill = std::function<void(int y0, int y1, float* out)>;
Status WriteExrStriped(const std::string& path, int width, int height,
                       const std::vector<std::string>& channel_names,
                       const std::map<std::string, std::string>& attributes, ExrPixelType type,
                       int threads, const ExrStripeFill& fill,
                       ExrCompression compression = ExrCompression::kZip,
                       const std::optional<std::array<double, 8>>& chromaticities = {});

// Convenience for radiance maps: a CV_32FC3 image in OpenCV's BGR order <-> channels R, G, B.
Status WriteRgbExr(const std::string& path, const cv::Mat& bgr,
                   const std::map<std::string, std::string>& attributes = {},
                   ExrPixelType type = ExrPixelType::kFloat, int threads = 2,
                   ExrCompression compression = ExrCompression::kZip);
// Reads R, G, B (an EXR without them is an error naming the file) into a CV_32FC3 BGR image;
// `chromaticities` (if given) receives the header's chromaticities attribute, if any.
Result<cv::Mat> ReadRgbExr(const std::string& path,
                           std::map<std::string, std::string>* attributes = nullptr,
                           int threads = 2,
                           std::optional<std::array<double, 8>>* chromaticities = nullptr);

// Sizes OpenEXR's global thread pool (line-block compression and decompression) to at least
// one thread per `threads`; changed only when the count changes.
void SetExrThreads(int threads);

}  // namespace rig
