// Reading a radiance map for rendering and tone mapping: OpenEXR (R, G, B) or Radiance RGBE
// (.hdr, .pic), as linear CV_32FC3 BGR.
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

// Errors name the file: missing (kNotFound), unknown extension or unreadable (kInvalidInput).
Result<cv::Mat> ReadRadianceFile(const std::string& path);

}  // namespace rig
