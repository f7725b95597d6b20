// RTI light files (.lp) and their images, and the leave-one-out evaluation of bases, orders,
// methods and fit spaces on them, measured in 8-bit sRGB like the RTI tools measure it.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/fit.h"
#include "process/model/light_direction.h"

namespace rig {

struct LpEntry {
  std::string image;  // resolved: relative paths are relative to the .lp file's folder
  Vec3 direction{};   // unit light direction as written (x right, z towards the camera)
  int line = 0;       // line in the .lp file
};

// A count on the first line, then `<image> <x> <y> <z>` per line. Errors name file:line.
Result<std::vector<LpEntry>> ReadLp(const std::string& path);

struct RtiImages {
  std::vector<cv::Mat> encoded;   // CV_8UC3 BGR as stored (after downsampling)
  std::vector<cv::Mat> radiance;  // CV_32FC3 BGR linear: sRGB-decoded (or /255 with linear)
};
// Loads every image (8-bit; sRGB unless `linear`), all the same size; `downsample` >= 1
// shrinks each by that factor (area averaging) first.
Result<RtiImages> LoadRtiImages(const std::vector<LpEntry>& entries, bool linear,
                                int downsample);

struct LooRow {
  std::string basis;
  int order = 0, terms = 0;
  std::string method, space;
  bool supported = false;
  std::string refusal;
  double lambda_relative = 0;
  double condition = 0;
  double psnr_mean_mse_db = 0;    // PSNR of the per-image MSE averaged over all images
  double psnr_median_db = 0;      // median of the per-image PSNRs
  double fit_space_rmse = 0;      // LOO RMSE in the fit space
  double time_s = 0;              // building P, choosing λ, the LOO product and scoring
};

struct LooSpec {
  BasisKind basis;
  int order;
  FitMethod method;
  FitSpace space;
};

// Leave-one-out over images: every image predicted from a fit to all the others (exactly, via
// the shared hat matrix), encoded to 8-bit sRGB (clipped, rounded) and compared with the
// stored 8-bit image. `linear` says how radiance relates to the stored values.
std::vector<LooRow> RtiLeaveOneOut(const RtiImages& images, const std::vector<Vec3>& directions,
                                   const std::vector<LooSpec>& specs, bool linear,
                                   double max_condition);

std::string LooTableMarkdown(const std::vector<LooRow>& rows);

}  // namespace rig
