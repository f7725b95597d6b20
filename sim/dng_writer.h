// A minimal DNG writer (libtiff), so the simulated camera can hand out RAW files that LibRaw
// reads like a real body's: 16-bit sensor values with a black and a white level, either a
// Bayer mosaic (CFA, RGGB) or three linear channels per pixel (LinearRaw), the as-shot white
// balance, an identity colour matrix (the simulated sensor's primaries are the scene's) and
// the exposure time.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

struct DngOptions {
  bool mosaic = true;          // RGGB Bayer (one value per photosite); false: LinearRaw RGB
  uint16_t black = 0;          // zero-light level
  uint16_t white = 65535;      // the saturation level
  double exposure_s = 0;       // written as ExposureTime when > 0
  double as_shot_neutral[3] = {1, 1, 1};  // R, G, B: the neutral's camera values (1/WB)
  std::string model = "rig simulator";
};

// Encodes CV_16UC3 BGR sensor values (black level included, clipped at white) as DNG bytes.
Result<std::vector<uint8_t>> EncodeDng(const cv::Mat& bgr16, const DngOptions& options);

}  // namespace rig
