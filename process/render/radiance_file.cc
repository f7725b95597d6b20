#include "process/render/radiance_file.h"

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
  if (ext == ".exr") return ReadRgbExr(path);
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
