// The model of a multi-light capture chosen across families, per byte as written: the PCA
// family's own candidates (ChoosePca: components, grid, JPEG quality) beside relight's fixed
// bases stored the way relight stores them — HSH of 4 and 9 terms and PTM of 6, RGB, in
// 8-bit JPEG planes of its web format, the field's ~4 B/px HSH — every candidate scored on the
// same split (the same held-out lights, the same pixels), its planes' JPEG error and bytes
// measured on the same central crop. The smallest model within the tolerance of the best one
// that fits the budget is taken, whichever family it is. Everything comes from the samples
// given, so run inside a leave-one-out fold it is a choice made inside the fold.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "config/result.h"
#include "process/export/convert.h"
#include "process/model/any/rti_fit.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/reflectance_model.h"

namespace rig {

struct BasisCandidate {
  RelightTarget target;       // type and terms (rgb)
  int quality = 0;            // of the plane JPEGs
  double validation_mse = 0;  // at the held-out lights, 8-bit units², before quantisation
  double jpeg_mse = 0;        // what the 8-bit planes and JPEG add (the crop's planes)
  double psnr_db = 0;         // of the two together
  double bytes_per_pixel = 0; // the crop's plane files scaled to the image, and info.json
  bool within_budget = false;
};

struct LpChoice {
  PcaChoice pca;                     // PCA's candidates; its `chosen` is -1 when a basis is taken
  std::vector<BasisCandidate> bases;
  std::string family;                // "pca-bilinear" | "hsh" | "ptm"
  int basis_chosen = -1;             // into bases, when a basis is taken
  double best_psnr_db = 0;           // the best candidate within budget, either family
  std::string best;                  // what it is, in words
  std::string reason;                // one sentence: what was chosen and why
};

// The bases scored: HSH 4, PTM 6, HSH 9 at every quality of `options.qualities` (those with
// more terms than the fold's lights leave out are skipped).
std::vector<RelightTarget> LpChoiceBases();

// `components` the samples' own (as for ChoosePca). `with_bases` false: the PCA family only.
Result<LpChoice> ChooseLpModel(const PcaChoiceInput& input, const PcaComponents& components,
                               const PcaChoiceOptions& options, bool with_bases = true);

// The whole automatic fit of a capture's samples (`samples.usable` filled, as LoadRtiCapture
// fills it): components (given, e.g. a fold's, or computed), the choice, the chosen model.
struct LpAutoFit {
  LpChoice choice;
  std::unique_ptr<ReflectanceModel> model;  // pca-bilinear (a PCA folder) or hsh/ptm (web folder)
  PcaFitStats stats;                        // the PCA model's; zero for a basis
  size_t refitted_pixels = 0;               // a basis's pixels solved around masked samples
  double time_s = 0;
};
// `near_lamp` non-empty: the samples were divided by a near lamp's fall-off; the PCA family
// only, whose folder records it (info.json rig.near_lamp).
Result<LpAutoFit> FitLpAuto(const LightSamples& samples, const PcaComponents* components,
                            const PcaChoiceOptions& options, bool with_bases = true,
                            const std::string& near_lamp = "");

// What was chosen, in the words the reason starts with: "pca 12 components, 32x32 grid, q75",
// "hsh 9 terms rgb, 8-bit planes, q85".
std::string LpChosenWords(const LpChoice& choice);

// The choice, its reason, PCA's table, then the bases' table, each with the choice marked.
std::string LpChoiceMarkdown(const LpChoice& choice);

// `rig fit --lp`'s default (family "auto", no size given): FitLpAuto behind RtiFitResult, with
// the report FitRti writes. Any other request is FitRti's.
Result<RtiFitResult> FitRtiAcrossFamilies(const RtiCapture& capture, const RtiFitRequest& request);

}  // namespace rig
