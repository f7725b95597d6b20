// relight's own bases (PTM 6 terms RGB or LRGB, HSH 4 or 9 terms) fitted straight to a
// capture's photographs, as RTIBuilder and relight-cli fit them: per pixel, by least squares
// in the photographs' code values (0..255), the samples the LDR mask marks (clipped, black)
// left out. What `rig fit --lp … --out m.ptm | m.rti` writes: one step from the photographs
// to RTIViewer's files, with the error of the model as written at images it was not fitted to.
#pragma once

#include <string>
#include <vector>

#include "config/result.h"
#include "process/export/convert.h"
#include "process/model/light_samples.h"

namespace rig {

struct RelightFitOptions {
  // Held out for the error: images 0, every, 2·every, … (relight's figures in
  // docs/model.md are for every 6th), the model refitted without them; 0: no held-out error.
  int every = 6;
  // "ptm" or "rti": the file the held-out model is written to and read back from (its
  // quantisation counted), in a scratch folder of the system's temporary directory.
  std::string format = "ptm";
  int threads = 2;
  // The fitted model rendered at every image for fitted_psnr_db (a render per image); off when
  // only the coefficients are wanted (the choice across families fits many).
  bool fitted_psnr = true;
};

struct RelightFit {
  RelightCoefficients coefficients;  // fitted to every image
  int held_out = 0;                  // images held out
  double held_out_psnr_db = 0;       // 8-bit PSNR at them of the model fitted without them, as written
  double fitted_psnr_db = 0;         // the model fitted to every image, at every image (unquantised)
  size_t refitted_pixels = 0;        // pixels whose fit left masked samples out
  double fit_s = 0, held_out_s = 0;
};

// Errors: a target relight has no basis for; fewer usable images than terms; lights at or
// below the horizon for HSH (its basis is a hemisphere's).
Result<RelightFit> FitRelightToSamples(const LightSamples& samples, const RelightTarget& target,
                                       const RelightFitOptions& options = {});

}  // namespace rig
