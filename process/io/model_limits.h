// Checks every model reader makes before it trusts a value or allocates (issue 30, item 11):
// a scale, bias or coefficient that a float cannot hold renders as a black or white picture,
// and a declared size is believed only when the files are large enough to hold it.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "config/result.h"

namespace rig {

// `value` finite and within float range; the error names the file and the field
// ("materials[0].scale[3]").
inline Status CheckFloatValue(double value, const std::string& path, const std::string& field) {
  if (!std::isfinite(value) || std::fabs(value) > std::numeric_limits<float>::max()) {
    return MakeError(ErrorCode::kInvalidInput, path, "{}: {} is not a finite value within float range",
                     field, value);
  }
  return Ok();
}

// A byte b dequantised as b·scale + offset over b in 0..255 (relight's 255·(b/255 − bias)·scale,
// .ptm's (b − bias)·scale, .rti's (b/255·scale + bias)·255): scale and offset, and every value
// they give, within float range.
inline Status CheckDequantisation(double scale, double offset, const std::string& path,
                                  const std::string& field) {
  RIG_TRY(CheckFloatValue(scale, path, field + " (scale)"));
  RIG_TRY(CheckFloatValue(offset, path, field + " (offset)"));
  RIG_TRY(CheckFloatValue(offset + 255.0 * scale, path, field + " (value of byte 255)"));
  return Ok();
}

// The smallest a baseline JPEG of width×height can be: a bit per 8×8 block of its first
// component (a DC difference and an end of block take at least that). A header declaring
// more than its file can hold is refused before anything is allocated for it.
inline uint64_t MinJpegBytes(int64_t width, int64_t height) {
  const uint64_t blocks = static_cast<uint64_t>((width + 7) / 8) * static_cast<uint64_t>((height + 7) / 8);
  return blocks / 8;
}

}  // namespace rig
