// Camera RAW files through LibRaw: linear sensor values, black level subtracted and white level
// scaled to the full 16-bit range, the camera's white balance (or a fixed one, or none), no
// tone curve, no colour matrix (the sensor's own primaries), the sensor's layout (no rotation).
// Photosites at or above the white level are clipped: every output pixel they reach through
// demosaicing is set to the top level, so a merge gives it no weight.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

enum class RawWhiteBalance { kCamera, kFixed, kNone };

struct RawDecodeOptions {
  RawWhiteBalance white_balance = RawWhiteBalance::kCamera;
  std::array<double, 3> fixed_rgb{1, 1, 1};  // kFixed: multipliers for R, G, B
};

struct RawInfo {
  std::string camera;          // make and model as LibRaw reports them
  double black = 0, white = 0;  // levels in raw units
  double shutter_s = 0;         // the exposure time in the file's metadata (0: none)
  std::array<double, 3> multipliers{1, 1, 1};  // R, G, B multipliers applied
  double clipped_fraction = 0;  // share of photosites at or above the white level
  bool mosaic = false;          // a colour filter array was demosaiced
};

// The file name endings read as RAW (lower case, with the dot): .dng .cr2 .cr3 .nef .arw .raf
// .orf .rw2 .pef .srw.
bool IsRawPath(const std::string& path);

// Decodes a RAW file's bytes into CV_16UC3 BGR (linear). `path` names it in errors.
Result<cv::Mat> DecodeRawBytes(std::span<const uint8_t> bytes, const std::string& path,
                               const RawDecodeOptions& options = {}, RawInfo* info = nullptr);

}  // namespace rig
