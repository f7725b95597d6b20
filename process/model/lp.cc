// The RTI light file (.lp: a count, then `<image> <x> <y> <z>` per line) and its images,
// shared by every family that fits photographs.
#include "process/model/lp.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "config/log.h"
#include "process/model/samples.h"

namespace rig {

std::optional<double> LiftToLowestElevation(Vec3* d) {
  const double z = std::clamp((*d)[2], -1.0, 1.0);
  const double elevation = std::asin(z) * 180 / M_PI;
  if (!(elevation >= -kHorizonToleranceDeg && elevation < kLowestElevationDeg)) return std::nullopt;
  const double azimuth = std::atan2((*d)[1], (*d)[0]);
  const double e = kLowestElevationDeg * M_PI / 180;
  *d = {std::cos(e) * std::cos(azimuth), std::cos(e) * std::sin(azimuth), std::sin(e)};
  return elevation;
}

Result<std::vector<LpEntry>> ReadLp(const std::string& path) {
  std::ifstream f(path);
  if (!f) return MakeError(ErrorCode::kNotFound, path, "cannot open the light file");
  const std::filesystem::path folder = std::filesystem::path(path).parent_path();
  std::string line;
  int lineno = 0;
  long count = -1;
  std::vector<LpEntry> out;
  while (std::getline(f, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;  // blank, or a comment
    std::istringstream is(line);
    const std::string where = fmt::format("{}:{}", path, lineno);
    if (count < 0) {
      std::string token, extra;
      size_t used = 0;
      try {
        if (!(is >> token) || (is >> extra)) throw std::invalid_argument("count");
        count = std::stol(token, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != token.size() || count <= 0 || count > 100000) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "expected the image count (a whole number from 1 to 100000), got '{}'",
                         line);
      }
      continue;
    }
    LpEntry e;
    e.line = lineno;
    std::string extra;
    if (!(is >> e.image >> e.direction[0] >> e.direction[1] >> e.direction[2]) || (is >> extra) ||
        !std::isfinite(e.direction[0]) || !std::isfinite(e.direction[1]) ||
        !std::isfinite(e.direction[2])) {
      return MakeError(ErrorCode::kInvalidInput, where, "expected '<image> <x> <y> <z>', got '{}'",
                       line);
    }
    const double n = std::sqrt(e.direction[0] * e.direction[0] + e.direction[1] * e.direction[1] +
                               e.direction[2] * e.direction[2]);
    if (!(n > 0.5 && n < 1.5)) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "light direction ({}, {}, {}) is not a unit vector", e.direction[0],
                       e.direction[1], e.direction[2]);
    }
    for (auto& c : e.direction) c /= n;
    if (auto before = LiftToLowestElevation(&e.direction)) {
      Log("process")->warn("{}: light at elevation {:.3f} deg, at the horizon within {} deg: taken "
                           "at {} deg", where, *before, kHorizonToleranceDeg, kLowestElevationDeg);
    }
    std::filesystem::path p(e.image);
    if (p.is_relative()) p = folder / p;
    e.image = p.string();
    out.push_back(e);
  }
  if (count < 0) return MakeError(ErrorCode::kInvalidInput, path, "empty light file");
  if (static_cast<long>(out.size()) != count) {
    if (static_cast<long>(out.size()) > count) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("{}:{}", path, out[count].line),
                       "the count says {} images, this is image {}", count, count + 1);
    }
    return MakeError(ErrorCode::kInvalidInput, path, "the count says {} images, {} are listed",
                     count, out.size());
  }
  return out;
}

Result<RtiImages> LoadRtiImages(const std::vector<LpEntry>& entries, bool linear,
                                int downsample) {
  RtiImages out;
  cv::Mat lut(1, 256, CV_32F);
  for (int v = 0; v < 256; ++v)
    lut.at<float>(v) = linear ? v / 255.0f : SrgbDecode(v / 255.0f);
  for (const auto& e : entries) {
    cv::Mat img;
    try {
      img = cv::imread(e.image, cv::IMREAD_COLOR);
    } catch (const cv::Exception& ex) {
      return MakeError(ErrorCode::kIo, e.image, "cannot read: {}", ex.what());
    }
    if (img.empty()) return MakeError(ErrorCode::kNotFound, e.image, "cannot read the image");
    if (downsample > 1) {
      cv::Mat small;
      cv::resize(img, small, cv::Size(img.cols / downsample, img.rows / downsample), 0, 0,
                 cv::INTER_AREA);
      img = small;
    }
    if (!out.encoded.empty() && img.size() != out.encoded[0].size()) {
      return MakeError(ErrorCode::kInvalidInput, e.image, "size {}x{} differs from the first image",
                       img.cols, img.rows);
    }
    cv::Mat rad(img.size(), CV_32FC3);
    for (int y = 0; y < img.rows; ++y) {
      const uint8_t* s = img.ptr<uint8_t>(y);
      float* d = rad.ptr<float>(y);
      for (int x = 0; x < img.cols * 3; ++x) d[x] = lut.at<float>(s[x]);
    }
    out.encoded.push_back(img);
    out.radiance.push_back(rad);
  }
  return out;
}

}  // namespace rig
