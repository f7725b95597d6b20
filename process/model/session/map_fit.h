// Fitting a model to radiance maps with known lamp angles (a LIST of "<radiance.exr> <h_deg>
// <v_deg>" lines): in memory, or streamed by row bands when the samples exceed a bound. What
// `rig fit --list` does, callable without it.
#pragma once

#include <string>
#include <vector>

#include "config/config.h"
#include "config/result.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/model.h"

namespace rig {

struct MapListEntry {
  std::string path;  // resolved against the list's folder
  double h_deg = 0, v_deg = 0;
};
// '#' comments and blank lines skipped; errors name list:line.
Result<std::vector<MapListEntry>> ReadMapList(const std::string& list);

struct MapFitRequest {
  std::string list;
  Config config;               // light frame, lamp radiance, [process]
  FitOptions options;
  std::string out;             // model EXR
  ExrPixelType pixel_type = ExrPixelType::kHalf;
  size_t stream_above_bytes = size_t{1} << 30;
};

struct MapFitResult {
  bool streamed = false;
  std::string summary;  // one line
  std::string report;   // Markdown (in-memory fits)
};

Result<MapFitResult> FitMaps(const MapFitRequest& request);

}  // namespace rig
