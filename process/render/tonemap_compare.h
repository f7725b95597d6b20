// `rig tonemap`'s pictures: one method's, or every method's side by side, each labelled with
// its name, resized to a common width, with what each method did and how long it took.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/render/tonemap.h"

namespace rig {

struct ToneMapPanel {
  ToneMapOptions options;  // as applied (options.method: the panel's method)
  ToneMapReport report;
  double ms = 0;           // ToneMap's time
};

// The methods `rig tonemap --compare` shows, in order.
std::vector<ToneMapMethod> ComparedToneMapMethods();

// `radiance` tone-mapped by each of `methods` (with `options` otherwise), every picture resized
// to `width` (0: as is), labelled with its method's name when `label`, concatenated left to
// right. `panels` (may be null) receives one entry per method.
Result<cv::Mat> ToneMapSideBySide(const cv::Mat& radiance, const ToneMapOptions& options,
                                  const std::vector<ToneMapMethod>& methods, int width, bool label,
                                  std::vector<ToneMapPanel>* panels);

// One line on what a panel's method did ("fov 40.0 deg, foveal 10x8, ..., black 0.10%, white 0.20%").
std::string DescribeToneMapPanel(const ToneMapPanel& panel);

}  // namespace rig
