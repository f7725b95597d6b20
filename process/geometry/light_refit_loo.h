// Does re-estimating a capture's light directions from its own images help the model? The
// leave-one-out PSNR of the default model (PCA, size chosen inside each fold) with the
// directions as given against the same model with directions re-estimated by alternating
// robust photometric stereo and per-light least squares — the re-estimation redone inside every
// fold from the fold's images alone; the held-out image's light is then estimated from that
// image against the fold's normals and albedo (as a sphere in it would be), never its pixels
// fitted.
#pragma once

#include <string>
#include <vector>

#include "config/result.h"
#include "process/geometry/light_stack.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/any/rti_fit.h"

namespace rig {

struct LightLooRow {
  std::string lights;      // "as given" | "re-estimated from the images"
  double psnr_mean_mse_db = 0, psnr_median_db = 0;
  int folds = 0;
  double mean_change_deg = 0;  // of the re-estimated directions from the given ones (all images)
  double bytes_per_pixel = 0;
};

Result<std::vector<LightLooRow>> CompareLightsLoo(const RtiCapture& capture,
                                                  const LightStack& stack, int every, int rounds,
                                                  const PcaChoiceOptions& choice = {},
                                                  int threads = 2);

}  // namespace rig
