// Fitting a model to radiance maps too large for memory: row bands are read from every map
// (OpenEXR scanline ranges), fitted with the shared matrix and written band by band, so the
// peak memory is a few bands, not the session (24 MP x 40 poses x RGB float is 11.5 GB).
#pragma once

#include <array>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/result.h"
#include "process/io/exr_io.h"
#include "process/model/fit.h"

namespace rig {

struct StreamFitInput {
  std::vector<std::string> paths;  // radiance EXRs (R, G, B; optional "flags", 0 = valid)
  std::vector<Vec3> directions;
  std::vector<double> weights;     // quadrature weights; empty: 2π/N each
  std::array<double, 3> lamp_radiance_rgb = {1, 1, 1};
  LightFrameConfig light_frame;
  int band_rows = 32;              // rows per band
  int selection_rows = 256;        // rows (in evenly spaced bands) that choose order and λ
};

struct StreamFitOutput {
  Selection selection;
  MissingStats missing;
  double loo_rmse = 0;
  double time_s = 0;
  int width = 0, height = 0;  // of the maps and the model
};

// Bytes the in-memory fit would hold for the samples (width x height x 3 x 4 x maps), from
// the headers only.
Result<size_t> EstimateSampleBytes(const std::vector<std::string>& paths);

// Two passes: the Gram matrix of `selection_rows` rows chooses order/λ; then every band is
// fitted and written. The model is written atomically (temporary file, then rename); it has a
// "valid" channel whenever some input has a "flags" channel.
Result<StreamFitOutput> FitModelStreaming(const StreamFitInput& input, const FitOptions& options,
                                          const std::string& out_path, ExrPixelType type);

}  // namespace rig
