// Choosing the size of a PCA model from the data: components, grid resolution and JPEG
// quality, by held-out error per byte — the smallest model within a stated tolerance of the
// best one that fits the byte budget. Everything it uses comes from the samples it is given,
// so run inside a leave-one-out fold it is a choice made inside the fold.
#pragma once

#include <string>
#include <vector>

#include "config/result.h"
#include "process/model/light_samples.h"
#include "process/model/pca/pca.h"

namespace rig {

struct PcaChoiceOptions {
  std::vector<int> components = {3, 6, 9, 12, 15, 18};
  std::vector<int> resolutions = {12, 16, 24, 32};
  std::vector<int> qualities = {75, 85, 95};
  // Whole model on disk, bytes per pixel. The default is the size of the field's usual
  // compact model (relight's 9 PCA planes at JPEG q95: 3.35 B/px on the shared icon).
  double max_bytes_per_pixel = 3.4;
  double tolerance_db = 0.2;  // the smallest model within this of the best within budget
  int validation_every = 6;   // every n-th light is held out to score the candidates
  // Repeated splits: split r holds out every n-th light from r·n/splits on, so with splits ==
  // n every light is held out exactly once. One split's estimate moves with which 12 lights it
  // holds out (a left-out image shifts them all); the candidates' errors summed over the
  // splits move far less (docs/model.md).
  int validation_splits = 6;
  // Pixel-scorings over all splits: each split scores validation_pixels / splits (at least
  // 256) pixels, the same ones.
  size_t validation_pixels = size_t{1} << 13;
  PcaOptions base;            // mask, thresholds, seed, threads, quantile
};

struct PcaCandidate {
  int components = 0, resolution = 0, quality = 0;
  double validation_mse = 0;  // at the held-out lights, 8-bit units², before JPEG
  double jpeg_mse = 0;        // what JPEG adds, from the planes' own compression error
  double psnr_db = 0;         // of the two together
  double bytes_per_pixel = 0; // estimated from compressing a crop of the planes
  bool within_budget = false;
};

struct PcaChoice {
  PcaOptions options;                  // base + the chosen size
  std::vector<PcaCandidate> candidates;
  int chosen = -1;                     // index into candidates
  int best = -1;                       // the best within budget
  std::string reason;                  // one sentence: what was chosen and why
};

// `components` are the samples' own (ComputePcaComponents with at least the largest count).
Result<PcaChoice> ChoosePca(const LightSamples& samples, const PcaComponents& components,
                            const PcaChoiceOptions& options);

// All the choice reads of a capture, gathered without holding it (a streamed fit collects it
// in one pass): the same choice as from the whole samples.
struct PcaChoiceInput {
  size_t pixels = 0;     // of the whole capture
  LightSamples sampled;  // the pixels of the components' `subset`, in that order (one row)
  LightSamples crop;     // the pixels of PcaChoiceCrop, row-major, crop width × height
};
// The splits the candidates are scored on: the lights held out in each (every
// validation_every-th, at least every 2nd, from the split's offset on), and the pixels of `sampled` (indices into PcaChoiceInput::sampled) whose
// predictions there are scored. Other families compared with PCA use the same split.
std::vector<int> PcaChoiceHeldOutLights(int lights, const PcaChoiceOptions& options,
                                        int split = 0);
int PcaChoiceSplits(const PcaChoiceOptions& options);  // validation_splits, within 1..n
// How the split is said in a choice's reason: "every 6th light of the fit held out" or
// "every light of the fit held out once, in 6 splits".
std::string PcaChoiceSplitWords(const PcaChoiceOptions& options);
std::vector<size_t> PcaChoiceEvalPixels(size_t sampled, const PcaChoiceOptions& options);
// The samples of some pixels (indices into `samples`) as a one-row image, values only.
LightSamples PcaChoicePickPixels(const LightSamples& samples, const std::vector<size_t>& pixels);
// The central crop (at most 256 × 256) whose planes measure what JPEG costs and adds.
cv::Rect PcaChoiceCrop(int width, int height);
PcaChoiceInput PcaChoiceInputOf(const LightSamples& samples, const std::vector<size_t>& subset);
Result<PcaChoice> ChoosePca(const PcaChoiceInput& input, const PcaComponents& components,
                            const PcaChoiceOptions& options);

// The whole automatic fit: components (given — exactly the samples' own, e.g. a fold's from
// PcaComponentsWithout — or computed), the choice, the model of the chosen size.
struct PcaAutoFit {
  PcaChoice choice;
  PcaModel model;
  PcaFitStats stats;
};
Result<PcaAutoFit> FitPcaAuto(const LightSamples& samples, const PcaComponents* components,
                              const PcaChoiceOptions& options);
int LargestCandidate(const PcaChoiceOptions& options);
// The model of a chosen size (`options` as a PcaChoice's): the basis from the components, every
// pixel's coefficients — FitPcaAuto's last step.
Result<PcaModel> FitPcaChosen(const LightSamples& samples, const PcaComponents& components,
                              const PcaOptions& options, PcaFitStats* stats = nullptr);

// The candidates for a byte budget, one rule for `rig fit --max-bytes-per-pixel B`, the
// leave-one-out report's rows and the benchmarks: the default candidates, and from twice the
// default budget (6.8 B/px) on also 24 and 30 components, which only a budget that large can
// hold (a component plane costs ~0.2-0.4 B/px at q75-q95 on real captures).
inline constexpr double kPcaLargeCandidatesFromBytesPerPixel = 6.8;
PcaChoiceOptions PcaChoiceForBudget(double max_bytes_per_pixel);

// Markdown table of the candidates with the choice marked.
std::string PcaChoiceMarkdown(const PcaChoice& choice);

}  // namespace rig
