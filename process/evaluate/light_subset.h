// How well a subset of a capture's lights serves: the default .lp model (`rig fit --lp`'s PCA,
// its size chosen inside the subset) fitted on the subset only, written as it ships, read back,
// rendered at held-out lights and scored in 8 bits against their photographs.
#pragma once

#include <string>
#include <vector>

#include "config/result.h"
#include "process/model/any/rti_fit.h"

namespace rig {

struct LightSubsetScore {
  double psnr_mean_mse_db = 0;  // 10·log10(255² / the mean MSE over the held-out images)
  double psnr_median_db = 0;    // median of their PSNRs
  double bytes_per_pixel = 0;
  std::string model;            // the size chosen
};

// `fitted` and `held_out` index capture.samples' lights and must not share one (a held-out
// light is seen by no choice and no fit). `scratch` is a folder replaced by the model.
Result<LightSubsetScore> ScoreLightSubset(const RtiCapture& capture, const std::vector<int>& fitted,
                                          const std::vector<int>& held_out,
                                          const std::string& scratch);

// The lights of `lights` in none of `sets`, increasing.
std::vector<int> LightsInNone(int lights, const std::vector<std::vector<int>>& sets);

}  // namespace rig
