// Radiance maps from OpenEXR or Radiance RGBE files, with their header: primaries, view,
// exposure and colour correction, following Radiance's color.h, header.c and image.c.
#include "process/render/radiance_file.h"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"

namespace rig {
namespace {

constexpr double kColourEpsilon = 1e-4;  // Radiance's CEPS
constexpr size_t kMaxHeaderBytes = 1 << 16;

// The Sharp primaries von Kries adaptation works in (Radiance's vkmat and its inverse).
const cv::Matx33d kSharp(1.2694, -0.0988, -0.1706, -0.8364, 1.8006, 0.0357, 0.0297, -0.0315,
                         1.0018);

bool Near(double a, double b) { return std::abs(a - b) <= kColourEpsilon; }

// RGB → XYZ without white balance: the columns are the primaries' XYZ scaled so that RGB
// (1, 1, 1) is the white with Y = 1.
Result<cv::Matx33d> RgbToXyz(const Chromaticities& p) {
  const cv::Matx33d prim(p.red_x, p.green_x, p.blue_x, p.red_y, p.green_y, p.blue_y,
                         1 - p.red_x - p.red_y, 1 - p.green_x - p.green_y,
                         1 - p.blue_x - p.blue_y);
  if (!(std::abs(cv::determinant(prim)) > 1e-9) || !(p.white_y > kColourEpsilon)) {
    return MakeError(ErrorCode::kInvalidInput, "primaries",
                     "degenerate chromaticities (collinear primaries or a white with y = 0)");
  }
  const cv::Vec3d white(p.white_x / p.white_y, 1, (1 - p.white_x - p.white_y) / p.white_y);
  const cv::Vec3d scale = prim.inv() * white;
  return prim * cv::Matx33d::diag(scale);
}

// The von Kries transform (in XYZ) that carries white xy `from` to white xy `to`.
cv::Matx33d VonKries(double from_x, double from_y, double to_x, double to_y) {
  if (Near(from_x, to_x) && Near(from_y, to_y)) return cv::Matx33d::eye();
  const cv::Vec3d w1 = kSharp * cv::Vec3d(from_x / from_y, 1, (1 - from_x - from_y) / from_y);
  const cv::Vec3d w2 = kSharp * cv::Vec3d(to_x / to_y, 1, (1 - to_x - to_y) / to_y);
  const cv::Matx33d d = cv::Matx33d::diag(cv::Vec3d(w2[0] / w1[0], w2[1] / w1[1], w2[2] / w1[2]));
  return kSharp.inv() * d * kSharp;
}

Error BadLine(const std::string& path, const std::string& line, const std::string& why) {
  return MakeError(ErrorCode::kInvalidInput, path, "header line '{}': {}", line, why);
}

// The numbers after a "NAME=" prefix; false when fewer than `n` parse.
bool Numbers(const std::string& rest, size_t n, std::vector<double>* out) {
  std::istringstream in(rest);
  out->clear();
  double v = 0;
  while (out->size() < n && in >> v) out->push_back(v);
  return out->size() == n;
}

// Radiance's isview: a VIEW= line, or a command line of a program that writes its view.
bool IsViewLine(const std::string& line) {
  std::string first = line.substr(0, line.find(' '));
  first = first.substr(first.find_last_of('/') == std::string::npos ? 0
                                                                    : first.find_last_of('/') + 1);
  for (const char* name : {"VIEW=", "rpict", "rvu", "rpiece", "pinterp"}) {
    if (first.rfind(name, 0) == 0) return true;
  }
  return false;
}

// Radiance's sscanview: applies every view option of the line to `view`; the others (and
// the arguments of -vp, -vd, -vu, -vo, -va, -vs, -vl) are skipped.
Status ScanView(const std::string& line, const std::string& path, PictureView* view) {
  std::istringstream in(line.rfind("VIEW=", 0) == 0 ? line.substr(5) : line.substr(line.find(' ') + 1));
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  for (size_t i = 0; i < words.size(); ++i) {
    const std::string& w = words[i];
    if (w.size() < 3 || w[0] != '-' || w[1] != 'v') continue;
    if (w[2] == 't' && w.size() == 4) {
      view->type = w[3];
    } else if ((w == "-vh" || w == "-vv") && i + 1 < words.size()) {
      char* end = nullptr;
      const double deg = std::strtod(words[i + 1].c_str(), &end);
      if (end == words[i + 1].c_str() || *end != '\0' || !std::isfinite(deg)) {
        return BadLine(path, line, fmt::format("{} needs a number of degrees", w));
      }
      (w == "-vh" ? view->horizontal_deg : view->vertical_deg) = deg;
      ++i;
    } else if (w == "-vp" || w == "-vd" || w == "-vu") {
      i += 3;
    } else if (w == "-vo" || w == "-va" || w == "-vs" || w == "-vl") {
      i += 1;
    }
  }
  return Ok();
}

// The header's text: everything before the first empty line, read from at most the first
// kMaxHeaderBytes of the file (a file without newlines is not read whole).
Result<std::string> ReadHeaderText(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return MakeError(ErrorCode::kIo, path, "cannot open");
  std::string head(kMaxHeaderBytes, '\0');
  f.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(f.gcount()));
  const size_t end = head.find("\n\n");
  if (end == std::string::npos) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "no end of the Radiance header (an empty line) in its first {} bytes",
                     kMaxHeaderBytes);
  }
  return head.substr(0, end + 1);
}

Result<RadiancePicture> ReadExrPicture(const std::string& path) {
  std::optional<std::array<double, 8>> c;
  RIG_ASSIGN_OR_RETURN(cv::Mat exr, ReadRgbExr(path, nullptr, 2, &c));
  std::optional<Chromaticities> chroma;
  if (c) chroma = Chromaticities{(*c)[0], (*c)[1], (*c)[2], (*c)[3], (*c)[4], (*c)[5], (*c)[6], (*c)[7]};
  // NaN or infinite pixels would come out black without a word: refused, the first named.
  cv::Point at;
  if (!cv::checkRange(exr.reshape(1), true, &at)) {
    cv::Mat nan;
    cv::compare(exr.reshape(1), exr.reshape(1), nan, cv::CMP_NE);
    cv::Mat inf = cv::abs(exr.reshape(1)) == std::numeric_limits<float>::infinity();
    return MakeError(ErrorCode::kInvalidInput, path,
                     "{} sample(s) are NaN and {} infinite (the first at pixel x={} y={}); a "
                     "radiance map holds finite values only",
                     cv::countNonZero(nan), cv::countNonZero(inf), at.x / 3, at.y);
  }
  RadiancePicture picture;
  picture.radiance = exr;
  picture.header.primaries = chroma ? *chroma : Rec709Primaries();
  picture.header.primaries_given = chroma.has_value();
  if (chroma && !RgbToXyz(*chroma).ok()) {
    return MakeError(ErrorCode::kInvalidInput, path, "the chromaticities attribute is degenerate");
  }
  return picture;
}

}  // namespace

bool Chromaticities::SameAs(const Chromaticities& o) const {
  return Near(red_x, o.red_x) && Near(red_y, o.red_y) && Near(green_x, o.green_x) &&
         Near(green_y, o.green_y) && Near(blue_x, o.blue_x) && Near(blue_y, o.blue_y) &&
         Near(white_x, o.white_x) && Near(white_y, o.white_y);
}

Chromaticities RadiancePrimaries() { return {0.640, 0.330, 0.290, 0.600, 0.150, 0.060, 0.3333, 0.3333}; }

Chromaticities Rec709Primaries() { return {0.640, 0.330, 0.300, 0.600, 0.150, 0.060, 0.3127, 0.3290}; }

Result<cv::Matx33d> RgbToXyzWhiteBalanced(const Chromaticities& p) {
  RIG_ASSIGN_OR_RETURN(cv::Matx33d m, RgbToXyz(p));
  return VonKries(p.white_x, p.white_y, 1.0 / 3, 1.0 / 3) * m;
}

Result<cv::Matx33d> RgbToRgbWhiteBalanced(const Chromaticities& from, const Chromaticities& to) {
  if (from.SameAs(to)) return cv::Matx33d::eye();
  RIG_ASSIGN_OR_RETURN(cv::Matx33d from_xyz, RgbToXyz(from));
  RIG_ASSIGN_OR_RETURN(cv::Matx33d to_xyz, RgbToXyz(to));
  return to_xyz.inv() * VonKries(from.white_x, from.white_y, to.white_x, to.white_y) * from_xyz;
}

Result<std::array<double, 2>> ViewExtent(const PictureView& v) {
  constexpr double kRad = std::numbers::pi / 180;
  constexpr double kTiny = 1e-6;  // Radiance's FTINY
  auto bad = [&](const char* what) {
    return MakeError(ErrorCode::kInvalidInput, "view",
                     "illegal {} view size for -vt{} (-vh {} -vv {})", what, v.type,
                     v.horizontal_deg, v.vertical_deg);
  };
  const double h = v.horizontal_deg, vv = v.vertical_deg;
  if (!(h > kTiny)) return bad("horizontal");
  if (!(vv > kTiny)) return bad("vertical");
  switch (v.type) {
    case 'l': return std::array<double, 2>{h, vv};
    case 'v':
      if (!(h < 180 - kTiny)) return bad("horizontal");
      if (!(vv < 180 - kTiny)) return bad("vertical");
      return std::array<double, 2>{2 * std::tan(h * kRad / 2), 2 * std::tan(vv * kRad / 2)};
    case 'c':
      if (!(h <= 360 + kTiny)) return bad("horizontal");
      if (!(vv < 180 - kTiny)) return bad("vertical");
      return std::array<double, 2>{h * kRad, 2 * std::tan(vv * kRad / 2)};
    case 'a':
      if (!(h <= 360 + kTiny)) return bad("horizontal");
      if (!(vv <= 360 + kTiny)) return bad("vertical");
      return std::array<double, 2>{h * kRad, vv * kRad};
    case 'h':
      if (!(h <= 180 + kTiny)) return bad("horizontal");
      if (!(vv <= 180 + kTiny)) return bad("vertical");
      return std::array<double, 2>{2 * std::sin(h * kRad / 2), 2 * std::sin(vv * kRad / 2)};
    default:
      return MakeError(ErrorCode::kInvalidInput, "view",
                       "unknown view type -vt{} (v, l, c, h or a)", v.type);
  }
}

Result<PictureHeader> ParseRadianceHeader(const std::string& text, const std::string& path) {
  PictureHeader h;
  h.primaries = RadiancePrimaries();
  std::istringstream in(text);
  std::vector<double> n;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.rfind("EXPOSURE=", 0) == 0) {
      if (!Numbers(line.substr(9), 1, &n) || !(n[0] > 0) || !std::isfinite(n[0])) {
        return BadLine(path, line, "EXPOSURE must be a positive number");
      }
      h.exposure *= n[0];
    } else if (line.rfind("COLORCORR=", 0) == 0) {
      if (!Numbers(line.substr(10), 3, &n) || !(n[0] > 0 && n[1] > 0 && n[2] > 0) ||
          !std::isfinite(n[0] + n[1] + n[2])) {
        return BadLine(path, line, "COLORCORR needs three positive numbers (R G B)");
      }
      for (int c = 0; c < 3; ++c) h.colour_correction[c] *= n[c];
    } else if (line.rfind("PIXASPECT=", 0) == 0) {
      if (!Numbers(line.substr(10), 1, &n) || !(n[0] > 0) || !std::isfinite(n[0])) {
        return BadLine(path, line, "PIXASPECT must be a positive number");
      }
      h.pixel_aspect *= n[0];
    } else if (line.rfind("PRIMARIES=", 0) == 0) {
      if (!Numbers(line.substr(10), 8, &n)) {
        return BadLine(path, line, "PRIMARIES needs eight numbers (xr yr xg yg xb yb xw yw)");
      }
      const Chromaticities p{n[0], n[1], n[2], n[3], n[4], n[5], n[6], n[7]};
      if (!RgbToXyz(p).ok()) return BadLine(path, line, "the primaries are degenerate");
      h.primaries = p;
      h.primaries_given = true;
    } else if (IsViewLine(line)) {
      PictureView view = h.view.value_or(PictureView{});
      RIG_TRY(ScanView(line, path, &view));
      h.view = view;
    }
  }
  return h;
}

Result<RadiancePicture> ReadRadiancePicture(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return MakeError(ErrorCode::kNotFound, path, "no such file");
  }
  if (ext == ".exr") return ReadExrPicture(path);
  if (ext != ".hdr" && ext != ".pic") {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "unknown HDR format '{}' (.exr, .hdr or .pic expected)", ext);
  }
  RIG_ASSIGN_OR_RETURN(std::string text, ReadHeaderText(path));
  RIG_ASSIGN_OR_RETURN(PictureHeader header, ParseRadianceHeader(text, path));
  cv::Mat img;
  try {
    img = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_COLOR);
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kInvalidInput, path, "cannot read: {}", e.what());
  }
  if (img.empty() || img.type() != CV_32FC3) {
    return MakeError(ErrorCode::kInvalidInput, path, "not a readable Radiance RGBE picture");
  }
  // Stored = original × EXPOSURE × COLORCORR (per channel): divided out, B, G, R order.
  const cv::Scalar divide(1 / (header.exposure * header.colour_correction[2]),
                          1 / (header.exposure * header.colour_correction[1]),
                          1 / (header.exposure * header.colour_correction[0]));
  if (divide != cv::Scalar::all(1)) cv::multiply(img, divide, img);
  return RadiancePicture{img, header};
}

Result<cv::Mat> ReadRadianceFile(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(RadiancePicture picture, ReadRadiancePicture(path));
  return picture.radiance;
}

}  // namespace rig
