// A session's radiance maps as an RTI capture for other tools: hdr/<pose>.exr ->
// OUT/<pose>.jpg (8-bit sRGB JPEG, quality 95 — relight reads *.jpg only; or .png; one exposure
// for all: the 99.5th percentile of every map's values becomes white) and OUT/dirs.lp with each
// pose's direction in the object frame (the session's light frame). A pose at the horizon (the
// grid's 0° elevation row in the default frame, where relight's HSH fit writes NaN) is written
// at kLowestElevationDeg (process/model/lp.h) and named in `lifted`.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "config/result.h"

namespace rig {

struct SessionLpExport {
  std::string lp;      // OUT/dirs.lp
  size_t images = 0;
  int width = 0, height = 0;
  float white = 1;     // the radiance written as 255
  std::vector<std::string> lifted;  // poses lifted off the horizon, "h090_v00 (0.000 deg)"
};

enum class LpImageFormat { kJpeg, kPng };

// `out` is created (the caller refuses an existing one).
Result<SessionLpExport> ExportSessionLp(const std::filesystem::path& session, const std::string& out,
                                        LpImageFormat format = LpImageFormat::kJpeg);

}  // namespace rig
