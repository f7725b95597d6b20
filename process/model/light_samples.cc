// The LDR mask and fold construction for multi-light samples.
#include "process/model/light_samples.h"

#include <algorithm>

namespace rig {

size_t MaskLdrSamples(LightSamples* samples, const LdrMaskThresholds& thresholds) {
  const size_t n = samples->values.size();
  samples->usable.assign(n, 1);
  size_t missing = 0;
  for (size_t i = 0; i < n; ++i) {
    const int v = samples->values[i];
    if (v <= thresholds.black_max || v >= thresholds.clipped_min) {
      samples->usable[i] = 0;
      ++missing;
    }
  }
  return missing;
}

LightSamples WithoutLight(const LightSamples& samples, int held_out) {
  LightSamples out;
  out.width = samples.width;
  out.height = samples.height;
  const int lights = samples.lights();
  for (int l = 0; l < lights; ++l) {
    if (l != held_out) out.directions.push_back(samples.directions[l]);
  }
  const size_t pixels = samples.pixels();
  const size_t row_in = static_cast<size_t>(lights) * 3;
  const size_t row_out = row_in - 3;
  out.values.resize(pixels * row_out);
  if (!samples.usable.empty()) out.usable.resize(pixels * row_out);
  const size_t cut = static_cast<size_t>(held_out) * 3;
  for (size_t p = 0; p < pixels; ++p) {
    const uint8_t* src = samples.values.data() + p * row_in;
    uint8_t* dst = out.values.data() + p * row_out;
    std::copy(src, src + cut, dst);
    std::copy(src + cut + 3, src + row_in, dst + cut);
    if (!samples.usable.empty()) {
      const uint8_t* us = samples.usable.data() + p * row_in;
      uint8_t* ud = out.usable.data() + p * row_out;
      std::copy(us, us + cut, ud);
      std::copy(us + cut + 3, us + row_in, ud + cut);
    }
  }
  return out;
}

}  // namespace rig
