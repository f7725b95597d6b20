// How sharp a frame is, for framing and focusing with `rig shot --preview`: the variance of
// the Laplacian of its luminance (Pech-Pacheco et al. 2000), over the whole frame and over a
// 3×3 grid of tiles, so that a user turning the focus ring sees the number rise and where the
// frame is sharpest. The figure is relative — it grows with contrast and with noise — so it is
// compared between previews of one scene, not across scenes.
#pragma once

#include <array>

#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

struct FocusStats {
  double whole = 0;               // variance of the Laplacian, 8-bit luminance units²
  std::array<double, 9> tiles{};  // the same per tile, row by row from the top left
  int sharpest_tile = 0;          // index into tiles
};

// `image`: 8-bit BGR or grey (16-bit is scaled to 8). kInvalidInput when empty or smaller
// than 9×9 pixels.
Result<FocusStats> AnalyzeFocus(const cv::Mat& image);

}  // namespace rig
