// Deep-zoom pyramids of a web-format folder's planes, in the layout relight's viewer and
// OpenLIME read as "deepzoom" (relight-deepzoom's output): plane_N.dzi (Microsoft's DZI XML:
// TileSize, Overlap, Format, Size) and plane_N_files/L/x_y.jpg. Level L is
// ceil(W / 2^(max − L)) × ceil(H / 2^(max − L)), max = ceil(log2(max(W, H))), the full size at
// max, 1×1 at 0; each level is the one above halved (2×2 box average of the bytes; the
// relighting is linear in the coefficients, so an averaged coefficient is the coefficient of
// the averaged picture before clamping). Tile (x, y) covers [x·T − o, (x+1)·T + o) ∩ the level,
// o = overlap on inner edges only.
#pragma once

#include <string>

#include "config/result.h"

namespace rig {

struct DeepZoomOptions {
  int tile_size = 256;
  int overlap = 1;
  int quality = 95;
  int threads = 2;
};

struct DeepZoomReport {
  int files = 0;        // plane files tiled
  int levels = 0;       // per file
  long tiles = 0;       // written, all files
  double seconds = 0;
};

// Whether a model of this size gets tiles by default: the longer side above 4096 pixels.
bool WantsDeepZoom(int width, int height);

// Tiles every plane_N.jpg of `folder` (N = 0.. while the file exists). The .dzi and the
// _files folder must not exist yet (nothing is overwritten). Tiles are JPEG at `quality`,
// colour space and subsampling as the plane file (YCbCr 4:4:4 or RGB).
Result<DeepZoomReport> WriteDeepZoom(const std::string& folder, const DeepZoomOptions& options);

}  // namespace rig
