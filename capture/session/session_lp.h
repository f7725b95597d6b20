// A session's radiance maps as an RTI capture for other tools: hdr/<pose>.exr ->
// OUT/<pose>.png (8-bit sRGB, one exposure for all: the 99.5th percentile of every map's values
// becomes white) and OUT/dirs.lp with each pose's direction in the object frame (the session's
// light frame).
#pragma once

#include <filesystem>
#include <string>

#include "config/result.h"

namespace rig {

struct SessionLpExport {
  std::string lp;      // OUT/dirs.lp
  size_t images = 0;
  int width = 0, height = 0;
  float white = 1;     // the radiance written as 255
};

// `out` is created (the caller refuses an existing one).
Result<SessionLpExport> ExportSessionLp(const std::filesystem::path& session, const std::string& out);

}  // namespace rig
