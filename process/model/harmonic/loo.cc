// The exact leave-one-out evaluation of harmonic bases on an .lp capture, in 8-bit sRGB.
#include "process/model/harmonic/loo.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace rig {

namespace {

// Only the requested order is evaluated; λ (rls) is chosen by LOO error in fit space.
Result<Selection> LooProjector(const LooSpec& spec, const std::vector<Vec3>& dirs,
                               const std::vector<double>& weights, const Eigen::MatrixXd& gram,
                               size_t values, double max_condition) {
  Basis basis(spec.basis, spec.order);
  std::vector<double> lambdas;
  if (spec.method == FitMethod::kRls) {
    for (int e = -16; e <= 2; ++e) lambdas.push_back(std::pow(10.0, e * 0.5));
  } else {
    lambdas.push_back(0);
  }
  Selection best;
  double best_mse = std::numeric_limits<double>::infinity();
  Error last{ErrorCode::kInvalidInput, "leave-one-out error undefined", ""};
  for (double lam : lambdas) {
    auto pr = BuildProjector(basis, dirs, weights, spec.method, lam, max_condition);
    if (!pr.ok()) {
      last = pr.error();
      continue;
    }
    const double mse = LooMse(LooOperator(*pr), gram, static_cast<double>(values));
    if (mse < best_mse) {
      best_mse = mse;
      best.projector = *pr;
      best.order = spec.order;
    }
  }
  if (!std::isfinite(best_mse)) return last;
  return best;
}

// The LOO predictions of every image, back to 8 bits and compared with the stored image:
// the row's fit-space RMSE and its PSNRs.
void ScoreLooPredictions(const RtiImages& images, const SampleMatrix& y, const Projector& pr,
                         const FitTransform& transform, bool linear, LooRow* row) {
  const size_t n = images.radiance.size();
  const size_t values = images.radiance[0].total() * 3;
  const Eigen::MatrixXf m = LooOperator(pr).cast<float>();
  SampleMatrix pred = y;
  pred.noalias() -= m * y;  // y - LOO residual = LOO prediction
  row->fit_space_rmse = std::sqrt((pred - y).cast<double>().squaredNorm() /
                                  static_cast<double>(n * values));
  std::vector<double> mse(n), psnr(n);
  double mse_sum = 0;
  for (size_t i = 0; i < n; ++i) {
    float* p = pred.row(static_cast<Eigen::Index>(i)).data();
    transform.InverseInPlace(p, values);
    const cv::Mat& enc = images.encoded[i];
    double sum = 0;
    size_t idx = 0;
    for (int yy = 0; yy < enc.rows; ++yy) {
      const uint8_t* e = enc.ptr<uint8_t>(yy);
      for (int x = 0; x < enc.cols * 3; ++x, ++idx) {
        const float lin = p[idx];
        const float v = linear ? lin : SrgbEncode(lin);
        const double q = std::round(std::clamp(v * 255.0f, 0.0f, 255.0f));
        const double d = q - e[x];
        sum += d * d;
      }
    }
    mse[i] = sum / static_cast<double>(values);
    mse_sum += mse[i];
    psnr[i] = 10.0 * std::log10(255.0 * 255.0 / std::max(mse[i], 1e-12));
  }
  row->psnr_mean_mse_db = 10.0 * std::log10(255.0 * 255.0 / std::max(mse_sum / n, 1e-12));
  std::sort(psnr.begin(), psnr.end());
  row->psnr_median_db = n % 2 ? psnr[n / 2] : 0.5 * (psnr[n / 2 - 1] + psnr[n / 2]);
}

}  // namespace

std::vector<LooRow> RtiLeaveOneOut(const RtiImages& images, const std::vector<Vec3>& dirs,
                                   const std::vector<LooSpec>& specs, bool linear,
                                   double max_condition) {
  using Clock = std::chrono::steady_clock;
  const size_t n = images.radiance.size();
  const size_t values = images.radiance.empty() ? 0 : images.radiance[0].total() * 3;
  const std::vector<double> weights = UniformHemisphereWeights(n);
  std::map<FitSpace, std::pair<SampleMatrix, Eigen::MatrixXd>> per_space;
  std::vector<LooRow> rows;
  for (const auto& spec : specs) {
    const auto t0 = Clock::now();
    LooRow row;
    row.basis = BasisKindName(spec.basis);
    row.order = spec.order;
    row.terms = Basis::SizeFor(spec.basis, spec.order);
    row.method = FitMethodName(spec.method);
    row.space = FitSpaceName(spec.space);
    FitTransform transform;
    transform.space = spec.space;
    auto it = per_space.find(spec.space);
    if (it == per_space.end()) {
      SampleMatrix y;
      std::vector<uint8_t> missing;
      Status s = BuildSamples(images.radiance, {}, {1, 1, 1}, transform, &y, &missing);
      RIG_CHECK(s.ok(), s.ok() ? "" : s.error().ToString());
      Eigen::MatrixXd g = (y.cast<double>() * y.cast<double>().transpose());
      it = per_space.emplace(spec.space, std::make_pair(std::move(y), std::move(g))).first;
    }
    auto sel = LooProjector(spec, dirs, weights, it->second.second, values, max_condition);
    if (!sel.ok()) {
      row.refusal = sel.error().message;
      rows.push_back(row);
      continue;
    }
    const Projector& pr = sel->projector;
    row.supported = true;
    row.lambda_relative = pr.lambda_relative;
    row.condition = pr.condition;
    ScoreLooPredictions(images, it->second.first, pr, transform, linear, &row);
    row.time_s = std::chrono::duration<double>(Clock::now() - t0).count();
    rows.push_back(row);
  }
  return rows;
}

std::string LooTableMarkdown(const std::vector<LooRow>& rows) {
  std::string s =
      "| basis | order | terms/channel | method | fit space | LOO PSNR (mean MSE) dB | "
      "LOO PSNR (median) dB | LOO RMSE (fit space) | lambda (rel.) | cond(B) | time (s) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : rows) {
    if (!r.supported) {
      s += fmt::format("| {} | {} | {} | {} | {} | refused: {} | | | | | |\n", r.basis, r.order,
                       r.terms, r.method, r.space, r.refusal);
      continue;
    }
    s += fmt::format("| {} | {} | {} | {} | {} | {:.2f} | {:.2f} | {:.5f} | {:.3g} | {:.3g} | "
                     "{:.2f} |\n",
                     r.basis, r.order, r.terms, r.method, r.space, r.psnr_mean_mse_db,
                     r.psnr_median_db, r.fit_space_rmse, r.lambda_relative, r.condition,
                     r.time_s);
  }
  return s;
}

}  // namespace rig
