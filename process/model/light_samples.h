// Multi-light samples of a pixel block: every pixel's value under every lamp, as the images
// stored them, with the per-channel mask of samples that carry no information (clipped or
// black). The common input of the data-driven model families (PCA, neural).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "process/model/light_direction.h"

namespace rig {

// Thresholds of the LDR mask, in 8-bit code values, per channel: a sample at or below
// `black_max` or at or above `clipped_min` is missing. 8-bit JPEG rings by a few codes around
// a clipped area, so "near 255" is 250 and up; "near 0" is 2 and below (below the noise of
// every camera's black level after JPEG).
struct LdrMaskThresholds {
  int black_max = 2;
  int clipped_min = 250;
};

struct LightSamples {
  int width = 0, height = 0;     // the block: pixels = width * height, row-major
  std::vector<Vec3> directions;  // L unit lamp directions (x right, y up, z towards the camera)
  // values[(pixel * L + light) * 3 + c], c = 0 R, 1 G, 2 B: 8-bit code values as stored
  // (display-referred, sRGB for the usual RTI capture).
  std::vector<uint8_t> values;
  // Same indexing: 1 usable, 0 missing (clipped or black). Empty: every sample usable.
  std::vector<uint8_t> usable;

  size_t pixels() const { return static_cast<size_t>(width) * static_cast<size_t>(height); }
  int lights() const { return static_cast<int>(directions.size()); }
  uint8_t value(size_t pixel, int light, int c) const {
    return values[(pixel * directions.size() + static_cast<size_t>(light)) * 3 + c];
  }
  bool is_usable(size_t pixel, int light, int c) const {
    return usable.empty() ||
           usable[(pixel * directions.size() + static_cast<size_t>(light)) * 3 + c] != 0;
  }
};

// Fills `usable` from the values (per channel, thresholds above) and returns how many
// sample-channels were marked missing.
size_t MaskLdrSamples(LightSamples* samples, const LdrMaskThresholds& thresholds = {});

// A near lamp (docs/lights.md "Near lamps"): every sample divided by its pixel's fall-off
// (NearLamp::InverseFalloff, the block taken as the whole width x height image and the sample's
// lamp direction), in linear units — the codes sRGB-decoded when `srgb`, else taken as linear
// — then encoded and rounded back to codes. A sample pushed to 255 or beyond is clipped there
// and marked missing (`usable` filled by MaskLdrSamples first when empty); returns how many.
// A far lamp leaves the samples unchanged.
size_t DivideSamplesByFalloff(const NearLamp& lamp, bool srgb, LightSamples* samples,
                              const LdrMaskThresholds& thresholds = {});

// The same samples without light `held_out` (its directions, values and mask removed).
LightSamples WithoutLight(const LightSamples& samples, int held_out);

// The same samples of the lights `kept` only (indices into samples.directions), in that order.
LightSamples OnlyLights(const LightSamples& samples, const std::vector<int>& kept);

}  // namespace rig
