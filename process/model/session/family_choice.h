// The session's model family chosen per byte at held-out lamps, inside one fold: the PCA family
// (its own per-byte choice of curve and size, ChoosePcaHdr) against the harmonic family (its
// own order and λ, chosen by FitModel from the fold's lamps), both fitted to the same maps
// without the same lamps and scored there in linear reflectance. The smaller model is taken
// unless the larger one's lower error is beyond the measurement's noise: one standard error of
// the paired excess, measured across the lamps held out (as ChoosePcaHdr judges its sizes).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/harmonic/fit.h"
#include "process/model/pca/pca_hdr.h"

namespace rig {

struct FamilyCandidate {
  std::string family;  // "pca" | "harmonic"
  std::string what;    // "power1.25, 30 components, 32x32, q100" | "sh order 6, 49 terms"
  int size = 0;        // components, or the harmonic order
  double bytes_per_pixel = 0;
  double held_out_relative = 0;  // relative RMS of ρ at the lamps held out
  std::vector<double> per_lamp;  // HeldOutErrors
  double excess = 0, excess_se = 0;  // against the better of the two
  double fit_s = 0;
};

struct SessionFamilyChoice {
  std::string family;       // the chosen: "pca" | "harmonic"
  PcaHdrFit pca;            // the PCA family's own choice (model left empty)
  FamilyCandidate pca_candidate, harmonic_candidate;
  int held_out = 0;         // lamps held out
  std::string held_out_rule;  // "inside the lamps' outline" | "every 6th"
  std::string reason;       // one sentence
  double time_s = 0;
};

// `radiance`: CV_32FC3 BGR maps (the choice region), one per direction; ρ = radiance ÷ lamp.
// `harmonic_value_bytes`: bytes of one stored coefficient (2: half, 4: float); the harmonic
// model's bytes per pixel are its coefficient planes (terms × 3 channels), uncompressed, as the
// session's model file stores them by default.
Result<SessionFamilyChoice> ChooseSessionFamily(const std::vector<cv::Mat>& radiance,
                                                const std::vector<Vec3>& directions,
                                                const std::array<double, 3>& lamp_radiance_rgb,
                                                const FitOptions& harmonic,
                                                int harmonic_value_bytes,
                                                const PcaHdrChoiceOptions& pca);

// The two families side by side in Markdown, the choice marked, then the PCA candidates.
std::string SessionFamilyMarkdown(const SessionFamilyChoice& choice);

}  // namespace rig
