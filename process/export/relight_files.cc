// relight's web format, .ptm and .rti: the writers choose scale/bias, the readers bound every
// size by the file's own length before allocating.
#include "process/export/relight_files.h"
#include "process/io/json_file.h"
#include "config/atomic_file.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "process/io/jpeg_io.h"
#include "process/io/model_limits.h"
#include "process/model/pca/pca.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

constexpr int kMaxSide = 1 << 16;
constexpr int64_t kMaxPixels = int64_t{1} << 28;
// File order of a .ptm's 6 coefficients (x², y², xy, x, y, 1) as indices of relight's
// [1, x, y, x², xy, y²].
constexpr int kPtmFileToRelight[6] = {3, 5, 4, 1, 2, 0};

Status CheckSize(const std::string& context, int64_t width, int64_t height) {
  if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide ||
      width * height > kMaxPixels) {
    return MakeError(ErrorCode::kInvalidInput, context,
                     "size {}x{} is outside 1..{} per side ({} pixels at most)", width, height,
                     kMaxSide, kMaxPixels);
  }
  return Ok();
}

// Smallest and largest of every value of a plane's channels (all channels when channel < 0).
void Range(const cv::Mat& plane, int channel, double* lo, double* hi) {
  *lo = std::numeric_limits<double>::infinity();
  *hi = -*lo;
  const int ch = plane.channels();
  for (int y = 0; y < plane.rows; ++y) {
    const float* p = plane.ptr<float>(y);
    for (int x = 0; x < plane.cols; ++x)
      for (int k = 0; k < ch; ++k) {
        if (channel >= 0 && k != channel) continue;
        *lo = std::min(*lo, double(p[x * ch + k]));
        *hi = std::max(*hi, double(p[x * ch + k]));
      }
  }
}

// Coefficients a file can hold: finite (a NaN has no byte).
Status CheckFinite(const RelightCoefficients& c, const std::string& path) {
  for (size_t j = 0; j < c.planes.size(); ++j) {
    if (!cv::checkRange(c.planes[j])) {
      return MakeError(ErrorCode::kInvalidInput, path, "coefficient {} holds a NaN or infinity", j);
    }
  }
  if (c.lrgb && !cv::checkRange(c.albedo)) {
    return MakeError(ErrorCode::kInvalidInput, path, "the albedo holds a NaN or infinity");
  }
  return Ok();
}

// A plane file at least as large as a JPEG of width×height can be (model_limits.h).
Status CheckPlaneFileSize(const std::string& plane, int width, int height) {
  std::error_code ec;
  const auto st = fs::status(plane, ec);
  if (ec || !fs::exists(st)) return MakeError(ErrorCode::kNotFound, plane, "no such file");
  if (!fs::is_regular_file(st)) return MakeError(ErrorCode::kInvalidInput, plane, "not a file");
  const uint64_t bytes = fs::file_size(plane, ec);
  if (ec) return MakeError(ErrorCode::kIo, plane, "cannot stat: {}", ec.message());
  if (bytes < MinJpegBytes(width, height)) {
    return MakeError(ErrorCode::kInvalidInput, plane,
                     "{} bytes cannot hold a {}x{} JPEG (at least {}): the size declared is not the file's",
                     bytes, width, height, MinJpegBytes(width, height));
  }
  return Ok();
}

// The plane files plane_0 .. plane_{files-1}.jpg, each checked against width×height (byte
// count, then header) and opened.
Result<std::vector<std::unique_ptr<JpegReader>>> OpenPlanes(const std::string& folder, int files,
                                                            int width, int height) {
  std::vector<std::unique_ptr<JpegReader>> readers;
  for (int j = 0; j < files; ++j) {
    const std::string plane = (fs::path(folder) / fmt::format("plane_{}.jpg", j)).string();
    RIG_TRY(CheckPlaneFileSize(plane, width, height));
    RIG_ASSIGN_OR_RETURN(auto reader, JpegReader::Open(plane));
    if (reader->width() != width || reader->height() != height || reader->channels() != 3) {
      return MakeError(ErrorCode::kInvalidInput, plane, "{}x{}x{}, info.json says {}x{}x3",
                       reader->width(), reader->height(), reader->channels(), width, height);
    }
    readers.push_back(std::move(reader));
  }
  return readers;
}

uint8_t ToByte(double v) {
  return static_cast<uint8_t>(std::clamp(std::nearbyint(v), 0.0, 255.0));
}

// The header and the data through the project's one writer (config/atomic_file.h).
Status WriteFile(const std::string& path, const std::string& header,
                 const std::vector<uint8_t>& data) {
  RIG_ASSIGN_OR_RETURN(AtomicFile f, AtomicFile::Create(path));
  RIG_TRY(f.Write(header));
  RIG_TRY(f.Write(data.data(), data.size()));
  return f.Commit();
}

// A binary file read as header lines, then a bounded binary tail.
class LineFile {
 public:
  static Result<LineFile> Open(const std::string& path) {
    LineFile f;
    f.path_ = path;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) return MakeError(ErrorCode::kNotFound, path, "no such file");
    f.size_ = fs::file_size(path, ec);
    if (ec) return MakeError(ErrorCode::kIo, path, "cannot stat: {}", ec.message());
    f.in_.open(path, std::ios::binary);
    if (!f.in_) return MakeError(ErrorCode::kIo, path, "cannot open");
    return f;
  }
  // The next line without its "\n" (and "\r"); an error naming `field` at the end of the file
  // or past 4096 characters.
  Result<std::string> Line(const char* field) {
    std::string s;
    char ch;
    while (in_.get(ch)) {
      if (ch == '\n') {
        if (!s.empty() && s.back() == '\r') s.pop_back();
        return s;
      }
      s.push_back(ch);
      if (s.size() > 4096) {
        return MakeError(ErrorCode::kInvalidInput, path_, "{}: header line longer than 4096 bytes",
                         field);
      }
    }
    return MakeError(ErrorCode::kInvalidInput, path_, "truncated: the file ends before the {} line",
                     field);
  }
  uint64_t remaining() {
    const auto pos = in_.tellg();
    return pos < 0 ? 0 : size_ - static_cast<uint64_t>(pos);
  }
  Status Read(void* dst, uint64_t n, const char* field) {
    if (remaining() < n) {
      return MakeError(ErrorCode::kInvalidInput, path_,
                       "truncated: {} needs {} bytes, the file holds {} after the header", field,
                       n, remaining());
    }
    in_.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
    if (!in_) return MakeError(ErrorCode::kIo, path_, "read failed in {}", field);
    return Ok();
  }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  uint64_t size_ = 0;
  std::ifstream in_;
};

// Whitespace-separated numbers of a header line; exactly `count` of them (0: any, at least 1).
Result<std::vector<double>> Numbers(const std::string& line, size_t count, const std::string& path,
                                    const char* field) {
  std::vector<double> v;
  std::istringstream s(line);
  std::string tok;
  while (s >> tok) {
    char* end = nullptr;
    errno = 0;
    const double d = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0' || errno != 0 || !std::isfinite(d)) {
      return MakeError(ErrorCode::kInvalidInput, path, "{}: '{}' is not a number", field, tok);
    }
    v.push_back(d);
  }
  if ((count == 0 && v.empty()) || (count > 0 && v.size() != count)) {
    return MakeError(ErrorCode::kInvalidInput, path, "{}: {} numbers, {} expected (line '{}')",
                     field, v.size(), count == 0 ? std::string("some") : std::to_string(count),
                     line);
  }
  return v;
}

Result<int> Integer(double v, const std::string& path, const char* field) {
  if (v != std::floor(v) || std::fabs(v) > 1e9) {
    return MakeError(ErrorCode::kInvalidInput, path, "{}: {} is not an integer", field, v);
  }
  return static_cast<int>(v);
}

// Relight's quantisation range of one plane channel: the quantiles of a stride sample.
void QuantileRange(const cv::Mat& plane, int channel, double q, double* lo, double* hi) {
  const size_t n = plane.total();
  const size_t stride = std::max<size_t>(1, n / (size_t{1} << 20));
  std::vector<float> v;
  v.reserve(n / stride + 1);
  const int ch = plane.channels();
  RIG_CHECK(plane.isContinuous(), "relight planes are whole images");
  const float* p = plane.ptr<float>();
  for (size_t i = 0; i < n; i += stride) v.push_back(p[i * ch + channel]);
  const size_t a = static_cast<size_t>(std::floor(q * (v.size() - 1)));
  const size_t b = static_cast<size_t>(std::ceil((1 - q) * (v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + a, v.end());
  *lo = v[a];
  std::nth_element(v.begin(), v.begin() + b, v.end());
  *hi = v[b];
  if (*hi - *lo < 1e-6) *hi = *lo + 1;
}

}  // namespace

// ---- web format ---------------------------------------------------------------------------

RelightWebPlanes QuantiseRelightWeb(const RelightCoefficients& c, const WebWriteOptions& o) {
  CheckRelightCoefficients(c);
  // relight's planes in order, one channel each: rgb: plane 3j+k = coefficient j of channel k
  // (R, G, B); lrgb: planes 0..2 = the albedo's R, G, B bytes, planes 3..8 = luminance terms.
  std::vector<cv::Mat> channels;
  if (!c.lrgb) {
    for (int j = 0; j < c.terms; ++j) {
      std::vector<cv::Mat> bgr;
      cv::split(c.planes[j], bgr);
      channels.insert(channels.end(), {bgr[2], bgr[1], bgr[0]});
    }
  } else {
    std::vector<cv::Mat> bgr;
    cv::split(c.albedo, bgr);
    channels = {bgr[2], bgr[1], bgr[0]};
    for (int j = 0; j < c.terms; ++j) channels.push_back(c.planes[j]);
  }
  const int nplanes = static_cast<int>(channels.size());
  RelightWebPlanes out;
  out.scale.resize(nplanes);
  out.bias.resize(nplanes);
  for (int p = 0; p < nplanes; ++p) {
    if (c.lrgb && p < 3) {  // relight renders the albedo from the bytes as they are
      out.scale[p] = 1;
      out.bias[p] = 0;
    } else {
      double lo, hi;
      QuantileRange(channels[p], 0, o.quantile, &lo, &hi);
      out.scale[p] = (hi - lo) / 255.0;
      out.bias[p] = -lo / (hi - lo);
    }
  }
  for (int j = 0; 3 * j < nplanes; ++j) {
    cv::Mat rgb = cv::Mat::zeros(c.height, c.width, CV_8UC3);  // unused channels stay 0
    for (int k = 0; k < 3 && 3 * j + k < nplanes; ++k) {
      const int p = 3 * j + k;
      const bool raw = c.lrgb && p < 3;
      const double lo = raw ? 0 : -out.bias[p] * out.scale[p] * 255.0, step = raw ? 1 : out.scale[p];
      for (int y = 0; y < c.height; ++y) {
        const float* in = channels[p].ptr<float>(y);
        uint8_t* px = rgb.ptr<uint8_t>(y);
        for (int x = 0; x < c.width; ++x) px[3 * x + k] = ToByte((in[x] - lo) / step);
      }
    }
    out.files.push_back(std::move(rgb));
  }
  return out;
}

std::string RelightWebInfo(const RelightCoefficients& c, const RelightWebPlanes& q,
                           const WebWriteOptions& o) {
  nlohmann::ordered_json info;
  info["width"] = c.width;
  info["height"] = c.height;
  info["format"] = "jpg";
  info["type"] = RelightTypeName(c.type);
  info["colorspace"] = c.colorspace();
  if (!c.lights.empty()) {
    auto lights = nlohmann::ordered_json::array();
    for (const auto& l : c.lights)
      for (double v : l) lights.push_back(std::round(v * 1000) / 1000);
    info["lights"] = lights;
  }
  info["nplanes"] = static_cast<int>(q.scale.size());
  info["quality"] = o.quality;
  info["colorprofile"] = "sRGB";
  nlohmann::ordered_json material;
  material["scale"] = q.scale;
  material["bias"] = q.bias;
  info["materials"] = nlohmann::ordered_json::array({material});
  return info.dump() + "\n";
}

Status WriteRelightWeb(const std::string& folder, const RelightCoefficients& c,
                       const WebWriteOptions& o) {
  CheckRelightCoefficients(c);
  RIG_TRY(CheckFinite(c, folder));
  if (c.terms > 9) {
    return MakeError(ErrorCode::kInvalidInput, folder,
                     "relight's web format holds an HSH of at most 9 terms (its renderer weighs 9); "
                     "this one has {}: keep it as a .rti (RTIViewer), or refit to 9 (rig export "
                     "MODEL --format relight --hsh-terms 9)", c.terms);
  }
  if (o.quality < 1 || o.quality > 100) {
    return MakeError(ErrorCode::kInvalidInput, folder, "JPEG quality {} is outside 1..100", o.quality);
  }
  std::error_code ec;
  if (fs::exists(fs::path(folder) / "info.json", ec)) {
    return MakeError(ErrorCode::kInvalidInput, folder, "holds a model already (info.json)");
  }
  fs::create_directories(folder, ec);
  if (ec) return MakeError(ErrorCode::kIo, folder, "cannot create: {}", ec.message());

  const RelightWebPlanes q = QuantiseRelightWeb(c, o);
  for (size_t j = 0; j < q.files.size(); ++j) {
    const std::string plane = (fs::path(folder) / fmt::format("plane_{}.jpg", j)).string();
    RIG_TRY(WriteJpeg(plane, q.files[j], o.ycbcr ? JpegColor::kYcbcr : JpegColor::kRgb, o.quality));
  }
  const std::string text = RelightWebInfo(c, q, o);
  return WriteFile((fs::path(folder) / "info.json").string(), text, {});
}

Result<std::vector<std::string>> DeclaredWebFiles(const std::string& folder) {
  const std::string path = (fs::path(folder) / "info.json").string();
  RIG_ASSIGN_OR_RETURN(nlohmann::json info, ReadJsonObjectFile(path));
  int64_t nplanes = 0;
  if (info.contains("yccplanes") && info["yccplanes"].is_array()) {
    // mycc: [ny, nc, nc] instead of nplanes
    for (const auto& v : info["yccplanes"]) {
      if (!v.is_number_integer() || v.get<int64_t>() < 0 || v.get<int64_t>() > 256)
        return MakeError(ErrorCode::kInvalidInput, path, "yccplanes: {} is not an integer in 0..256", v.dump());
      nplanes += v.get<int64_t>();
    }
  } else if (!info.contains("nplanes") || !info["nplanes"].is_number_integer()) {
    return MakeError(ErrorCode::kInvalidInput, path, "nplanes: missing or not an integer");
  } else {
    nplanes = info["nplanes"].get<int64_t>();
  }
  if (nplanes < 1 || nplanes > 256)
    return MakeError(ErrorCode::kInvalidInput, path, "nplanes: {} is outside 1..256", nplanes);
  std::vector<std::string> names = {"info.json"};
  for (int64_t j = 0; 3 * j < nplanes; ++j) names.push_back(fmt::format("plane_{}.jpg", j));
  return names;
}

std::string RelightWebType(const std::string& folder) {
  auto info = ReadJsonObjectFile((fs::path(folder) / "info.json").string());
  if (info.ok() && info->contains("type") && (*info)["type"].is_string())
    return (*info)["type"].get<std::string>();
  return "";
}

namespace {
Result<RelightCoefficients> ReadRelightWebImpl(const std::string& folder, bool planes);
}  // namespace

Result<RelightCoefficients> ReadRelightWeb(const std::string& folder) {
  return ReadRelightWebImpl(folder, true);
}
Result<RelightCoefficients> ReadRelightWebInfo(const std::string& folder) {
  return ReadRelightWebImpl(folder, false);
}

namespace {
Result<RelightCoefficients> ReadRelightWebImpl(const std::string& folder, bool read_planes) {
  const std::string path = (fs::path(folder) / "info.json").string();
  RIG_ASSIGN_OR_RETURN(nlohmann::json info, ReadJsonObjectFile(path));
  auto field = [&](const char* name) -> Result<const nlohmann::json*> {
    if (!info.contains(name)) return MakeError(ErrorCode::kInvalidInput, path, "{}: missing", name);
    return &info[name];
  };
  auto integer = [&](const char* name) -> Result<int64_t> {
    RIG_ASSIGN_OR_RETURN(const nlohmann::json* v, field(name));
    if (!v->is_number_integer()) return MakeError(ErrorCode::kInvalidInput, path, "{}: not an integer", name);
    return v->get<int64_t>();
  };
  auto text = [&](const char* name) -> Result<std::string> {
    RIG_ASSIGN_OR_RETURN(const nlohmann::json* v, field(name));
    if (!v->is_string()) return MakeError(ErrorCode::kInvalidInput, path, "{}: not a string", name);
    return v->get<std::string>();
  };
  RelightCoefficients c;
  RIG_ASSIGN_OR_RETURN(int64_t width, integer("width"));
  RIG_ASSIGN_OR_RETURN(int64_t height, integer("height"));
  RIG_TRY(CheckSize(path + ": width, height", width, height));
  c.width = static_cast<int>(width);
  c.height = static_cast<int>(height);
  RIG_ASSIGN_OR_RETURN(std::string type, text("type"));
  RIG_ASSIGN_OR_RETURN(std::string colorspace, text("colorspace"));
  RIG_ASSIGN_OR_RETURN(int64_t nplanes, integer("nplanes"));
  if (colorspace == "lrgb" && type == "ptm") {
    c.type = RelightType::kPtm;
    c.lrgb = true;
    if (nplanes != 9) {
      return MakeError(ErrorCode::kInvalidInput, path,
                       "nplanes: {} for type ptm, colorspace lrgb, 9 expected", nplanes);
    }
  } else if (colorspace != "rgb") {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "colorspace: '{}' for type {} is not read here (rgb; lrgb for ptm)", colorspace, type);
  } else if (type == "ptm") {
    c.type = RelightType::kPtm;
    if (nplanes != 18) {
      return MakeError(ErrorCode::kInvalidInput, path, "nplanes: {} for type ptm, 18 expected",
                       nplanes);
    }
  } else if (type == "hsh") {
    c.type = RelightType::kHsh;
    if (nplanes != 27 && nplanes != 12) {
      return MakeError(ErrorCode::kInvalidInput, path,
                       "nplanes: {} for type hsh, 27 (9 terms) or 12 (4 terms) expected", nplanes);
    }
  } else if (type == "sh") {
    c.type = RelightType::kSh;
    if (nplanes != 27 && nplanes != 12) {
      return MakeError(ErrorCode::kInvalidInput, path,
                       "nplanes: {} for type sh, 27 (9 terms) or 12 (4 terms) expected", nplanes);
    }
  } else {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "type: '{}' is not read here (read: {})", type, kRelightTypesRead);
  }
  c.terms = c.lrgb ? 6 : static_cast<int>(nplanes / 3);
  if (info.contains("format") && info["format"] != "jpg") {
    return MakeError(ErrorCode::kInvalidInput, path, "format: {} (jpg expected)", info["format"].dump());
  }
  RIG_ASSIGN_OR_RETURN(const nlohmann::json* materials, field("materials"));
  if (!materials->is_array() || materials->size() != 1 || !(*materials)[0].is_object()) {
    return MakeError(ErrorCode::kInvalidInput, path, "materials: exactly one object expected");
  }
  const auto& m = (*materials)[0];
  std::vector<double> scale, bias;
  for (auto [name, out] : {std::pair{"scale", &scale}, std::pair{"bias", &bias}}) {
    if (!m.contains(name) || !m[name].is_array() || m[name].size() != static_cast<size_t>(nplanes)) {
      return MakeError(ErrorCode::kInvalidInput, path, "materials[0].{}: {} numbers expected (nplanes)",
                       name, nplanes);
    }
    for (const auto& v : m[name]) {
      if (!v.is_number()) {
        return MakeError(ErrorCode::kInvalidInput, path, "materials[0].{}: {} is not a number", name,
                         v.dump());
      }
      out->push_back(v.get<double>());
      RIG_TRY(CheckFloatValue(out->back(), path, fmt::format("materials[0].{}[{}]", name, out->size() - 1)));
    }
  }
  for (int64_t p = 0; p < nplanes; ++p) {  // 255·(byte/255 − bias)·scale, every value a float
    RIG_TRY(CheckDequantisation(scale[p], -255.0 * bias[p] * scale[p], path,
                                fmt::format("materials[0].scale[{}], bias[{}]", p, p)));
  }
  if (info.contains("lights")) {
    const auto& l = info["lights"];
    if (!l.is_array() || l.size() % 3 != 0) {
      return MakeError(ErrorCode::kInvalidInput, path, "lights: a flat array of x, y, z expected");
    }
    for (size_t i = 0; i < l.size(); i += 3) {
      if (!l[i].is_number() || !l[i + 1].is_number() || !l[i + 2].is_number())
        return MakeError(ErrorCode::kInvalidInput, path, "lights: non-number at {}", i);
      c.lights.push_back({l[i].get<double>(), l[i + 1].get<double>(), l[i + 2].get<double>()});
    }
  }
  // Every plane's header and size against what info.json declares before anything is
  // allocated for the planes.
  RIG_ASSIGN_OR_RETURN(auto readers, OpenPlanes(folder, static_cast<int>((nplanes + 2) / 3), c.width, c.height));
  if (!read_planes) return c;
  for (int j = 0; j < c.terms; ++j)
    c.planes.emplace_back(c.height, c.width, c.lrgb ? CV_32FC1 : CV_32FC3);
  if (c.lrgb) c.albedo.create(c.height, c.width, CV_32FC3);
  for (int j = 0; 3 * j < nplanes; ++j) {
    const std::string plane = (fs::path(folder) / fmt::format("plane_{}.jpg", j)).string();
    JpegReader* reader = readers[j].get();
    cv::Mat rgb;
    RIG_TRY(reader->Read(c.height, &rgb));
    for (int k = 0; k < 3 && 3 * j + k < nplanes; ++k) {
      const int p = 3 * j + k;
      // Material::Plane::dequantize: 255·(byte/255 − bias)·scale; lrgb's albedo: the byte.
      const bool raw = c.lrgb && p < 3;
      const float a = raw ? 1.0f : static_cast<float>(scale[p]);
      const float b = raw ? 0.0f : static_cast<float>(-255.0 * bias[p] * scale[p]);
      cv::Mat& dst = c.lrgb ? (p < 3 ? c.albedo : c.planes[p - 3]) : c.planes[p / 3];
      const int ch = dst.channels();
      const int offset = ch == 1 ? 0 : 2 - (c.lrgb ? p : p % 3);  // B, G, R order
      for (int y = 0; y < c.height; ++y) {
        const uint8_t* in = rgb.ptr<uint8_t>(y);
        float* o = dst.ptr<float>(y);
        for (int x = 0; x < c.width; ++x) o[ch * x + offset] = in[3 * x + k] * a + b;
      }
    }
  }
  return c;
}

}  // namespace

// ---- .ptm ---------------------------------------------------------------------------------

Status WritePtm(const std::string& path, const RelightCoefficients& c) {
  CheckRelightCoefficients(c);
  RIG_TRY(CheckFinite(c, path));
  if (c.type != RelightType::kPtm) {
    return MakeError(ErrorCode::kInvalidInput, path, "a .ptm holds a PTM, not {}",
                     RelightTypeName(c.type));
  }
  const size_t n = static_cast<size_t>(c.width) * c.height;
  float scale[6];
  double bias[6];
  for (int f = 0; f < 6; ++f) {
    double lo, hi;
    Range(c.planes[kPtmFileToRelight[f]], -1, &lo, &hi);
    // The PTM specification's bias is a byte (coefficient = (byte − bias)·scale), and strict
    // readers refuse one outside 0..255: the range always holds 0, so the bias lies in 0..254.
    lo = std::min(lo, 0.0);
    hi = std::max(hi, 0.0);
    const double range = std::max(hi - lo, 1e-3);
    // 254 steps and a bias rounded up: every coefficient lands in [0, 255) before rounding,
    // whatever the integer bias does to the offset.
    scale[f] = std::stof(fmt::format("{:.9g}", range / 254.0));
    bias[f] = std::ceil(-lo / scale[f]);
  }
  std::string header = fmt::format("PTM_1.2\n{}\n{}\n{}\n", c.lrgb ? "PTM_FORMAT_LRGB" : "PTM_FORMAT_RGB",
                                   c.width, c.height);
  for (int f = 0; f < 6; ++f) header += fmt::format("{}{:.9g}", f ? " " : "", scale[f]);
  header += "\n";
  for (int f = 0; f < 6; ++f) header += fmt::format("{}{}", f ? " " : "", static_cast<long>(bias[f]));
  header += "\n";

  std::vector<uint8_t> data(n * (c.lrgb ? 9 : 18));
  uint8_t* out = data.data();
  if (!c.lrgb) {
    for (int k = 0; k < 3; ++k)           // R, G, B blocks
      for (int fy = 0; fy < c.height; ++fy) {  // file rows bottom-up
        const int y = c.height - 1 - fy;
        for (int x = 0; x < c.width; ++x)
          for (int f = 0; f < 6; ++f) {
            const float v = c.planes[kPtmFileToRelight[f]].ptr<float>(y)[3 * x + 2 - k];
            *out++ = ToByte(v / scale[f] + bias[f]);
          }
      }
  } else {
    for (int fy = 0; fy < c.height; ++fy) {
      const int y = c.height - 1 - fy;
      for (int x = 0; x < c.width; ++x)
        for (int f = 0; f < 6; ++f)
          *out++ = ToByte(c.planes[kPtmFileToRelight[f]].ptr<float>(y)[x] / scale[f] + bias[f]);
    }
    for (int fy = 0; fy < c.height; ++fy) {
      const float* a = c.albedo.ptr<float>(c.height - 1 - fy);
      for (int x = 0; x < c.width; ++x)
        for (int k = 0; k < 3; ++k) *out++ = ToByte(a[3 * x + 2 - k]);
    }
  }
  return WriteFile(path, header, data);
}

Result<RelightCoefficients> ReadPtm(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(LineFile f, LineFile::Open(path));
  RIG_ASSIGN_OR_RETURN(std::string version, f.Line("version"));
  if (version.rfind("PTM_1.", 0) != 0) {
    return MakeError(ErrorCode::kInvalidInput, path, "version: '{}' is not a PTM header (PTM_1.2)",
                     version.substr(0, 40));
  }
  RIG_ASSIGN_OR_RETURN(std::string format, f.Line("format"));
  RelightCoefficients c;
  c.type = RelightType::kPtm;
  c.terms = 6;
  if (format == "PTM_FORMAT_RGB") {
    c.lrgb = false;
  } else if (format == "PTM_FORMAT_LRGB") {
    c.lrgb = true;
  } else {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "format: '{}' is not read here (raw PTM_FORMAT_RGB and PTM_FORMAT_LRGB only)",
                     format.substr(0, 40));
  }
  // Width and height on their own lines (the specification), or both on one.
  RIG_ASSIGN_OR_RETURN(std::string wline, f.Line("width"));
  RIG_ASSIGN_OR_RETURN(std::vector<double> wh, Numbers(wline, 0, path, "width"));
  if (wh.size() > 2) return MakeError(ErrorCode::kInvalidInput, path, "width: '{}'", wline);
  if (wh.size() == 1) {
    RIG_ASSIGN_OR_RETURN(std::string hline, f.Line("height"));
    RIG_ASSIGN_OR_RETURN(std::vector<double> h, Numbers(hline, 1, path, "height"));
    wh.push_back(h[0]);
  }
  RIG_ASSIGN_OR_RETURN(int width, Integer(wh[0], path, "width"));
  RIG_ASSIGN_OR_RETURN(int height, Integer(wh[1], path, "height"));
  RIG_TRY(CheckSize(path + ": width, height", width, height));
  c.width = width;
  c.height = height;
  RIG_ASSIGN_OR_RETURN(std::string sline, f.Line("scale"));
  RIG_ASSIGN_OR_RETURN(std::vector<double> scale, Numbers(sline, 6, path, "scale"));
  RIG_ASSIGN_OR_RETURN(std::string bline, f.Line("bias"));
  RIG_ASSIGN_OR_RETURN(std::vector<double> bias, Numbers(bline, 6, path, "bias"));
  for (int fi = 0; fi < 6; ++fi) {  // (byte − bias)·scale, every value a float
    RIG_TRY(CheckFloatValue(scale[fi], path, fmt::format("scale {}", fi)));
    RIG_TRY(CheckFloatValue(bias[fi], path, fmt::format("bias {}", fi)));
    RIG_TRY(CheckDequantisation(scale[fi], -bias[fi] * scale[fi], path,
                                fmt::format("scale/bias {}", fi)));
  }

  const uint64_t n = static_cast<uint64_t>(width) * height;
  const uint64_t need = n * (c.lrgb ? 9 : 18);
  if (f.remaining() < need) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "truncated: {} {}x{} needs {} bytes of coefficients, the file holds {}", format,
                     width, height, need, f.remaining());
  }
  std::vector<uint8_t> data(need);
  RIG_TRY(f.Read(data.data(), need, "coefficients"));
  auto value = [&](int fi, uint8_t b) { return static_cast<float>((b - bias[fi]) * scale[fi]); };
  const uint8_t* in = data.data();
  if (!c.lrgb) {
    for (int j = 0; j < 6; ++j) c.planes.emplace_back(height, width, CV_32FC3);
    for (int k = 0; k < 3; ++k)
      for (int fy = 0; fy < height; ++fy) {
        const int y = height - 1 - fy;
        for (int x = 0; x < width; ++x)
          for (int fi = 0; fi < 6; ++fi)
            c.planes[kPtmFileToRelight[fi]].ptr<float>(y)[3 * x + 2 - k] = value(fi, *in++);
      }
  } else {
    for (int j = 0; j < 6; ++j) c.planes.emplace_back(height, width, CV_32FC1);
    c.albedo.create(height, width, CV_32FC3);
    // PTM 1.2: 6 interleaved luminance bytes per pixel, then an RGB block; before 1.2 all 9
    // interleaved.
    const bool v12 = version == "PTM_1.2";
    for (int fy = 0; fy < height; ++fy) {
      const int y = height - 1 - fy;
      for (int x = 0; x < width; ++x) {
        for (int fi = 0; fi < 6; ++fi) c.planes[kPtmFileToRelight[fi]].ptr<float>(y)[x] = value(fi, *in++);
        if (!v12)
          for (int k = 0; k < 3; ++k) c.albedo.ptr<float>(y)[3 * x + 2 - k] = *in++;
      }
    }
    if (v12) {
      for (int fy = 0; fy < height; ++fy) {
        float* a = c.albedo.ptr<float>(height - 1 - fy);
        for (int x = 0; x < width; ++x)
          for (int k = 0; k < 3; ++k) a[3 * x + 2 - k] = *in++;
      }
    }
  }
  return c;
}

// ---- .rti (HSH) ---------------------------------------------------------------------------

Status WriteRti(const std::string& path, const RelightCoefficients& c) {
  CheckRelightCoefficients(c);
  RIG_TRY(CheckFinite(c, path));
  if (c.type != RelightType::kHsh) {
    return MakeError(ErrorCode::kInvalidInput, path, "an HSH .rti holds HSH, not {}",
                     RelightTypeName(c.type));
  }
  const int t = c.terms;
  std::vector<float> scale(t), bias(t);  // coefficient = byte · scale + 255 · bias (0..255 units)
  for (int j = 0; j < t; ++j) {
    double lo, hi;
    Range(c.planes[j], -1, &lo, &hi);
    scale[j] = static_cast<float>(std::max(hi - lo, 1e-3) / 255.0);
    bias[j] = static_cast<float>(lo / 255.0);
  }
  const std::string header = fmt::format("#HSH1.2\n3\n{} {} 3\n{} 2 1\n", c.width, c.height, t);
  const size_t n = static_cast<size_t>(c.width) * c.height;
  std::vector<uint8_t> data(2 * t * sizeof(float) + n * 3 * t);
  static_assert(sizeof(float) == 4);
  uint8_t* out = data.data();
  auto put_float = [&](float v) {
    uint32_t u;
    std::memcpy(&u, &v, 4);
    for (int b = 0; b < 4; ++b) *out++ = static_cast<uint8_t>(u >> (8 * b));  // little-endian
  };
  for (float s : scale) put_float(s);
  for (float b : bias) put_float(b);
  for (int y = 0; y < c.height; ++y)
    for (int x = 0; x < c.width; ++x)
      for (int k = 0; k < 3; ++k)  // R, G, B
        for (int j = 0; j < t; ++j) {
          const float v = c.planes[j].ptr<float>(y)[3 * x + 2 - k];
          *out++ = ToByte((v - 255.0f * bias[j]) / scale[j]);
        }
  return WriteFile(path, header, data);
}

Result<RelightCoefficients> ReadRti(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(LineFile f, LineFile::Open(path));
  RIG_ASSIGN_OR_RETURN(std::string first, f.Line("#HSH1.2"));
  if (first.rfind("#HSH1.2", 0) != 0) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "first line: '{}' (only HSH .rti files, \"#HSH1.2\", are read here)",
                     first.substr(0, 40));
  }
  std::string line = "#";
  while (!line.empty() && line[0] == '#') {
    RIG_ASSIGN_OR_RETURN(line, f.Line("rti_type"));
  }
  RIG_ASSIGN_OR_RETURN(std::vector<double> type, Numbers(line, 1, path, "rti_type"));
  if (type[0] != 3) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "rti_type: {} is not read here (3, HSH; 1 is PTM, 2 SH, others adaptive)", type[0]);
  }
  RIG_ASSIGN_OR_RETURN(std::string dline, f.Line("width height components"));
  RIG_ASSIGN_OR_RETURN(std::vector<double> dims, Numbers(dline, 3, path, "width height components"));
  RIG_ASSIGN_OR_RETURN(int width, Integer(dims[0], path, "width"));
  RIG_ASSIGN_OR_RETURN(int height, Integer(dims[1], path, "height"));
  RIG_TRY(CheckSize(path + ": width, height", width, height));
  if (dims[2] != 3) {
    return MakeError(ErrorCode::kInvalidInput, path, "components: {} (3 expected)", dims[2]);
  }
  RIG_ASSIGN_OR_RETURN(std::string bline, f.Line("terms basis_type element_size"));
  RIG_ASSIGN_OR_RETURN(std::vector<double> basis,
                       Numbers(bline, 3, path, "terms basis_type element_size"));
  RIG_ASSIGN_OR_RETURN(int terms, Integer(basis[0], path, "terms"));
  if (terms != 9 && terms != 4 && terms != 1 && terms != 16) {
    return MakeError(ErrorCode::kInvalidInput, path, "terms: {} (HSH of 1, 4, 9 or 16 terms expected)", terms);
  }
  if (basis[2] != 1) {
    return MakeError(ErrorCode::kInvalidInput, path, "element_size: {} (1-byte elements only)", basis[2]);
  }
  RelightCoefficients c;
  c.type = RelightType::kHsh;
  c.terms = terms;
  c.width = width;
  c.height = height;
  const uint64_t n = static_cast<uint64_t>(width) * height;
  const uint64_t need = 8ull * terms + n * 3 * terms;
  if (f.remaining() < need) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "truncated: HSH {}x{} with {} terms needs {} bytes of scale, bias and "
                     "coefficients, the file holds {}",
                     width, height, terms, need, f.remaining());
  }
  std::vector<uint8_t> data(need);
  RIG_TRY(f.Read(data.data(), need, "coefficients"));
  const uint8_t* in = data.data();
  auto get_float = [&]() {
    uint32_t u = 0;
    for (int b = 0; b < 4; ++b) u |= static_cast<uint32_t>(*in++) << (8 * b);
    float v;
    std::memcpy(&v, &u, 4);
    return v;
  };
  std::vector<float> scale(terms), bias(terms);
  for (auto& s : scale) s = get_float();
  for (auto& b : bias) b = get_float();
  for (int j = 0; j < terms; ++j) {
    // byte·scale + 255·bias, every value a float.
    RIG_TRY(CheckDequantisation(scale[j], 255.0 * double(bias[j]), path,
                                fmt::format("scale/bias of term {}", j)));
  }
  for (int j = 0; j < terms; ++j) c.planes.emplace_back(height, width, CV_32FC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < terms; ++j)
          c.planes[j].ptr<float>(y)[3 * x + 2 - k] = *in++ * scale[j] + 255.0f * bias[j];
  return c;
}

// ---- .lp ----------------------------------------------------------------------------------

Status WriteLp(const std::string& path, const std::vector<std::string>& images,
               const std::vector<Vec3>& directions) {
  RIG_CHECK(images.size() == directions.size(), "WriteLp: one direction per image");
  std::string text = fmt::format("{}\n", images.size());
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i].find_first_of(" \t\n") != std::string::npos) {
      return MakeError(ErrorCode::kInvalidInput, path, "image name '{}' holds white space", images[i]);
    }
    const auto& d = directions[i];
    text += fmt::format("{} {:.6f} {:.6f} {:.6f}\n", images[i], d[0], d[1], d[2]);
  }
  return WriteFile(path, text, {});
}

}  // namespace rig
