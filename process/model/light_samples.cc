// The LDR mask and fold construction for multi-light samples.
#include "process/model/light_samples.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "process/model/samples.h"

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

size_t DivideSamplesByFalloff(const NearLamp& lamp, bool srgb, LightSamples* samples,
                              const LdrMaskThresholds& thresholds) {
  if (!lamp.near() || samples->values.empty()) return 0;
  if (samples->usable.empty()) MaskLdrSamples(samples, thresholds);
  std::array<float, 256> linear;
  for (int v = 0; v < 256; ++v) linear[v] = srgb ? SrgbDecode(v / 255.0f) : v / 255.0f;
  const int lights = samples->lights();
  const size_t pixels = samples->pixels();
  size_t clipped = 0;
  for (size_t p = 0; p < pixels; ++p) {
    const int i = static_cast<int>(p % static_cast<size_t>(samples->width));
    const int j = static_cast<int>(p / static_cast<size_t>(samples->width));
    for (int l = 0; l < lights; ++l) {
      const float f = static_cast<float>(
          lamp.InverseFalloff(i, j, samples->width, samples->height, samples->directions[l]));
      const size_t at = (p * static_cast<size_t>(lights) + static_cast<size_t>(l)) * 3;
      for (int c = 0; c < 3; ++c) {
        const float x = linear[samples->values[at + c]] * f;
        const float code = 255.0f * (srgb ? SrgbEncode(x) : x);
        if (code >= 254.5f) {
          if (samples->usable[at + c]) ++clipped;
          samples->usable[at + c] = 0;
          samples->values[at + c] = 255;
        } else {
          samples->values[at + c] = static_cast<uint8_t>(std::lround(std::max(0.0f, code)));
        }
      }
    }
  }
  return clipped;
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

LightSamples OnlyLights(const LightSamples& samples, const std::vector<int>& kept) {
  LightSamples out;
  out.width = samples.width;
  out.height = samples.height;
  for (int l : kept) out.directions.push_back(samples.directions[static_cast<size_t>(l)]);
  const size_t pixels = samples.pixels();
  const size_t row_in = samples.directions.size() * 3, row_out = kept.size() * 3;
  out.values.resize(pixels * row_out);
  if (!samples.usable.empty()) out.usable.resize(pixels * row_out);
  for (size_t p = 0; p < pixels; ++p) {
    for (size_t k = 0; k < kept.size(); ++k) {
      const size_t from = p * row_in + static_cast<size_t>(kept[k]) * 3, to = p * row_out + k * 3;
      std::copy_n(samples.values.data() + from, 3, out.values.data() + to);
      if (!samples.usable.empty()) std::copy_n(samples.usable.data() + from, 3, out.usable.data() + to);
    }
  }
  return out;
}

}  // namespace rig
