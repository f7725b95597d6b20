// Speed against accuracy of every reflectance-model choice on the same data: each basis, fit
// method and order (SH by the paper's quadrature, by least squares and regularised; HSH;
// PTM; the PCA family with its interpolated light basis, each value curve, size and JPEG
// quality) measured for fit time, render time per megapixel, bytes per pixel as stored,
// leave-one-out error (harmonic) and — when the truth is known (simulated sessions) — error at
// held-out lamp positions inside the sampled region and beyond it. Marks the Pareto fronts,
// the harmonic order the automatic selection picks and the session's default model (the
// family chosen per byte, as `rig process` makes it).
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/harmonic/fit.h"
#include "process/model/harmonic/model.h"
#include "process/model/pca/pca_hdr.h"

namespace rig {

struct MethodEvalInput {
  std::vector<cv::Mat> radiance;          // CV_32FC3 BGR, one per pose
  std::vector<double> h_deg, v_deg;       // the poses' rig angles
  std::array<double, 3> lamp_radiance_rgb = {1, 1, 1};
  LightFrameConfig light_frame;
  // The exact apparent BRDF (CV_32FC3 BGR) at rig angles, when known (simulator truth).
  std::function<cv::Mat(double h_deg, double v_deg)> truth_rho;
  std::vector<std::pair<double, double>> held_out;  // lamp angles inside the sampled region
  std::vector<std::pair<double, double>> outside;   // lamp angles beyond it (extrapolation)
  int max_order = 6;                      // SH/HSH orders 0..max_order; PTM 1..4
  int bytes_per_coefficient = 2;          // half (2) or float (4) storage
  FitOptions selection;                   // the automatic choice (the session's settings)
  // Each fit and each render timed this many times, the median kept (the same machine draws
  // the same chart whatever else it is doing); the first fit's model is the one measured.
  int timing_runs = 3;
  // The PCA family's rows (8 or more maps): every curve of pca.curves, size of
  // pca_components, grid of pca.resolutions and JPEG quality of pca.qualities, fitted to every
  // map and measured as read back from the bytes it ships as.
  bool pca_family = true;
  PcaHdrChoiceOptions pca;
  std::vector<int> pca_components = {3, 6, 12, 18, 30};
  // The session's own default model: "auto" chooses the family per byte at held-out lamps
  // (ChooseSessionFamily, as `rig process` does); "harmonic" or "pca" as configured.
  std::string model_family = "auto";
};

struct MethodResult {
  std::string basis, method;
  int order = 0, terms = 0;
  bool supported = false;
  std::string refusal;                    // why not, when !supported
  double fit_time_s = 0;                  // median of timing_runs fits (wall)
  double render_s_per_mp = 0;             // one lamp, ρ for every pixel (median of runs)
  double bytes_per_pixel = 0;
  double condition = 0;                   // of the design matrix
  double loo_relative = 0;                // LOO RMS / RMS of ρ (0 when undefined)
  // Relative RMS error of ρ against the truth (NaN without truth): at held-out lamps inside
  // the sampled region, the same on pixels shadowed at some sampled pose and on pixels lit at
  // all of them, and at lamps outside the region.
  double truth_relative = 0, truth_relative_shadowed = 0, truth_relative_lit = 0;
  double extrapolation_relative = 0;
  bool selected = false, pareto_time = false, pareto_storage = false;
  bool session_default = false;           // the model `rig process` makes of this session

  std::string Name() const;               // "sh-rls", "ptm-ls", "pca-power1.25-q95"
  double Error() const;                   // truth_relative when known, else loo_relative
};

// One held-out rule of the family choice: both families' fold errors and the truth of what
// each would make (NaN when not among the rows).
struct FamilyFold {
  std::string rule;        // "spread inside the lamps' outline" | "every 6th"
  int held_out = 0;
  std::string chosen;      // "pca" | "harmonic"
  double pca_held_out = 0, harmonic_held_out = 0;
  int pca_components = 0, harmonic_order = 0;
  double pca_bytes_per_pixel = 0, harmonic_bytes_per_pixel = 0;
  double pca_truth = 0, harmonic_truth = 0;
  bool session = false;    // the rule `rig process` uses
};

struct MethodEvaluation {
  std::vector<MethodResult> rows;
  bool has_truth = false;
  std::string selected;                   // "sh-rls order 4"
  std::string session_default;            // "pca-power1.25-q100, 18 components" (or why none)
  std::string session_default_reason;     // the family choice's sentence
  std::vector<FamilyFold> family_folds;   // the session's held-out rule, then the other
  double truth_scale = 1;                 // data ρ = scale · true ρ (HDR units are relative)
  size_t shadowed_pixels = 0, lit_pixels = 0;
  int timing_runs = 1;                    // each time the median of this many runs
};

Result<MethodEvaluation> EvaluateMethods(const MethodEvalInput& input);

// The median of timings (the mean of the middle two for an even count; NaN for none).
double MedianSeconds(std::vector<double> seconds);

// Marks the rows on the error-against-fit-time and error-against-storage Pareto fronts.
void MarkParetoFronts(std::vector<MethodResult>* rows);

std::string MethodsCsv(const MethodEvaluation& e);
std::string MethodsMarkdown(const MethodEvaluation& e);

// Charts (CV_8UC3): error against fit time, error against bytes per pixel — one line per
// method, the Pareto front ringed, the selected model highlighted — and condition number and
// error against order.
cv::Mat ChartErrorVsTime(const MethodEvaluation& e);
cv::Mat ChartErrorVsStorage(const MethodEvaluation& e);
cv::Mat ChartConditionVsOrder(const MethodEvaluation& e);
cv::Mat ChartExtrapolation(const MethodEvaluation& e);

}  // namespace rig
