// Fitting a model to a multi-light capture (an .lp file and its 8-bit images): the capture
// read and checked (every image named by its .lp line, truncated JPEGs refused, clipped and
// black samples masked), then the family asked for — by default the PCA model of the size
// chosen from the data — fitted and described. What `rig fit --lp` does, callable without it.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "config/result.h"
#include "process/model/harmonic/fit.h"
#include "process/model/light_samples.h"
#include "process/model/pca/pca.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/reflectance_model.h"
#include "process/model/harmonic/loo.h"

namespace rig {

struct RtiCapture {
  std::string lp;
  std::vector<LpEntry> entries;
  LightSamples samples;           // usable mask filled (MaskLdrSamples)
  size_t masked_samples = 0;      // sample-channels at or beyond the thresholds
  double masked_fraction = 0;     // of all sample-channels
  double pixels_with_masked = 0;  // fraction of pixels with at least one masked sample
  double load_time_s = 0;
};

// Reads the .lp and every image it names (JPEG through libjpeg with the end-of-image check;
// other formats through OpenCV), all one size, 8 bits. `downsample` >= 1 shrinks each image by
// that factor (area averaging). Errors name the .lp line of the image concerned.
Result<RtiCapture> LoadRtiCapture(const std::string& lp, int downsample = 1,
                                  const LdrMaskThresholds& thresholds = {});

// Families: "auto" (the PCA model, its size chosen by held-out error per byte within
// `choice.max_bytes_per_pixel`), "pca" (sizes given in `pca`, 0 = chosen), "sh", "hsh", "ptm"
// (coefficients of a fixed basis, `harmonic` options, masked samples left out).
struct RtiFitRequest {
  std::string family = "auto";
  PcaChoiceOptions choice;
  int components = 0, grid_resolution = 0, jpeg_quality = 0;  // "pca": 0 = chosen
  FitOptions harmonic;
  // sh/hsh/ptm: the images' codes are linear in radiance (÷255), not sRGB. The PCA family
  // models the codes as they are stored, so it does not need to know.
  bool linear = false;
  // Non-empty: the capture's samples were divided by a near lamp's fall-off
  // (DivideSamplesByFalloff); recorded in the model (PCA: info.json rig.near_lamp; sh/hsh/ptm:
  // the header's near_lamp).
  std::string near_lamp;
};

struct RtiFitResult {
  std::unique_ptr<ReflectanceModel> model;
  std::string family;
  std::string summary;  // one line: what was fitted and why
  std::string report;   // Markdown: the capture, the masks, the candidates and the choice
  double fit_time_s = 0;
};

Result<RtiFitResult> FitRti(const RtiCapture& capture, const RtiFitRequest& request);
// The report's first lines: the capture, its size, what the mask left out.
std::string RtiReportHeader(const RtiCapture& capture, const RtiFitRequest& request);

// Lights at or below the horizon (z <= 0) by .lp line: the hemispherical families (pca, hsh)
// refuse them.
std::vector<int> LightsBelowHorizon(const RtiCapture& capture);

}  // namespace rig
