// RTI light files (.lp) and their images: the capture every photograph-fitting family reads.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/light_direction.h"

namespace rig {

struct LpEntry {
  std::string image;  // resolved: relative paths are relative to the .lp file's folder
  Vec3 direction{};   // unit light direction as written (x right, z towards the camera)
  int line = 0;       // line in the .lp file
};

// Lights at the horizon. A light calibrated a fraction of a degree below the horizon is
// calibration noise, not a light from below; and relight's HSH fit writes NaN for a light
// exactly at z = 0. So a direction whose elevation lies in [-kHorizonToleranceDeg,
// kLowestElevationDeg) is lifted to kLowestElevationDeg (its azimuth kept), both on reading an
// .lp and on writing one; lower lights are left as they are (the hemispherical families refuse
// them, sh and ptm fit them).
inline constexpr double kHorizonToleranceDeg = 1.0;
inline constexpr double kLowestElevationDeg = 0.25;
// Lifts `d` (a unit vector) as above; returns its elevation before, in degrees, when it moved it.
std::optional<double> LiftToLowestElevation(Vec3* d);

// A count on the first line, then `<image> <x> <y> <z>` per line. Errors name file:line. A light
// within the horizon's tolerance is lifted (LiftToLowestElevation) with a warning naming the line.
Result<std::vector<LpEntry>> ReadLp(const std::string& path);

struct RtiImages {
  std::vector<cv::Mat> encoded;   // CV_8UC3 BGR as stored (after downsampling)
  std::vector<cv::Mat> radiance;  // CV_32FC3 BGR linear: sRGB-decoded (or /255 with linear)
};
// Loads every image (8-bit; sRGB unless `linear`), all the same size; `downsample` >= 1
// shrinks each by that factor (area averaging) first.
Result<RtiImages> LoadRtiImages(const std::vector<LpEntry>& entries, bool linear,
                                int downsample);

}  // namespace rig
