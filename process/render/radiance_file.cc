#include "process/render/radiance_file.h"

#include <limits>

#include <cctype>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"

namespace rig {

Result<cv::Mat> ReadRadianceFile(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    return MakeError(ErrorCode::kNotFound, path, "no such file");
  }
  if (ext == ".exr") {
    RIG_ASSIGN_OR_RETURN(cv::Mat exr, ReadRgbExr(path));
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
    return exr;
  }
  if (ext != ".hdr" && ext != ".pic") {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "unknown HDR format '{}' (.exr, .hdr or .pic expected)", ext);
  }
  cv::Mat img;
  try {
    img = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_COLOR);
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kInvalidInput, path, "cannot read: {}", e.what());
  }
  if (img.empty() || img.type() != CV_32FC3) {
    return MakeError(ErrorCode::kInvalidInput, path, "not a readable Radiance RGBE picture");
  }
  return img;
}

}  // namespace rig
