// The leave-one-out evaluation of harmonic bases, orders, methods and fit spaces on an .lp
// capture, measured in 8-bit sRGB like the RTI tools measure it.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/harmonic/fit.h"
#include "process/model/light_direction.h"
#include "process/model/lp.h"

namespace rig {

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
