// One bracket list to one radiance map file: `rig hdr`'s work. LIST holds one
// '<image> <exposure_s>' per line; RAW frames are linear once decoded (no response recovered).
#pragma once

#include <map>
#include <string>

#include "config/result.h"
#include "process/hdr/hdr.h"
#include "process/io/exr_io.h"

namespace rig {

struct BracketFileRequest {
  std::string list;           // the bracket list
  std::string out;            // the radiance map written (.exr)
  std::string response_in;    // a stored response (CSV) to use instead of recovering one
  std::string response_out;   // where to write the response used (CSV); empty: not written
  bool linear = false;        // linear frames: no response recovery
  ResponseOptions response;   // recovery options
  MergeOptions merge;         // merge options
  ExrPixelType pixel_type = ExrPixelType::kFloat;
  ExrCompression compression{};
  std::map<std::string, std::string> attributes;  // extra header attributes
  int threads = 2;
};

struct BracketFileResult {
  int width = 0, height = 0;
  size_t frames = 0;
  std::string response_id;
  int saturated_pixels = 0, black_pixels = 0;
  double decode_s = 0, response_s = 0, merge_s = 0, write_s = 0;
};

// Decodes the frames, recovers (or reads, or assumes linear) the response, merges and writes.
// A bracket mixing RAW with camera-rendered frames, or RAW with a stored response, is refused
// (kInvalidInput naming the list).
Result<BracketFileResult> MergeBracketFile(const BracketFileRequest& request);

}  // namespace rig
