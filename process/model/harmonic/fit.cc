// Quadrature / least squares / regularised least squares fits as one shared matrix, LOO
// order selection from the Gram matrix, weighted solves for pixels with missing samples.
#include "process/model/harmonic/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <set>

#include <Eigen/Dense>
#include <Eigen/SVD>

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

double SinceS(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Penalty weights l(l+1) of the terms.
Eigen::VectorXd PenaltyWeights(const Basis& basis) {
  auto deg = basis.Degrees();
  Eigen::VectorXd d(basis.size());
  for (int k = 0; k < basis.size(); ++k) d(k) = deg[k] * (deg[k] + 1.0);
  return d;
}

double Condition(const Eigen::VectorXd& singular) {
  if (singular.size() == 0) return std::numeric_limits<double>::infinity();
  const double smax = singular.maxCoeff(), smin = singular.minCoeff();
  if (smin <= smax * 1e-15) return std::numeric_limits<double>::infinity();
  return smax / smin;
}

}  // namespace

const char* FitMethodName(FitMethod m) {
  switch (m) {
    case FitMethod::kQuadrature: return "quadrature";
    case FitMethod::kLs: return "ls";
    case FitMethod::kRls: return "rls";
  }
  return "?";
}

Result<FitMethod> ParseFitMethod(const std::string& name) {
  if (name == "quadrature") return FitMethod::kQuadrature;
  if (name == "ls") return FitMethod::kLs;
  if (name == "rls") return FitMethod::kRls;
  return MakeError(ErrorCode::kInvalidInput, "method",
                   "unknown fit method '{}' (quadrature, ls or rls)", name);
}

Result<FitOptions> FitOptionsFromConfig(const ProcessConfig& p) {
  FitOptions o;
  RIG_ASSIGN_OR_RETURN(o.basis, ParseBasisKind(p.basis));
  RIG_ASSIGN_OR_RETURN(o.method, ParseFitMethod(p.fit_method));
  RIG_ASSIGN_OR_RETURN(o.transform.space, ParseFitSpace(p.fit_space));
  o.order = p.order;
  o.max_order = p.max_order;
  o.order_tolerance = p.order_tolerance;
  o.max_condition = p.max_condition_number;
  o.threads = p.threads;
  return o;
}

Result<Projector> BuildProjector(const Basis& basis, const std::vector<Vec3>& dirs,
                                 const std::vector<double>& weights, FitMethod method,
                                 double lambda_relative, double max_condition) {
  const int n = static_cast<int>(dirs.size());
  const int k = basis.size();
  const std::string where = fmt::format("{} order {} ({} terms, {} poses)", basis.name(),
                                        basis.order(), k, n);
  if (n == 0) return MakeError(ErrorCode::kInvalidInput, where, "no samples");
  Projector pr;
  pr.basis = basis;
  pr.method = method;
  const Eigen::MatrixXd b = basis.Design(dirs);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(b, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd s = svd.singularValues();
  pr.condition = k > n ? std::numeric_limits<double>::infinity() : Condition(s);
  const double tol = s.size() ? s(0) * 1e-12 * std::max(n, k) : 0;
  pr.rank = 0;
  for (int i = 0; i < s.size(); ++i) pr.rank += s(i) > tol;

  switch (method) {
    case FitMethod::kQuadrature: {
      if (static_cast<int>(weights.size()) != n) {
        return MakeError(ErrorCode::kInvalidInput, where, "{} quadrature weights for {} poses",
                         weights.size(), n);
      }
      Eigen::VectorXd w(n);
      for (int i = 0; i < n; ++i) w(i) = weights[i];
      pr.p = b.transpose() * w.asDiagonal();
      pr.solved_condition = pr.condition;
      break;
    }
    case FitMethod::kLs: {
      if (k > n - 1) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "least squares needs fewer terms than poses (at least one pose to spare "
                         "for validation); use a lower order or --method rls");
      }
      if (pr.rank < k || pr.condition > max_condition) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "the lamp directions cannot support this order: condition number {:.3g} "
                         "exceeds the limit {:.3g} (rank {} of {}); use a lower order or "
                         "--method rls",
                         pr.condition, max_condition, pr.rank, k);
      }
      pr.p = svd.matrixV() * s.cwiseInverse().asDiagonal() * svd.matrixU().transpose();
      pr.solved_condition = pr.condition;
      break;
    }
    case FitMethod::kRls: {
      const Eigen::MatrixXd btb = b.transpose() * b;
      const double scale = std::max(btb.trace() / k, 1e-300);
      pr.lambda_relative = lambda_relative;
      pr.lambda = lambda_relative * scale;
      Eigen::MatrixXd a = btb;
      a.diagonal() += pr.lambda * PenaltyWeights(basis);
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(a, Eigen::EigenvaluesOnly);
      const double emin = eig.eigenvalues().minCoeff(), emax = eig.eigenvalues().maxCoeff();
      pr.solved_condition =
          emin > emax * 1e-30 ? std::sqrt(emax / emin) : std::numeric_limits<double>::infinity();
      if (!(pr.solved_condition <= max_condition)) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "regularised system condition number {:.3g} exceeds the limit {:.3g} "
                         "(lambda {:.3g}); increase lambda or lower the order",
                         pr.solved_condition, max_condition, lambda_relative);
      }
      pr.p = a.ldlt().solve(b.transpose());
      break;
    }
  }
  pr.hat = b * pr.p;
  return pr;
}

Eigen::MatrixXd LooOperator(const Projector& pr) {
  const Eigen::Index n = pr.hat.rows();
  Eigen::MatrixXd m;
  if (pr.method == FitMethod::kQuadrature) {
    m = -pr.hat;
    m.diagonal().setOnes();
    return m;
  }
  m = -pr.hat;
  m.diagonal().array() += 1.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double d = 1.0 - pr.hat(i, i);
    if (d < 1e-6) return Eigen::MatrixXd();
    m.row(i) /= d;
  }
  return m;
}

double LooMse(const Eigen::MatrixXd& m, const Eigen::MatrixXd& gram, double count) {
  if (m.size() == 0 || count <= 0) return std::numeric_limits<double>::infinity();
  // Σ over pixels |M y|² = trace(M G Mᵀ).
  const double sum = ((m * gram).array() * m.array()).sum();
  return std::max(0.0, sum) / (count * static_cast<double>(m.rows()));
}

std::vector<double> GridQuadratureWeights(const std::vector<double>& h_deg,
                                          const std::vector<double>& v_deg) {
  auto step = [](std::vector<double> a) {
    std::sort(a.begin(), a.end());
    double best = 0;
    for (size_t i = 1; i < a.size(); ++i) {
      const double d = a[i] - a[i - 1];
      if (d > 1e-6 && (best == 0 || d < best)) best = d;
    }
    return best > 0 ? best : 10.0;
  };
  const double kRad = std::numbers::pi / 180.0;
  const double dh = step(h_deg) * kRad, dv = step(v_deg) * kRad;
  std::vector<double> w(h_deg.size());
  for (size_t i = 0; i < w.size(); ++i) w[i] = std::cos(v_deg[i] * kRad) * dh * dv;
  return w;
}

std::vector<double> UniformHemisphereWeights(size_t count) {
  return std::vector<double>(count, count ? 2.0 * std::numbers::pi / count : 0.0);
}

Result<Selection> SelectProjector(const std::vector<Vec3>& dirs,
                                  const std::vector<double>& weights,
                                  const Eigen::MatrixXd& gram, double count,
                                  const FitOptions& o) {
  const int lo = o.basis == BasisKind::kPtm ? 1 : 0;
  const int hi_cap = o.basis == BasisKind::kPtm ? 8 : 12;
  const int hi = std::min(hi_cap, std::max(o.max_order, o.order));
  if (o.order >= 0 && (o.order < lo || o.order > hi_cap)) {
    return MakeError(ErrorCode::kInvalidInput, "order",
                     "order {} is outside {}..{} for basis '{}'", o.order, lo, hi_cap,
                     BasisKindName(o.basis));
  }
  // λ candidates for rls: half-decades relative to trace(BᵀB)/K.
  std::vector<double> lambdas;
  if (o.method == FitMethod::kRls) {
    if (o.lambda >= 0) {
      lambdas.push_back(o.lambda);
    } else {
      for (int e = -16; e <= 2; ++e) lambdas.push_back(std::pow(10.0, e * 0.5));
    }
  } else {
    lambdas.push_back(0);
  }

  Selection sel;
  if (count > 0 && gram.rows() > 0)
    sel.data_rms = std::sqrt(std::max(0.0, gram.trace()) / (count * static_cast<double>(gram.rows())));
  std::map<int, Projector> built;
  for (int order = lo; order <= hi; ++order) {
    const auto t0 = Clock::now();
    Basis basis(o.basis, order);
    OrderReport rep;
    rep.order = order;
    rep.terms = basis.size();
    double best = std::numeric_limits<double>::infinity();
    std::string last_refusal;
    for (double lam : lambdas) {
      auto pr = BuildProjector(basis, dirs, weights, o.method, lam, o.max_condition);
      if (!pr.ok()) {
        last_refusal = pr.error().message;
        continue;
      }
      const Eigen::MatrixXd m = LooOperator(*pr);
      const double mse = LooMse(m, gram, count);
      rep.condition = pr->condition;
      if (!(mse < best)) continue;
      best = mse;
      rep.supported = true;
      rep.lambda_relative = pr->lambda_relative;
      rep.loo_rmse = std::sqrt(mse);
      rep.solved_condition = pr->solved_condition;
      built[order] = std::move(*pr);
    }
    if (!rep.supported) {
      rep.refusal = last_refusal.empty() ? "leave-one-out error undefined" : last_refusal;
      if (rep.condition == 0) {
        Eigen::JacobiSVD<Eigen::MatrixXd> svd(basis.Design(dirs));
        rep.condition = basis.size() > static_cast<int>(dirs.size())
                            ? std::numeric_limits<double>::infinity()
                            : Condition(svd.singularValues());
      }
    } else if (!std::isfinite(rep.loo_rmse)) {
      rep.supported = false;
      rep.refusal = "leave-one-out error undefined (a sample fully determines its own fit)";
    }
    rep.build_time_s = SinceS(t0);
    sel.orders.push_back(rep);
  }

  if (o.order >= 0) {
    for (const auto& r : sel.orders) {
      if (r.order != o.order) continue;
      if (!built.count(o.order)) {
        return MakeError(ErrorCode::kInvalidInput,
                         fmt::format("{} order {} ({} terms, {} poses, method {})",
                                     BasisKindName(o.basis), o.order, r.terms, dirs.size(),
                                     FitMethodName(o.method)),
                         "refused: {}", r.refusal);
      }
      sel.order = o.order;
      sel.projector = built[o.order];
      return sel;
    }
  }
  double best = std::numeric_limits<double>::infinity();
  for (const auto& r : sel.orders)
    if (r.supported) best = std::min(best, r.loo_rmse);
  if (!std::isfinite(best)) {
    return MakeError(ErrorCode::kInvalidInput, fmt::format("{} poses", dirs.size()),
                     "no order of basis '{}' can be fitted stably with method {}",
                     BasisKindName(o.basis), FitMethodName(o.method));
  }
  for (const auto& r : sel.orders) {
    if (r.supported && r.loo_rmse <= best * (1.0 + o.order_tolerance)) {
      sel.order = r.order;
      sel.projector = built[r.order];
      break;
    }
  }
  return sel;
}

MissingStats ApplyProjector(const Projector& pr, const std::vector<Vec3>& dirs,
                            const std::vector<double>& weights, double max_condition,
                            const SampleMatrix& y, const std::vector<uint8_t>& missing,
                            SampleMatrix* coeffs, std::vector<uint8_t>* valid_out) {
  const Eigen::Index n = y.rows();
  const size_t pixels = static_cast<size_t>(y.cols()) / 3;
  const int k = pr.basis.size();
  const Eigen::MatrixXf pf = pr.p.cast<float>();
  coeffs->resize(k, y.cols());
  coeffs->noalias() = pf * y;
  valid_out->assign(pixels, 1);
  MissingStats stats;
  if (missing.empty()) return stats;

  const Eigen::MatrixXd b = pr.basis.Design(dirs);
  Eigen::VectorXd pen = PenaltyWeights(pr.basis) * pr.lambda;
  // Distinct missing patterns share one reduced projector.
  std::map<std::string, std::pair<bool, Eigen::MatrixXf>> cache;
  std::string pattern(static_cast<size_t>(n), '\0');
  for (size_t p = 0; p < pixels; ++p) {
    bool any = false;
    for (Eigen::Index i = 0; i < n; ++i) {
      pattern[i] = static_cast<char>(missing[i * pixels + p]);
      any |= pattern[i] != 0;
    }
    if (!any) continue;
    ++stats.pixels_with_missing;
    auto it = cache.find(pattern);
    if (it == cache.end()) {
      std::vector<Eigen::Index> keep;
      for (Eigen::Index i = 0; i < n; ++i)
        if (!pattern[i]) keep.push_back(i);
      bool ok = static_cast<int>(keep.size()) >= k;
      Eigen::MatrixXf full = Eigen::MatrixXf::Zero(k, n);
      if (ok) {
        Eigen::MatrixXd bv(keep.size(), k);
        for (size_t j = 0; j < keep.size(); ++j) bv.row(j) = b.row(keep[j]);
        Eigen::MatrixXd pv;
        if (pr.method == FitMethod::kQuadrature) {
          pv.resize(k, keep.size());
          for (size_t j = 0; j < keep.size(); ++j) pv.col(j) = bv.row(j).transpose() * weights[keep[j]];
        } else {
          Eigen::MatrixXd a = bv.transpose() * bv;
          a.diagonal() += pen;
          Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(a, Eigen::EigenvaluesOnly);
          const double emin = eig.eigenvalues().minCoeff(), emax = eig.eigenvalues().maxCoeff();
          ok = emin > 0 && std::sqrt(emax / emin) <= max_condition;
          if (ok) pv = a.ldlt().solve(bv.transpose());
        }
        if (ok) {
          for (size_t j = 0; j < keep.size(); ++j) full.col(keep[j]) = pv.col(j).cast<float>();
        }
      }
      it = cache.emplace(pattern, std::make_pair(ok, std::move(full))).first;
    }
    const auto& [ok, pp] = it->second;
    for (int c = 0; c < 3; ++c) {
      const Eigen::Index col = static_cast<Eigen::Index>(3 * p + c);
      if (ok) {
        coeffs->col(col).noalias() = pp * y.col(col);
      } else {
        coeffs->col(col).setZero();
      }
    }
    if (!ok) {
      (*valid_out)[p] = 0;
      ++stats.flagged;
    }
  }
  stats.patterns = cache.size();
  return stats;
}

std::string LooRelativeCell(double loo_rmse, double data_rms) {
  return data_rms > 0 ? fmt::format("{:.2f}%", 100 * loo_rmse / data_rms) : "";
}

std::string SelectionTable(const Selection& selection, const std::string& unit) {
  std::string md = fmt::format(
      "| order | terms | supported | LOO RMS error ({}) | LOO / samples' RMS | condition | "
      "λ (relative) |\n|---|---|---|---|---|---|---|\n", unit);
  for (const auto& o : selection.orders) {
    if (!o.supported) {
      md += fmt::format("| {} | {} | no: {} | | | | |\n", o.order, o.terms, o.refusal);
      continue;
    }
    md += fmt::format("| {} | {} | yes | {:.5g} | {} | {} | {:.3g} |\n", o.order, o.terms,
                      o.loo_rmse, LooRelativeCell(o.loo_rmse, selection.data_rms),
                      ConditionCell(o.condition, o.lambda_relative), o.lambda_relative);
  }
  return md;
}

std::string ConditionCell(double condition, double lambda_relative) {
  // Infinite: the design is rank deficient; only rls's λ makes such an order solvable.
  if (std::isfinite(condition)) return fmt::format("{:.3g}", condition);
  return lambda_relative > 0 ? "ill-conditioned (rank deficient; regularised by λ)"
                             : "ill-conditioned (rank deficient)";
}

}  // namespace rig
