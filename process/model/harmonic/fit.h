// Fitting per-pixel reflectance ρ(direction) onto a basis: the paper's quadrature of eq. 1,
// least squares and regularised least squares, order (and regularisation) chosen from
// leave-one-out error, pixels with missing samples solved from the samples they have.
//
// Every pixel shares the lamp directions, so a fit is one small matrix P (terms x poses)
// computed once and applied to all pixels as one matrix product. Leave-one-out is nearly
// free: the hat matrix H = B·P is shared too, and the all-pixel LOO error needs only the
// poses x poses Gram matrix G = Y·Yᵀ of the data (error = trace(M G Mᵀ), M the LOO operator).
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/model/harmonic/basis.h"
#include "process/model/light_direction.h"
#include "process/model/samples.h"

namespace rig {

enum class FitMethod { kQuadrature, kLs, kRls };

const char* FitMethodName(FitMethod method);  // "quadrature", "ls", "rls"
Result<FitMethod> ParseFitMethod(const std::string& name);

struct FitOptions {
  BasisKind basis = BasisKind::kSh;
  int order = -1;  // -1: automatic (smallest order within order_tolerance of the best)
  int max_order = 6;
  FitMethod method = FitMethod::kRls;
  FitTransform transform;
  double order_tolerance = 0.02;  // relative, on the LOO RMS error
  double max_condition = 1e6;     // beyond this an unregularised fit is refused
  double lambda = -1;             // rls strength relative to trace(BᵀB)/K; < 0: from LOO
  // Pixel-channel values used to choose order and λ (the Gram matrix); 0: all.
  size_t selection_values = size_t{1} << 22;
  int threads = 1;  // Eigen threads for the matrix product
};

// Options from the [process] section of a configuration.
Result<FitOptions> FitOptionsFromConfig(const ProcessConfig& process);

// The one small matrix of a fit, and what it costs.
struct Projector {
  Basis basis{BasisKind::kSh, 0};
  FitMethod method = FitMethod::kRls;
  double lambda = 0;          // absolute rls strength (0 for ls and quadrature)
  double lambda_relative = 0; // relative to trace(BᵀB)/K
  Eigen::MatrixXd p;          // terms x poses: coefficients = p · samples
  Eigen::MatrixXd hat;        // poses x poses: B · p
  double condition = 0;       // σmax/σmin of the design matrix B (inf: rank deficient)
  double solved_condition = 0;  // of the system actually solved (rls: √cond(BᵀB+λD))
  int rank = 0;
};

// Builds P for one basis/method. `weights` are the quadrature weights (solid angle per
// sample; only used by kQuadrature). Refuses (kInvalidInput, with the reason) what would be
// garbage: ls with more terms than poses minus one, a rank-deficient design or a condition
// number beyond max_condition.
Result<Projector> BuildProjector(const Basis& basis, const std::vector<Vec3>& directions,
                                 const std::vector<double>& weights, FitMethod method,
                                 double lambda_relative, double max_condition);

// The LOO operator M (poses x poses): LOO residuals of a sample vector y are M·y.
//   ls/rls: M = diag(1/(1-H_ii))·(I-H);  quadrature: M = I - (H - diag(H)) (sample i left out
//   of the sum). Returns an empty matrix when some H_ii ≈ 1 (LOO undefined).
Eigen::MatrixXd LooOperator(const Projector& projector);
// Mean squared LOO residual over `count` values from the Gram matrix G = Σ y·yᵀ.
double LooMse(const Eigen::MatrixXd& loo_operator, const Eigen::MatrixXd& gram, double count);

// Quadrature weights: the solid angle of each sample's cell of the rig's (h, v) grid,
// cos(v)·Δh·Δv (the paper's sin θ dθ dφ with θ the angle from the rig's vertical axis);
// Δh, Δv: the grid steps (smallest non-zero spacing of the distinct angles). A single
// row/column uses a step of 10°.
std::vector<double> GridQuadratureWeights(const std::vector<double>& h_deg,
                                          const std::vector<double>& v_deg);
// For scattered directions over a hemisphere (RTI): 2π/N each.
std::vector<double> UniformHemisphereWeights(size_t count);

// What one order costs and gives.
struct OrderReport {
  int order = 0;
  int terms = 0;
  bool supported = false;
  std::string refusal;      // why not, when !supported
  double lambda_relative = 0;
  double loo_rmse = 0;      // fit space, per pixel-channel
  double condition = 0;
  double solved_condition = 0;
  double build_time_s = 0;  // building P and choosing λ
};

struct Selection {
  Projector projector;
  int order = 0;
  std::vector<OrderReport> orders;
  // RMS of the selection's samples (fit space, per pixel-channel): the scale a LOO error is
  // judged against (loo_rmse / data_rms: the share of the signal the model misses).
  double data_rms = 0;
};

// The selection's table in Markdown: per order its terms, whether it is supported (or why
// not), its LOO RMS error (in `unit`) and relative to the samples' RMS, the design's condition
// ("ill-conditioned" where it is infinite) and λ.
std::string SelectionTable(const Selection& selection, const std::string& unit);
// A LOO error as a percentage of the samples' RMS ("3.21%"); empty when the RMS is unknown.
std::string LooRelativeCell(double loo_rmse, double data_rms);
// A design's condition number as a table cell: "1.2e+03", or, where it is infinite (the design
// is rank deficient, so an order can be "supported" only through λ), "ill-conditioned (rank
// deficient; regularised by λ)" — never a bare "inf" beside "supported: yes".
std::string ConditionCell(double condition, double lambda_relative);

// Chooses order (and λ for rls) from LOO error computed from the Gram matrix. With
// options.order >= 0 that order is built (and refused if it cannot be fitted stably); the
// report still covers 0..max_order.
Result<Selection> SelectProjector(const std::vector<Vec3>& directions,
                                  const std::vector<double>& weights,
                                  const Eigen::MatrixXd& gram, double count,
                                  const FitOptions& options);

// Coefficients = P · samples (terms x pixels*3), then every pixel with missing samples is
// solved again from its valid samples only (one weighted solve per distinct missing-pattern),
// or flagged (coefficients 0, valid 0) when fewer than `terms` valid samples remain or the
// reduced system is not stable. `valid_out` (pixels) receives 1/0.
struct MissingStats {
  size_t pixels_with_missing = 0;
  size_t flagged = 0;
  size_t patterns = 0;
};
MissingStats ApplyProjector(const Projector& projector, const std::vector<Vec3>& directions,
                            const std::vector<double>& weights, double max_condition,
                            const SampleMatrix& samples, const std::vector<uint8_t>& missing,
                            SampleMatrix* coefficients, std::vector<uint8_t>* valid_out);

}  // namespace rig
