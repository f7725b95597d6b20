// The PCA model of a session's radiance maps, its value curve and size chosen per byte:
// every candidate (curve, components, grid, JPEG quality) fitted without every n-th lamp,
// encoded as it ships, decoded back (in memory: the files' own bytes) and scored in linear
// reflectance at the lamps held out; the smallest candidate within the measurement's noise of
// the best (its excess error within a standard error measured across the held-out lamps) that
// fits the byte budget is fitted again on every lamp. Everything comes from the maps given, so run inside a fold it is a choice made
// inside the fold. When no candidate fits the budget (a small image: the grid is stored
// whatever the image's size) the smallest is taken and the reason says so.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/model/hdr_codes.h"
#include "process/model/pca/pca.h"

namespace rig {

struct PcaHdrCurveCandidate {
  HdrCurve curve = HdrCurve::kPower;
  double gamma = 1.25;
  std::string Name() const;  // "power1.25", "srgb", "log"
};

struct PcaHdrChoiceOptions {
  std::vector<PcaHdrCurveCandidate> curves = {{HdrCurve::kPower, 1.25}, {HdrCurve::kPower, 1.5}};
  std::vector<int> components = {18, 30};
  std::vector<int> resolutions = {32};
  std::vector<int> qualities = {95, 100};
  double max_bytes_per_pixel = 30;
  // A candidate is within the noise of the best when its excess of squared held-out error over
  // the best's is at most `noise_z` standard errors of that excess, the standard error measured
  // across the lamps held out (paired: both candidates at the same lamps). 0 = the best only.
  double noise_z = 1.0;
  int validation_every = 6;  // one lamp in n held out (HeldOutLamps)
  // Which lamps are held out: "interior" (spread over the lamps inside the set's outline, so the
  // fold measures what relighting between the lamps costs, as the off-grid truth does) or
  // "every" (every n-th from the first, edges included: extrapolation weighs in).
  std::string held_out = "interior";
  double high = 0.9999;      // the curve's max at this quantile of ρ
  int threads = 2;           // the curves' candidates are scored this many at once
  bool warn_over_budget = true;  // log a warning when no candidate fits the budget
};

struct PcaHdrCandidate {
  std::string curve;
  int components = 0, resolution = 0, quality = 0;
  double bytes_per_pixel = 0;  // the fold's model as written
  double held_out_relative = 0;  // RMS(model ρ − measured ρ) / RMS(measured ρ) at held-out lamps
  // Per held-out lamp: Σ(model ρ − measured ρ)² over the pixels, ÷ Σ(measured ρ)² over every
  // held-out lamp (so they sum to held_out_relative²).
  std::vector<double> per_lamp;
  // Against the best: the excess of held_out_relative² and its standard error across the lamps.
  double excess = 0, excess_se = 0;
  bool within_budget = false;
};

struct PcaHdrFit {
  PcaModel model;                  // empty after ChoosePcaHdr
  PcaHdrCurveCandidate curve;      // the chosen candidate's curve ...
  PcaOptions options;              // ... and its model's options (components, grid, quality)
  std::vector<PcaHdrCandidate> candidates;
  int chosen = -1, best = -1;
  std::string reason;  // one sentence
  double time_s = 0;
};

// `radiance`: CV_32FC3 BGR maps, one per lamp direction; ρ = radiance ÷ lamp (R, G, B).
Result<PcaHdrFit> FitPcaHdrAuto(const std::vector<cv::Mat>& radiance,
                                const std::vector<Vec3>& directions,
                                const std::array<double, 3>& lamp_radiance_rgb,
                                const LightFrameConfig& light_frame,
                                const PcaHdrChoiceOptions& options);

// The choice alone (fit.model left empty): the candidates, the chosen one's curve and options.
// FitPcaHdrAuto is this followed by FitPca on every map with the chosen curve's codes.
Result<PcaHdrFit> ChoosePcaHdr(const std::vector<cv::Mat>& radiance,
                               const std::vector<Vec3>& directions,
                               const std::array<double, 3>& lamp_radiance_rgb,
                               const PcaHdrChoiceOptions& options);
// The options FitPcaHdrAuto's final fit takes for a candidate of `options`.
PcaOptions PcaHdrModelOptions(const PcaHdrChoiceOptions& options, int components, int resolution,
                              int quality);
// The curve options of a candidate curve.
HdrCurveOptions PcaHdrCurveOptions(const PcaHdrCurveCandidate& curve, double high);

// The lamps a choice holds out: every n-th from the first (n = max(2, every)).
std::vector<int> HeldOutLamps(size_t lamps, int every);
// The lamps inside the outline of the set: those surrounded by neighbours (the lamps within
// twice the distance to its nearest), no gap between their bearings on the sphere wider than
// 135°. An edge row leaves a gap of about 180° however the outline bends (a grid's row of
// constant v bows inwards by most of a step over 90° of h), a corner more.
std::vector<int> InteriorLamps(const std::vector<Vec3>& directions);
// The held-out lamps of `options.held_out`: for "interior", ceil(n ÷ every) lamps spread evenly
// over the interior ones (all of them when fewer; every n-th when fewer than 3 are interior).
std::vector<int> ChoiceHeldOutLamps(const std::vector<Vec3>& directions,
                                    const PcaHdrChoiceOptions& options);
// What ChoiceHeldOutLamps took, in words: "spread inside the lamps' outline" | "every 6th".
std::string HeldOutRuleName(const std::vector<Vec3>& directions, const PcaHdrChoiceOptions& options);
// A model's squared error of ρ against the measured ρ (radiance ÷ lamp) at each held-out lamp,
// as a share of the measured ρ's squares over all of them: the shares sum to the relative RMS
// error squared. The maps' non-finite samples are left out of both.
std::vector<double> HeldOutErrors(const ReflectanceModel& m, const std::vector<cv::Mat>& radiance,
                                  const std::vector<Vec3>& directions, const std::vector<int>& held,
                                  const std::array<double, 3>& lamp);
// The excess of a's squared relative error over b's (the sum of the paired per-lamp shares)
// and its standard error, the lamps held out taken as a sample of the lamps.
void PairedExcess(const std::vector<double>& a, const std::vector<double>& b, double* excess,
                  double* se);

// Markdown table of the candidates, the choice marked.
std::string PcaHdrChoiceMarkdown(const PcaHdrFit& fit);

}  // namespace rig
