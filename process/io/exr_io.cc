// OpenEXR reading and writing (named float channels + string header attributes), atomic writes.
#include "process/io/exr_io.h"
#include "process/io/exr_ostream.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <system_error>

#include <Iex.h>
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStandardAttributes.h>
#include <ImfStringAttribute.h>
#include <ImfThreading.h>

namespace rig {

AtomicExrStream::AtomicExrStream(AtomicFile file)
    : Imf::OStream(file.path().c_str()), file_(std::move(file)) {}

void AtomicExrStream::write(const char c[], int n) {
  Status st = file_.Write(c, static_cast<size_t>(n));
  if (!st.ok()) throw Iex::IoExc(st.error().ToString());
}

uint64_t AtomicExrStream::tellp() { return file_.Tell(); }

void AtomicExrStream::seekp(uint64_t pos) {
  Status st = file_.Seek(pos);
  if (!st.ok()) throw Iex::IoExc(st.error().ToString());
}

namespace {

namespace fs = std::filesystem;

// Header attributes OpenEXR itself defines; never copied into ExrImage::attributes.
bool IsStandardAttribute(const std::string& name) {
  static const char* kStandard[] = {"channels",         "compression", "dataWindow", "chromaticities",
                                    "displayWindow",    "lineOrder",   "pixelAspectRatio",
                                    "screenWindowCenter", "screenWindowWidth"};
  for (const char* s : kStandard) {
    if (name == s) return true;
  }
  return false;
}

// The OpenEXR global thread pool: OpenEXR uses it for line-block (de)compression. Setting it
// is not free (threads are created), so it is changed only when the count changes.
// OpenEXR sizes its line buffers and chunk-offset tables from the header's data window before
// it reads a pixel: a hostile header claiming a window of 2^31 columns makes the InputFile
// constructor allocate and clear gigabytes (found by fuzz_model as an 11 s timeout). OpenEXR's
// own limit refuses such a header in its sanity check; the bound is this reader's own
// (kMaxExrSide, 65536 per side), above any camera's frame.
void ApplyExrSizeLimits() {
  static std::once_flag once;
  std::call_once(once, [] {
    Imf::Header::setMaxImageSize(static_cast<int>(kMaxExrSide), static_cast<int>(kMaxExrSide));
    Imf::Header::setMaxTileSize(static_cast<int>(kMaxExrSide), static_cast<int>(kMaxExrSide));
  });
}

void EnsureGlobalThreads(int threads) {
  static std::mutex mutex;
  static int current = -1;
  std::lock_guard<std::mutex> lock(mutex);
  if (threads != current) {
    Imf::setGlobalThreadCount(threads);
    current = threads;
  }
}


// OpenEXR 3.1 sizes an attribute's buffer from the count in the header before it reads the
// value: a header claiming a 2 GB string in a 2 KB file allocates and clears 2 GB (found by
// tests/fuzz/model). Every attribute of the first header must fit in what the file holds;
// anything else about the file is left to OpenEXR to judge. (Only the first header.)
Status CheckHeaderSizes(const std::string& path) {
  std::error_code ec;
  const uintmax_t file_size = fs::file_size(path, ec);
  if (ec) return Ok();
  std::ifstream f(path, std::ios::binary);
  unsigned char start[8];
  if (!f.read(reinterpret_cast<char*>(start), 8)) return Ok();
  if (start[0] != 0x76 || start[1] != 0x2f || start[2] != 0x31 || start[3] != 0x01) return Ok();
  auto text = [&](std::string* out) {
    out->clear();
    char c;
    while (f.get(c) && c != '\0' && out->size() < 256) *out += c;
    return static_cast<bool>(f);
  };
  std::string name, type;
  for (int n = 0; n < 100000; ++n) {
    if (!text(&name) || name.empty() || !text(&type)) return Ok();
    unsigned char b[4];
    if (!f.read(reinterpret_cast<char*>(b), 4)) return Ok();
    const int32_t size = static_cast<int32_t>(uint32_t{b[0]} | uint32_t{b[1]} << 8 |
                                              uint32_t{b[2]} << 16 | uint32_t{b[3]} << 24);
    // Read as OpenEXR reads it, so that the walk stays in step with it: a channel list up to
    // its empty name (whatever its size says), fixed-size types by their size.
    if (type == "chlist") {
      std::string channel;
      while (text(&channel) && !channel.empty()) f.seekg(16, std::ios::cur);
      if (!f) return Ok();
      continue;
    }
    static const std::map<std::string, int> kFixed = {
        {"box2i", 16}, {"box2f", 16}, {"v2i", 8}, {"v2f", 8}, {"v2d", 16}, {"v3i", 12},
        {"v3f", 12}, {"v3d", 24}, {"int", 4}, {"float", 4}, {"double", 8}, {"compression", 1},
        {"lineOrder", 1}, {"envmap", 1}, {"deepImageState", 1}, {"m33f", 36}, {"m33d", 72},
        {"m44f", 64}, {"m44d", 128}, {"chromaticities", 32}, {"keycode", 28}, {"timecode", 8},
        {"rational", 8}, {"tiledesc", 9}};
    if (auto it = kFixed.find(type); it != kFixed.end()) {
      f.seekg(it->second, std::ios::cur);
      continue;
    }
    const std::streamoff here = f.tellg();
    if (size < 0 || here < 0 || static_cast<uintmax_t>(size) > file_size - static_cast<uintmax_t>(here)) {
      return MakeError(ErrorCode::kCorrupt, path,
                       "header attribute '{}' ({}) claims {} bytes; the file holds {}",
                       name.substr(0, 64), type.substr(0, 32), size, file_size);
    }
    f.seekg(size, std::ios::cur);
  }
  return Ok();
}

Imf::Compression ToImf(ExrCompression c) {
  switch (c) {
    case ExrCompression::kNone: return Imf::NO_COMPRESSION;
    case ExrCompression::kRle: return Imf::RLE_COMPRESSION;
    case ExrCompression::kZips: return Imf::ZIPS_COMPRESSION;
    case ExrCompression::kZip: return Imf::ZIP_COMPRESSION;
    case ExrCompression::kZipFast: return Imf::ZIP_COMPRESSION;
    case ExrCompression::kPiz: return Imf::PIZ_COMPRESSION;
    case ExrCompression::kDwaa: return Imf::DWAA_COMPRESSION;
    case ExrCompression::kDwab: return Imf::DWAB_COMPRESSION;
  }
  return Imf::ZIP_COMPRESSION;
}

constexpr ExrCompression kAllCompressions[] = {ExrCompression::kNone, ExrCompression::kRle,
                                               ExrCompression::kZips, ExrCompression::kZip,
                                               ExrCompression::kZipFast, ExrCompression::kPiz};
constexpr ExrCompression kLossyCompressions[] = {ExrCompression::kDwaa, ExrCompression::kDwab};

}  // namespace

void SetExrThreads(int threads) { EnsureGlobalThreads(std::max(threads, 1)); }

const char* ExrCompressionName(ExrCompression c) {
  switch (c) {
    case ExrCompression::kNone: return "none";
    case ExrCompression::kRle: return "rle";
    case ExrCompression::kZips: return "zips";
    case ExrCompression::kZip: return "zip";
    case ExrCompression::kZipFast: return "zip-fast";
    case ExrCompression::kPiz: return "piz";
    case ExrCompression::kDwaa: return "dwaa";
    case ExrCompression::kDwab: return "dwab";
  }
  return "?";
}

bool ExrCompressionIsLossy(ExrCompression c) {
  return c == ExrCompression::kDwaa || c == ExrCompression::kDwab;
}

ExrCompressionCode ExrCompressionCodeOf(ExrCompression c) {
  return {static_cast<int>(ToImf(c)), c == ExrCompression::kZipFast ? 1 : 0,
          ExrCompressionIsLossy(c) ? kExrDwaLevel : 0.0f};
}

const std::vector<std::string>& ExrCompressionNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v;
    for (ExrCompression c : kAllCompressions) v.push_back(ExrCompressionName(c));
    return v;
  }();
  return names;
}

const std::vector<std::string>& ExrModelCompressionNames() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> v = ExrCompressionNames();
    for (ExrCompression c : kLossyCompressions) v.push_back(ExrCompressionName(c));
    return v;
  }();
  return names;
}

Result<ExrCompression> ParseExrCompression(const std::string& name, bool lossy) {
  for (ExrCompression c : kAllCompressions) {
    if (name == ExrCompressionName(c)) return c;
  }
  if (lossy) {
    for (ExrCompression c : kLossyCompressions) {
      if (name == ExrCompressionName(c)) return c;
    }
  }
  std::string choices;
  for (const auto& n : lossy ? ExrModelCompressionNames() : ExrCompressionNames())
    choices += (choices.empty() ? "" : ", ") + n;
  return MakeError(ErrorCode::kInvalidInput, "", "EXR compression '{}' (expected one of {})", name,
                   choices);
}

Status WriteExrStriped(const std::string& path, int width, int height,
                       const std::vector<std::string>& channel_names,
                       const std::map<std::string, std::string>& attributes, ExrPixelType type,
                       int threads, const ExrStripeFill& fill, ExrCompression compression,
                       const std::optional<std::array<double, 8>>& chromaticities) {
  if (width <= 0 || height <= 0) {
    return MakeError(ErrorCode::kInvalidInput, path, "cannot write an empty image ({}x{})", width,
                     height);
  }
  if (channel_names.empty()) {
    return MakeError(ErrorCode::kInvalidInput, path, "no channels to write");
  }
  // The folder is made when missing (a removed hdr/ is how a re-merge is forced).
  RIG_ASSIGN_OR_RETURN(AtomicFile file, AtomicFile::Create(path));
  try {
    threads = std::max(threads, 1);
    EnsureGlobalThreads(threads);
    // Blocks of lines compress independently, so OpenEXR spreads them over the thread pool.
    Imf::Header header(width, height, 1.0f, Imath::V2f(0, 0), 1.0f, Imf::INCREASING_Y,
                       ToImf(compression));
    // zlib's level 1 against OpenEXR's 6: a shorter search for matches. On float radiance it
    // saves only 10-15%: the time goes into coding the noisy low bytes (docs/hdr.md).
    if (compression == ExrCompression::kZipFast) header.zipCompressionLevel() = 1;
    if (ExrCompressionIsLossy(compression)) header.dwaCompressionLevel() = kExrDwaLevel;
    const Imf::PixelType pixel = type == ExrPixelType::kHalf ? Imf::HALF : Imf::FLOAT;
    for (const auto& name : channel_names) header.channels().insert(name, Imf::Channel(pixel));
    for (const auto& [key, value] : attributes) {
      if (IsStandardAttribute(key)) {
        return MakeError(ErrorCode::kInvalidInput, path,
                         "attribute name '{}' is reserved by OpenEXR", key);
      }
      header.insert(key, Imf::StringAttribute(value));
    }
    if (chromaticities) {
      const auto& c = *chromaticities;
      Imf::addChromaticities(
          header, Imf::Chromaticities(Imath::V2f(float(c[0]), float(c[1])),
                                      Imath::V2f(float(c[2]), float(c[3])),
                                      Imath::V2f(float(c[4]), float(c[5])),
                                      Imath::V2f(float(c[6]), float(c[7]))));
    }
    // Stripes of 64 lines (four ZIP blocks, compressed in parallel), interleaved, in two
    // buffers reused for every stripe: no image-sized temporaries (fresh memory costs a page
    // fault per 4 KiB, which on a virtual machine is most of a write's time). OpenEXR does not
    // convert float to half on output: OpenCV's CV_16F has the same IEEE binary16 layout as
    // Imath's half, and converts with SIMD.
    constexpr int kStripe = 64;
    const int nch = static_cast<int>(channel_names.size());
    const int row = width * nch;
    cv::Mat stripe_f(kStripe, row, CV_32F), stripe_h;
    if (type == ExrPixelType::kHalf) stripe_h.create(kStripe, row, CV_16F);
    const cv::Mat& buffer = type == ExrPixelType::kHalf ? stripe_h : stripe_f;
    const size_t elem = buffer.elemSize();
    AtomicExrStream stream(std::move(file));
    {
      Imf::OutputFile out(stream, header, threads);
      for (int y0 = 0; y0 < height; y0 += kStripe) {
        const int y1 = std::min(height, y0 + kStripe);
        fill(y0, y1, stripe_f.ptr<float>());
        if (type == ExrPixelType::kHalf) {
          stripe_f.rowRange(0, y1 - y0).convertTo(stripe_h.rowRange(0, y1 - y0), CV_16F);
        }
        // OpenEXR addresses (x, y) as base + x * xStride + y * yStride: the base is set so that
        // line y0 lands on the stripe's first row.
        char* base = const_cast<char*>(reinterpret_cast<const char*>(buffer.data)) -
                     static_cast<ptrdiff_t>(y0) * static_cast<ptrdiff_t>(buffer.step[0]);
        Imf::FrameBuffer fb;
        for (int i = 0; i < nch; ++i) {
          fb.insert(channel_names[i], Imf::Slice(pixel, base + i * elem, nch * elem, buffer.step[0]));
        }
        out.setFrameBuffer(fb);
        out.writePixels(y1 - y0);
      }
    }
    RIG_TRY(stream.Commit());
  } catch (const Iex::BaseExc& e) {
    return MakeError(ErrorCode::kIo, path, "cannot write EXR: {}", e.what());
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kIo, path, "cannot write EXR: {}", e.what());
  }
  return Ok();
}

Status WriteExr(const std::string& path, const ExrImage& image, ExrPixelType type,
                int threads, ExrCompression compression) {
  if (image.width <= 0 || image.height <= 0) {
    return MakeError(ErrorCode::kInvalidInput, path, "cannot write an empty image ({}x{})",
                     image.width, image.height);
  }
  if (image.channel_names.size() != image.channels.size() || image.channels.empty()) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "{} channel names for {} channels (need at least one, one name each)",
                     image.channel_names.size(), image.channels.size());
  }
  for (size_t i = 0; i < image.channels.size(); ++i) {
    const cv::Mat& c = image.channels[i];
    if (c.type() != CV_32FC1 || c.cols != image.width || c.rows != image.height) {
      return MakeError(ErrorCode::kInvalidInput, path,
                       "channel '{}' must be CV_32FC1 {}x{} (is type {} {}x{})",
                       image.channel_names[i], image.width, image.height, c.type(), c.cols,
                       c.rows);
    }
  }
  const int nch = static_cast<int>(image.channels.size());
  return WriteExrStriped(path, image.width, image.height, image.channel_names, image.attributes,
                         type, threads, [&](int y0, int y1, float* out) {
                           for (int y = y0; y < y1; ++y) {
                             float* o = out + size_t(y - y0) * image.width * nch;
                             for (int i = 0; i < nch; ++i) {
                               const float* src = image.channels[i].ptr<float>(y);
                               for (int x = 0; x < image.width; ++x) o[x * nch + i] = src[x];
                             }
                           }
                         }, compression, image.chromaticities);
}

Result<std::map<std::string, std::string>> ReadExrAttributes(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return MakeError(ErrorCode::kNotFound, path, "no such file");
  RIG_TRY(CheckHeaderSizes(path));
  ApplyExrSizeLimits();
  try {
    Imf::InputFile in(path.c_str(), 1);
    std::map<std::string, std::string> out;
    for (auto it = in.header().begin(); it != in.header().end(); ++it) {
      if (IsStandardAttribute(it.name())) continue;
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
        out[it.name()] = s->value();
      }
    }
    return out;
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kCorrupt, path, "cannot read EXR header: {}", e.what());
  }
}

Result<ExrImage> ReadExr(const std::string& path, int threads) {
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    return MakeError(ErrorCode::kNotFound, path, "no such file");
  }
  RIG_TRY(CheckHeaderSizes(path));
  ApplyExrSizeLimits();
  try {
    threads = std::max(threads, 1);
    EnsureGlobalThreads(threads);
    Imf::InputFile in(path.c_str(), threads);
    const Imf::Header& header = in.header();
    const Imath::Box2i dw = header.dataWindow();
    ExrImage image;
    // In 64 bits: a hostile data window overflows int.
    const int64_t w64 = int64_t{dw.max.x} - dw.min.x + 1, h64 = int64_t{dw.max.y} - dw.min.y + 1;
    if (w64 <= 0 || h64 <= 0) {
      return MakeError(ErrorCode::kCorrupt, path, "empty data window");
    }
    int64_t nch = 0;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) ++nch;
    if (w64 > kMaxExrSide || h64 > kMaxExrSide || w64 * h64 > kMaxExrPixels ||
        w64 * h64 * nch > kMaxExrSamples) {
      return MakeError(ErrorCode::kCorrupt, path,
                       "{}x{} pixels x {} channels is larger than this reader accepts (at most "
                       "{} px a side, {} pixels, {} samples)",
                       w64, h64, nch, kMaxExrSide, kMaxExrPixels, kMaxExrSamples);
    }
    image.width = static_cast<int>(w64);
    image.height = static_cast<int>(h64);
    Imf::FrameBuffer fb;
    for (auto it = header.channels().begin(); it != header.channels().end(); ++it) {
      if (it.channel().xSampling != 1 || it.channel().ySampling != 1) {
        return MakeError(ErrorCode::kInvalidInput, path, "channel '{}' is subsampled",
                         it.name());
      }
      cv::Mat m(image.height, image.width, CV_32FC1);
      // The slice base is shifted so that the data window's origin lands on m(0, 0).
      char* base = reinterpret_cast<char*>(m.ptr<float>()) -
                   (static_cast<ptrdiff_t>(dw.min.x) +
                    static_cast<ptrdiff_t>(dw.min.y) * image.width) *
                       static_cast<ptrdiff_t>(sizeof(float));
      fb.insert(it.name(), Imf::Slice(Imf::FLOAT, base, sizeof(float),
                                      sizeof(float) * image.width, 1, 1, 0.0));
      image.channel_names.push_back(it.name());
      image.channels.push_back(m);
    }
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    for (auto it = header.begin(); it != header.end(); ++it) {
      if (IsStandardAttribute(it.name())) continue;
      if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
        image.attributes[it.name()] = s->value();
      }
    }
    if (Imf::hasChromaticities(header)) {
      const Imf::Chromaticities& c = Imf::chromaticities(header);
      image.chromaticities = std::array<double, 8>{c.red.x,   c.red.y,   c.green.x, c.green.y,
                                                   c.blue.x,  c.blue.y,  c.white.x, c.white.y};
    }
    return image;
  } catch (const Iex::BaseExc& e) {
    return MakeError(ErrorCode::kCorrupt, path, "cannot read EXR: {}", e.what());
  } catch (const std::bad_alloc&) {
    return MakeError(ErrorCode::kInvalidInput, path, "cannot read EXR: too large for memory");
  } catch (const std::exception& e) {
    return MakeError(ErrorCode::kIo, path, "cannot read EXR: {}", e.what());
  }
}

Status WriteRgbExr(const std::string& path, const cv::Mat& bgr,
                   const std::map<std::string, std::string>& attributes, ExrPixelType type,
                   int threads, ExrCompression compression) {
  if (bgr.type() != CV_32FC3 || bgr.empty()) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "a radiance image must be a non-empty CV_32FC3 (is type {})", bgr.type());
  }
  ExrImage image;
  image.width = bgr.cols;
  image.height = bgr.rows;
  std::vector<cv::Mat> planes;
  cv::split(bgr, planes);
  image.channel_names = {"B", "G", "R"};
  image.channels = planes;
  image.attributes = attributes;
  return WriteExr(path, image, type, threads, compression);
}

Result<cv::Mat> ReadRgbExr(const std::string& path, std::map<std::string, std::string>* attributes,
                           int threads, std::optional<std::array<double, 8>>* chromaticities) {
  RIG_ASSIGN_OR_RETURN(ExrImage image, ReadExr(path, threads));
  cv::Mat planes[3];
  const char* kNames[3] = {"B", "G", "R"};
  for (int c = 0; c < 3; ++c) {
    for (size_t i = 0; i < image.channel_names.size(); ++i) {
      if (image.channel_names[i] == kNames[c]) planes[c] = image.channels[i];
    }
    if (planes[c].empty()) {
      return MakeError(ErrorCode::kInvalidInput, path, "no '{}' channel (an RGB EXR is needed)",
                       kNames[c]);
    }
  }
  cv::Mat bgr;
  cv::merge(planes, 3, bgr);
  if (attributes) *attributes = std::move(image.attributes);
  if (chromaticities) *chromaticities = image.chromaticities;
  return bgr;
}

}  // namespace rig
