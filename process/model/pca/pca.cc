// PCA of multi-light samples with a fitted octahedral grid per component (relight's
// "bilinear" layout), coefficients refitted through the stored basis, masked samples fitted
// around, planes quantised as relight does and written as RGB JPEGs.
#include "process/model/pca/pca.h"
#include "config/atomic_file.h"
#include "process/io/json_file.h"
#include "process/io/model_limits.h"

#include <algorithm>
#include <atomic>
#include <functional>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <numeric>
#include <random>
#include <thread>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "process/io/jpeg_io.h"
#include "process/model/samples.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// Relight's octahedral map of a direction onto the grid, and the four bilinear weights.
void OctaWeights(const Vec3& d, int res, int node[4], double w[4]) {
  const double s = std::abs(d[0]) + std::abs(d[1]) + std::abs(d[2]);
  const double x = (d[0] + d[1]) / s, y = (d[1] - d[0]) / s;
  const double u = (x + 1) / 2 * (res - 1), v = (y + 1) / 2 * (res - 1);
  const int sx = std::clamp(static_cast<int>(std::floor(u)), 0, res - 2);
  const int sy = std::clamp(static_cast<int>(std::floor(v)), 0, res - 2);
  const double dx = u - sx, dy = v - sy;
  node[0] = sx + sy * res;
  node[1] = sx + 1 + sy * res;
  node[2] = sx + (sy + 1) * res;
  node[3] = sx + 1 + (sy + 1) * res;
  w[0] = (1 - dx) * (1 - dy);
  w[1] = dx * (1 - dy);
  w[2] = (1 - dx) * dy;
  w[3] = dx * dy;
}

Eigen::MatrixXd GridWeights(const std::vector<Vec3>& lights, int res) {
  Eigen::MatrixXd w = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(lights.size()), res * res);
  for (size_t l = 0; l < lights.size(); ++l) {
    int node[4];
    double wt[4];
    OctaWeights(lights[l], res, node, wt);
    for (int i = 0; i < 4; ++i) w(static_cast<Eigen::Index>(l), node[i]) += wt[i];
  }
  return w;
}

// The prior's quadratic form over the grid nodes, gᵀ·Q·g, normalised to a mean diagonal of
// 1, with δ = 1e-7 on the diagonal so that it is positive definite. Sparse and banded (the
// grid's rows are res apart): its Cholesky factor in the natural order costs n·(2·res)².
Eigen::SparseMatrix<double> GridPriorMatrix(int res, GridPrior prior) {
  const int n = res * res;
  // Graph Laplacian of the 4-neighbour grid (Neumann at the borders).
  std::vector<Eigen::Triplet<double>> t;
  for (int y = 0; y < res; ++y) {
    for (int x = 0; x < res; ++x) {
      const int i = x + y * res;
      const int nb[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
      for (const auto& q : nb) {
        if (q[0] < 0 || q[0] >= res || q[1] < 0 || q[1] >= res) continue;
        t.emplace_back(i, i, 1.0);
        t.emplace_back(i, q[0] + q[1] * res, -1.0);
      }
    }
  }
  Eigen::SparseMatrix<double> lap(n, n);
  lap.setFromTriplets(t.begin(), t.end());
  Eigen::SparseMatrix<double> q =
      prior == GridPrior::kMembrane ? lap : Eigen::SparseMatrix<double>(lap.transpose() * lap);
  double trace = 0;
  for (int i = 0; i < n; ++i) trace += q.coeff(i, i);
  q /= std::max(trace / n, 1e-12);
  Eigen::SparseMatrix<double> id(n, n);
  id.setIdentity();
  q += 1e-7 * id;
  q.makeCompressed();
  return q;
}

// The prior's Cholesky factor depends on the grid alone: computed once per (res, prior).
struct PriorFactor {
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> llt;
};
const PriorFactor& CachedPriorFactor(int res, GridPrior prior) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, std::unique_ptr<PriorFactor>> cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto& slot = cache[{res, static_cast<int>(prior)}];
  if (!slot) {
    slot = std::make_unique<PriorFactor>();
    slot->llt.compute(GridPriorMatrix(res, prior));
  }
  return *slot;
}

struct GridFit {
  GridPrior prior;
  double smoothness;
  double loo_rms;
  Eigen::MatrixXd grid;  // nodes × functions
  int trend = 0;         // unpenalised trend terms (4: 1, lx, ly, lz)
};

// The direction of grid node (x, y): relight's inverse octahedral map.
Vec3 NodeDirection(int x, int y, int res) {
  const double ox = 2.0 * x / (res - 1) - 1, oy = 2.0 * y / (res - 1) - 1;
  const double dx = (ox - oy) / 2, dy = (ox + oy) / 2;
  Vec3 n = {dx, dy, std::max(0.0, 1 - std::abs(dx) - std::abs(dy))};
  const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (auto& c : n) c /= len;
  return n;
}

// Fits every function (columns of f, one row per light) onto the grid with one shared
// smoother: an unpenalised trend linear in the light direction (1, lx, ly, lz — what a matte
// surface is) plus a grid residual under the prior; both are baked into the stored grid.
// With `smoothness` < 0 the trend (or none), the prior's kind and its strength minimise the
// weighted leave-one-out error over lights (exact for a linear smoother: r / (1 − H_ll)).
GridFit FitGrid(const Eigen::MatrixXd& w, const std::vector<Vec3>& lights,
                const Eigen::MatrixXd& f, const Eigen::VectorXd& weight, int res,
                double smoothness) {
  const Eigen::Index nl = w.rows(), nodes = w.cols();
  const double data_scale = std::max(w.squaredNorm() / static_cast<double>(nodes), 1e-12);
  const double total_weight = weight.sum() * static_cast<double>(f.rows());
  GridFit best{GridPrior::kBending, 0, std::numeric_limits<double>::infinity(), {}};
  for (int trend : {4, 0}) {
    // P projects the data onto the trend's span, M = I − P onto what the grid must carry:
    // hat = P + M·W·(WᵀMW + λQ)⁻¹·WᵀM, the second part computed as below with W → M·W.
    Eigen::MatrixXd h(nl, trend), hn(nodes, trend);
    for (Eigen::Index l = 0; l < nl && trend; ++l)
      h.row(l) << 1, lights[l][0], lights[l][1], lights[l][2];
    for (int y = 0; y < res && trend; ++y)
      for (int x = 0; x < res; ++x) {
        const Vec3 d = NodeDirection(x, y, res);
        hn.row(x + y * res) << 1, d[0], d[1], d[2];
      }
    Eigen::MatrixXd proj = Eigen::MatrixXd::Zero(nl, nl);
    if (trend) {
      const Eigen::HouseholderQR<Eigen::MatrixXd> qr(h);
      const Eigen::MatrixXd q1 = qr.householderQ() * Eigen::MatrixXd::Identity(nl, trend);
      proj = q1 * q1.transpose();
    }
    const Eigen::MatrixXd mw = w - proj * w;
    const Eigen::MatrixXd pf = proj * f;
    for (GridPrior prior : {GridPrior::kBending, GridPrior::kMembrane}) {
      // With Q + δI = L·Lᵀ and K = L⁻¹·(MW)ᵀ = U·Σ·Vᵀ (thin), every strength λ costs only
      // diagonal work: g = L⁻ᵀ·U·diag(σ/(σ²+λ))·Vᵀ·f, M·W·g = V·diag(σ²/(σ²+λ))·Vᵀ·f.
      const PriorFactor& factor = CachedPriorFactor(res, prior);
      const Eigen::MatrixXd k = factor.llt.matrixL().solve(mw.transpose()) / std::sqrt(data_scale);
      // Thin SVD of K from the small eigenproblem KᵀK = V·Σ²·Vᵀ (lights × lights).
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> small(k.transpose() * k);
      const Eigen::VectorXd sigma = small.eigenvalues().cwiseMax(0).cwiseSqrt();
      const Eigen::MatrixXd& v = small.eigenvectors();
      const Eigen::VectorXd inv =
          (sigma.array() > 1e-9 * sigma.maxCoeff()).select(sigma.array().inverse(), 0.0).matrix();
      const Eigen::MatrixXd vtf = v.transpose() * f;
      std::vector<double> strengths;
      if (smoothness >= 0) {
        strengths.push_back(smoothness);
      } else {
        for (double e = -5; e <= 1.01; e += 0.5) strengths.push_back(std::pow(10.0, e));
      }
      for (double lambda : strengths) {
        const Eigen::ArrayXd shrink = sigma.array().square() / (sigma.array().square() + lambda);
        const Eigen::MatrixXd fitted = pf + v * (shrink.matrix().asDiagonal() * vtf);
        const Eigen::VectorXd hat_diag =
            proj.diagonal() + (v.array().square().rowwise() * shrink.transpose()).rowwise().sum().matrix();
        double err = 0;
        for (Eigen::Index l = 0; l < f.rows(); ++l) {
          const double denom = std::max(1.0 - hat_diag(l), 1e-6);
          err += ((f.row(l) - fitted.row(l)).array().square() * weight.transpose().array()).sum() /
                 (denom * denom);
        }
        const double rms = std::sqrt(err / total_weight);
        if (rms < best.loo_rms) {
          // U·diag(σ/(σ²+λ)) = K·V·diag(1/σ)·diag(σ/(σ²+λ)) = K·V·diag(1/(σ²+λ)) on σ > 0.
          const Eigen::ArrayXd gain = inv.array() * sigma.array() / (sigma.array().square() + lambda);
          const Eigen::MatrixXd inner = k * (v * (gain.matrix().asDiagonal() * vtf));
          Eigen::MatrixXd grid = factor.llt.matrixU().solve(inner) / std::sqrt(data_scale);
          if (trend) {
            const Eigen::MatrixXd beta = h.colPivHouseholderQr().solve(f - w * grid);
            grid += hn * beta;
          }
          best = {prior, lambda, rms, std::move(grid)};
          best.trend = trend;
        }
      }
      if (smoothness >= 0) break;  // a given strength: the bending prior
    }
  }
  return best;
}

}  // namespace

// Deterministic sample of pixel indices: one per stride, at a seeded offset within it.
std::vector<size_t> SamplePixels(size_t pixels, size_t wanted, uint64_t seed) {
  std::vector<size_t> out;
  if (wanted >= pixels) {
    out.resize(pixels);
    std::iota(out.begin(), out.end(), size_t{0});
    return out;
  }
  const double stride = static_cast<double>(pixels) / static_cast<double>(wanted);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  out.reserve(wanted);
  for (size_t i = 0; i < wanted; ++i) {
    const size_t p = static_cast<size_t>((static_cast<double>(i) + u(rng)) * stride);
    out.push_back(std::min(p, pixels - 1));
  }
  return out;
}

namespace {

void ParallelFor(size_t n, int threads, const std::function<void(size_t, size_t)>& body) {
  threads = std::max(1, std::min<int>(threads, static_cast<int>((n + 4095) / 4096)));
  if (threads == 1) {
    body(0, n);
    return;
  }
  std::vector<std::thread> pool;
  const size_t chunk = (n + threads - 1) / threads;
  for (int t = 0; t < threads; ++t) {
    const size_t lo = t * chunk, hi = std::min(n, lo + chunk);
    if (lo < hi) pool.emplace_back(body, lo, hi);
  }
  for (auto& th : pool) th.join();
}

// Quantiles of each column (sorted copies; the sample is small).
std::vector<PlaneQuantisation> Ranges(const Eigen::MatrixXf& coeffs, double quantile) {
  std::vector<PlaneQuantisation> out(static_cast<size_t>(coeffs.cols()));
  std::vector<float> v(static_cast<size_t>(coeffs.rows()));
  for (Eigen::Index p = 0; p < coeffs.cols(); ++p) {
    for (Eigen::Index i = 0; i < coeffs.rows(); ++i) v[static_cast<size_t>(i)] = coeffs(i, p);
    const auto at = [&](double q) {
      const size_t i = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(i), v.end());
      return static_cast<double>(v[i]);
    };
    PlaneQuantisation& q = out[static_cast<size_t>(p)];
    q.min = at(quantile);
    q.max = at(1 - quantile);
    if (!(q.max > q.min)) q.max = q.min + 1;
  }
  return out;
}

void Decompose(PcaComponents* pc, int count) {
  const Eigen::Index dim = pc->covariance.rows();
  count = std::max(1, std::min<int>(count, static_cast<int>(dim) - 1));
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(pc->covariance);
  pc->vectors.resize(dim, count);
  pc->eigenvalues.resize(count);
  for (int p = 0; p < count; ++p) {
    pc->vectors.col(p) = eig.eigenvectors().col(dim - 1 - p);
    pc->eigenvalues[p] = std::max(0.0, eig.eigenvalues()(dim - 1 - p));
  }
}

}  // namespace

const char* PcaMaskModeName(PcaMaskMode mode) {
  switch (mode) {
    case PcaMaskMode::kNone: return "none";
    case PcaMaskMode::kDrop: return "drop";
    case PcaMaskMode::kHinge: return "hinge";
  }
  return "?";
}

namespace {

// Rti::lightWeightsRbf's weights of the lights at a direction (relight's renderer takes the
// direction's x and y and makes z = √(1 − x² − y²)): w_i = exp(−|l − L_i|²/σ²) normalised to
// sum 1, those at or below 0.001 dropped and the rest normalised again.
void RbfWeights(const std::vector<Vec3>& lights, double sigma, const Vec3& direction,
                std::vector<std::pair<int, double>>* out) {
  const double n = std::sqrt(direction[0] * direction[0] + direction[1] * direction[1] +
                             direction[2] * direction[2]);
  const double lx = n > 0 ? direction[0] / n : 0, ly = n > 0 ? direction[1] / n : 0;
  const double lz = std::sqrt(std::max(0.0, 1 - lx * lx - ly * ly));
  const double radius = 1.0 / (sigma * sigma);
  std::vector<double> w(lights.size());
  double total = 0;
  for (size_t i = 0; i < lights.size(); ++i) {
    const double dx = lx - lights[i][0], dy = ly - lights[i][1], dz = lz - lights[i][2];
    w[i] = std::exp(-radius * (dx * dx + dy * dy + dz * dz));
    total += w[i];
  }
  out->clear();
  double kept = 0;
  for (size_t i = 0; i < lights.size(); ++i) {
    const double v = total > 0 ? w[i] / total : 0;
    if (v > 0.001) {
      out->push_back({static_cast<int>(i), v});
      kept += v;
    }
  }
  for (auto& e : *out) e.second /= kept;
}

}  // namespace

void PcaBasis::Evaluate(const Vec3& direction, double* out) const {
  const size_t n = static_cast<size_t>(nodes());
  if (rbf()) {
    std::vector<std::pair<int, double>> w;
    RbfWeights(rbf_lights, sigma, direction, &w);
    for (int p = 0; p <= components; ++p) {
      for (int c = 0; c < 3; ++c) {
        double v = 0;
        for (const auto& [i, wi] : w) v += wi * values[(static_cast<size_t>(p) * n + i) * 3 + c];
        out[p * 3 + c] = v;
      }
    }
    return;
  }
  int node[4];
  double w[4];
  OctaWeights(direction, resolution, node, w);
  for (int p = 0; p <= components; ++p) {
    for (int c = 0; c < 3; ++c) {
      double v = 0;
      for (int i = 0; i < 4; ++i) v += w[i] * values[(static_cast<size_t>(p) * n + node[i]) * 3 + c];
      out[p * 3 + c] = v;
    }
  }
}

namespace {

// Mean and covariance of the rows (the lower-triangle GEMM on two fixed halves of the rows,
// one thread each, summed in a fixed order: the same bits whatever the machine's load).
void MeanAndCovariance(const Eigen::MatrixXf& values, PcaComponents* pc) {
  const Eigen::Index m = values.rows(), dim = values.cols();
  pc->mean = values.cast<double>().colwise().mean().transpose();
  const Eigen::MatrixXf xs = values.rowwise() - pc->mean.cast<float>().transpose();
  const Eigen::Index half = m / 2;
  Eigen::MatrixXf gram = Eigen::MatrixXf::Zero(dim, dim), gram2 = Eigen::MatrixXf::Zero(dim, dim);
  std::thread second([&] {
    gram2.selfadjointView<Eigen::Lower>().rankUpdate(xs.bottomRows(m - half).transpose());
  });
  if (half > 0) gram.selfadjointView<Eigen::Lower>().rankUpdate(xs.topRows(half).transpose());
  second.join();
  gram += gram2;
  gram.triangularView<Eigen::StrictlyUpper>() = gram.transpose();
  pc->covariance = gram.cast<double>() / static_cast<double>(std::max<Eigen::Index>(m - 1, 1));
}

// Censored samples filled in from the components: each sampled pixel's coefficients solved
// from its usable samples alone, and every clipped sample replaced by the larger of its value
// and the prediction (a black one by the smaller) — what the sample says: "at least" /
// "at most" this. Rows without masked samples are untouched.
void ImputeCensored(const PcaComponents& pc, const PcaOptions& o, Eigen::MatrixXf* values) {
  const Eigen::Index m = values->rows(), dim = values->cols();
  const Eigen::Index k = pc.vectors.cols();
  const Eigen::MatrixXf e = pc.vectors.cast<float>();
  const Eigen::VectorXf mu = pc.mean.cast<float>();
  const int black = o.thresholds.black_max, clipped = o.thresholds.clipped_min;
  auto rows = [&](Eigen::Index lo, Eigen::Index hi) {
    std::vector<Eigen::Index> masked;
    for (Eigen::Index i = lo; i < hi; ++i) {
      masked.clear();
      for (Eigen::Index d = 0; d < dim; ++d) {
        const float v = (*values)(i, d);
        if (v <= black || v >= clipped) masked.push_back(d);
      }
      if (masked.empty() || static_cast<Eigen::Index>(masked.size()) > dim - 2 * k) continue;
      const Eigen::VectorXf y = values->row(i).transpose() - mu;
      // Components are orthonormal: over the usable samples Gᵤ = I − Σ_masked e_d·e_dᵀ.
      Eigen::MatrixXf g = Eigen::MatrixXf::Identity(k, k);
      Eigen::VectorXf rhs = e.transpose() * y;
      for (Eigen::Index d : masked) {
        g.noalias() -= e.row(d).transpose() * e.row(d);
        rhs.noalias() -= e.row(d).transpose() * y(d);
      }
      const Eigen::LLT<Eigen::MatrixXf> llt(g);
      if (llt.info() != Eigen::Success) continue;
      const Eigen::VectorXf c = llt.solve(rhs);
      for (Eigen::Index d : masked) {
        const float v = (*values)(i, d);
        const float pred = mu(d) + e.row(d).dot(c);
        (*values)(i, d) = v >= clipped ? std::max(v, pred) : std::min(v, pred);
      }
    }
  };
  const Eigen::Index half = m / 2;
  std::thread second(rows, half, m);
  rows(0, half);
  second.join();
}

// The components from the samples of the subset's pixels: row(i, subset[i]) points at the
// i-th sampled pixel's samples. With a mask, censored samples are imputed and the components
// computed again (options.impute_iterations times).
PcaComponents ComponentsOfRows(const std::vector<Vec3>& lights, std::vector<size_t> subset,
                               const std::function<const uint8_t*(size_t, size_t)>& row,
                               int count, const PcaOptions& o) {
  const int dim = static_cast<int>(lights.size()) * 3;
  PcaComponents pc;
  pc.lights = lights;
  pc.subset = std::move(subset);
  const Eigen::Index m = static_cast<Eigen::Index>(pc.subset.size());
  Eigen::MatrixXf values(m, dim);
  for (Eigen::Index i = 0; i < m; ++i) {
    const uint8_t* v = row(static_cast<size_t>(i), pc.subset[static_cast<size_t>(i)]);
    for (int d = 0; d < dim; ++d) values(i, d) = v[d];
  }
  MeanAndCovariance(values, &pc);
  Decompose(&pc, count);
  if (o.mask == PcaMaskMode::kNone) return pc;
  for (int it = 0; it < o.impute_iterations; ++it) {
    ImputeCensored(pc, o, &values);
    MeanAndCovariance(values, &pc);
    Decompose(&pc, count);
  }
  return pc;
}

}  // namespace

Result<PcaComponents> ComputePcaComponents(const LightSamples& samples, const PcaOptions& o,
                                           int count) {
  const int lights = samples.lights();
  const size_t pixels = samples.pixels();
  const int dim = lights * 3;
  if (lights < 4 || pixels == 0 || samples.values.size() != pixels * dim) {
    return MakeError(ErrorCode::kInvalidInput, "pca", "{} lights and {} pixels: nothing to fit",
                     lights, pixels);
  }
  return ComponentsOfRows(
      samples.directions, SamplePixels(pixels, o.basis_pixels, o.seed),
      [&](size_t, size_t pixel) { return samples.values.data() + pixel * dim; }, count, o);
}

Result<PcaComponents> ComputePcaComponentsOfSample(const LightSamples& sampled,
                                                   std::vector<size_t> subset, int count,
                                                   const PcaOptions& o) {
  const int lights = sampled.lights();
  const size_t dim = static_cast<size_t>(lights) * 3;
  if (lights < 4 || subset.empty() || sampled.pixels() != subset.size() ||
      sampled.values.size() != subset.size() * dim) {
    return MakeError(ErrorCode::kInvalidInput, "pca", "{} lights and {} sampled pixels: nothing to fit",
                     lights, subset.size());
  }
  return ComponentsOfRows(
      sampled.directions, std::move(subset),
      [&](size_t i, size_t) { return sampled.values.data() + i * dim; }, count, o);
}

PcaComponents PcaComponentsWithout(const PcaComponents& full, const std::vector<int>& dropped,
                                   int count) {
  PcaComponents pc;
  pc.subset = full.subset;
  std::vector<int> keep;
  const int lights = static_cast<int>(full.lights.size());
  for (int l = 0; l < lights; ++l) {
    if (std::find(dropped.begin(), dropped.end(), l) != dropped.end()) continue;
    pc.lights.push_back(full.lights[l]);
    for (int c = 0; c < 3; ++c) keep.push_back(l * 3 + c);
  }
  const Eigen::Index dim = static_cast<Eigen::Index>(keep.size());
  pc.mean.resize(dim);
  pc.covariance.resize(dim, dim);
  for (Eigen::Index i = 0; i < dim; ++i) {
    pc.mean(i) = full.mean(keep[i]);
    for (Eigen::Index j = 0; j < dim; ++j) pc.covariance(i, j) = full.covariance(keep[i], keep[j]);
  }
  Decompose(&pc, count);
  return pc;
}

Result<PcaModel> FitPca(const LightSamples& samples, const PcaOptions& o, PcaFitStats* stats) {
  const auto t0 = Clock::now();
  RIG_ASSIGN_OR_RETURN(PcaComponents pc, ComputePcaComponents(samples, o, o.components));
  RIG_ASSIGN_OR_RETURN(PcaModel m, FitPcaWith(samples, pc, o, stats));
  if (stats) stats->time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return m;
}

Result<PcaModel> FitPcaWith(const LightSamples& samples, const PcaComponents& pc,
                            const PcaOptions& o, PcaFitStats* stats) {
  const auto t0 = Clock::now();
  const int lights = samples.lights();
  const size_t pixels = samples.pixels();
  const int dim = lights * 3;
  if (pc.mean.size() != dim || samples.values.size() != pixels * dim) {
    return MakeError(ErrorCode::kInternal, "pca", "components of {} values for samples of {}",
                     pc.mean.size(), dim);
  }
  const int k = std::min<int>(o.components, static_cast<int>(pc.vectors.cols()));
  if (k < 1) return MakeError(ErrorCode::kInvalidInput, "pca", "no components asked");
  const int res = o.grid_resolution;
  if (res < 2 || res > 64) {
    return MakeError(ErrorCode::kInvalidInput, "pca", "grid resolution {} outside 2..64", res);
  }
  RIG_ASSIGN_OR_RETURN(PcaBasis basis, FitPcaBasis(pc, k, res, o.smoothness));
  RIG_ASSIGN_OR_RETURN(PcaModel model, FitPcaCoefficients(samples, std::move(basis), o, pc.subset, stats));
  if (stats) stats->time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return model;
}

Result<PcaBasis> FitPcaBasis(const PcaComponents& pc, int k, int res, double smoothness) {
  const int lights = static_cast<int>(pc.lights.size());
  if (k < 1 || k > pc.vectors.cols() || res < 2 || res > 64) {
    return MakeError(ErrorCode::kInvalidInput, "pca", "{} components on a {} grid: out of range", k, res);
  }
  const Eigen::VectorXd& mean = pc.mean;
  const Eigen::MatrixXd comps = pc.vectors.leftCols(k);
  const std::vector<double> eigenvalues(pc.eigenvalues.begin(), pc.eigenvalues.begin() + k);

  // 2. The light dependence of the mean and of each component, fitted onto the grid.
  Eigen::MatrixXd f(lights, 3 * (k + 1));
  Eigen::VectorXd weight(3 * (k + 1));
  for (int l = 0; l < lights; ++l) {
    for (int c = 0; c < 3; ++c) {
      f(l, c) = mean(l * 3 + c);
      for (int p = 0; p < k; ++p) f(l, (p + 1) * 3 + c) = comps(l * 3 + c, p);
    }
  }
  for (int c = 0; c < 3; ++c) {
    weight(c) = 1;
    for (int p = 0; p < k; ++p) weight((p + 1) * 3 + c) = eigenvalues[p];
  }
  const Eigen::MatrixXd w = GridWeights(pc.lights, res);
  const GridFit grid = FitGrid(w, pc.lights, f, weight, res, smoothness);

  // 3. The basis as relight stores it: the mean as integers 0..255, components as
  //    127 + range·e with range = 127 / max|e|.
  PcaBasis b;
  b.components = k;
  b.resolution = res;
  b.prior = grid.prior;
  b.smoothness = grid.smoothness;
  b.light_loo_rms = grid.loo_rms;
  b.eigenvalues = eigenvalues;
  const int nodes = res * res;
  b.stored.resize(static_cast<size_t>(k + 1) * nodes * 3);
  b.values.resize(b.stored.size());
  b.range.assign(k, 1);
  for (int p = 0; p <= k; ++p) {
    double peak = 0;
    if (p > 0) {
      for (int n = 0; n < nodes; ++n)
        for (int c = 0; c < 3; ++c) peak = std::max(peak, std::abs(grid.grid(n, p * 3 + c)));
      b.range[p - 1] = peak > 0 ? 127.0 / peak : 1.0;
    }
    for (int n = 0; n < nodes; ++n) {
      for (int c = 0; c < 3; ++c) {
        const size_t i = (static_cast<size_t>(p) * nodes + n) * 3 + c;
        const double g = grid.grid(n, p * 3 + c);
        if (p == 0) {
          b.stored[i] = std::clamp(static_cast<int>(std::lround(g)), 0, 255);
          b.values[i] = b.stored[i];
        } else {
          b.stored[i] = std::clamp(static_cast<int>(std::lround(127 + b.range[p - 1] * g)), 0, 254);
          b.values[i] = (b.stored[i] - 127) / b.range[p - 1];
        }
      }
    }
  }

  return b;
}

PcaCoefficientSolver::PcaCoefficientSolver(const PcaBasis& b, const std::vector<Vec3>& directions,
                                           const PcaOptions& o)
    : dim_(static_cast<int>(directions.size()) * 3),
      k_(b.components),
      mode_(o.mask),
      thresholds_(o.thresholds) {
  const int lights = static_cast<int>(directions.size());
  // 4. The design at the sampled lights through the stored basis, and its projector.
  a_.resize(dim_, k_);
  Eigen::VectorXd mu(dim_);
  {
    std::vector<double> at(static_cast<size_t>(k_ + 1) * 3);
    for (int l = 0; l < lights; ++l) {
      b.Evaluate(directions[l], at.data());
      for (int c = 0; c < 3; ++c) {
        mu(l * 3 + c) = at[c];
        for (int p = 0; p < k_; ++p) a_(l * 3 + c, p) = at[(p + 1) * 3 + c];
      }
    }
  }
  ata_ = a_.transpose() * a_;
  const Eigen::LDLT<Eigen::MatrixXd> ata_ldlt(ata_);
  proj_ = ata_ldlt.solve(a_.transpose()).cast<float>();  // k × dim
  muf_ = mu.cast<float>();
  af_ = a_.cast<float>();
}

// Coefficients of a block of pixels, masked samples fitted around.
void PcaCoefficientSolver::Solve(const uint8_t* values, size_t count, Eigen::MatrixXf* out,
                                 size_t* n_masked, size_t* n_refit) const {
  const int dim = dim_, k = k_;
  const Eigen::MatrixXd& a = a_;
  const Eigen::MatrixXf& proj = proj_;
  const Eigen::VectorXf& muf = muf_;
  const Eigen::MatrixXf& af = af_;
  const bool masked = mode_ != PcaMaskMode::kNone;
  const int black = thresholds_.black_max, clipped = thresholds_.clipped_min;
  Eigen::MatrixXf y(dim, static_cast<Eigen::Index>(count));
  for (size_t i = 0; i < count; ++i) {
    const uint8_t* v = values + i * dim;
    for (int d = 0; d < dim; ++d) y(d, static_cast<Eigen::Index>(i)) = v[d] - muf(d);
  }
  *out = proj * y;  // k × count
  if (!masked) return;
  size_t local_masked = 0, local_refit = 0;
  std::vector<int> drop;
  Eigen::VectorXf pred(dim);
  for (size_t i = 0; i < count; ++i) {
    const uint8_t* v = values + i * dim;
    drop.clear();
    bool any = false;
    for (int d = 0; d < dim; ++d) {
      if (v[d] > black && v[d] < clipped) continue;
      if (!any && mode_ == PcaMaskMode::kHinge) pred.noalias() = af * out->col(static_cast<Eigen::Index>(i));
      any = true;
      ++local_masked;
      // Hinge: a clipped sample is left out where the fit already reaches it, a black one
      // where the fit is already below it; elsewhere it pulls the fit towards its value.
      const float p = muf(d) + (mode_ == PcaMaskMode::kHinge ? pred(d) : 0.0f);
      if (mode_ == PcaMaskMode::kDrop || (v[d] >= clipped && p >= v[d]) ||
          (v[d] <= black && p <= v[d]))
        drop.push_back(d);
    }
    if (!any || drop.empty() || static_cast<int>(drop.size()) > dim - 2 * k) continue;
    Eigen::MatrixXd g = ata_;
    Eigen::VectorXd rhs = a.transpose() * y.col(static_cast<Eigen::Index>(i)).cast<double>();
    for (int d : drop) {
      g.noalias() -= a.row(d).transpose() * a.row(d);
      rhs.noalias() -= a.row(d).transpose() * static_cast<double>(y(d, static_cast<Eigen::Index>(i)));
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(g);
    // Too few samples left to hold every component: keep the unmasked solution.
    if (llt.info() != Eigen::Success) continue;
    const auto diag = llt.matrixLLT().diagonal();
    if (!(diag.minCoeff() > 1e-4 * diag.maxCoeff())) continue;
    out->col(static_cast<Eigen::Index>(i)) = llt.solve(rhs).cast<float>();
    ++local_refit;
  }
  *n_masked += local_masked;
  *n_refit += local_refit;
}

std::vector<std::pair<size_t, size_t>> PcaCoefficientBlocks(size_t pixels, int threads) {
  // ParallelFor's chunks, each cut into blocks of 2048 from its start.
  const size_t block = 2048;
  std::vector<std::pair<size_t, size_t>> out;
  threads = std::max(1, std::min<int>(threads, static_cast<int>((pixels + 4095) / 4096)));
  const size_t chunk = threads == 1 ? pixels : (pixels + threads - 1) / threads;
  for (int t = 0; t < threads; ++t) {
    const size_t lo = t * chunk, hi = std::min(pixels, lo + chunk);
    for (size_t start = lo; start < hi; start += block)
      out.emplace_back(start, std::min(block, hi - start));
  }
  return out;
}

std::vector<PlaneQuantisation> PcaQuantisation(const Eigen::MatrixXf& sampled, double quantile) {
  return Ranges(sampled, quantile);
}

void QuantisePcaPlane(const Eigen::MatrixXf& coeffs, int p, const PlaneQuantisation& q,
                      uint8_t* dst) {
  const float inv = static_cast<float>(255.0 / (q.max - q.min));
  const float lo_v = static_cast<float>(q.min);
  const Eigen::Index n = coeffs.cols();
  for (Eigen::Index i = 0; i < n; ++i) {
    const float v = std::nearbyint((coeffs(p, i) - lo_v) * inv);
    dst[i] = static_cast<uint8_t>(std::clamp(v, 0.0f, 255.0f));
  }
}

Result<PcaModel> FitPcaCoefficients(const LightSamples& samples, PcaBasis basis,
                                    const PcaOptions& o, const std::vector<size_t>& subset,
                                    PcaFitStats* stats) {
  const auto t0 = Clock::now();
  const size_t pixels = samples.pixels();
  const size_t dim = static_cast<size_t>(samples.lights()) * 3;
  const int k = basis.components;
  PcaModel model;
  model.width_ = samples.width;
  model.height_ = samples.height;
  model.jpeg_quality_ = o.jpeg_quality;
  model.lights_ = samples.directions;
  model.basis_ = std::move(basis);
  const PcaCoefficientSolver solver(model.basis_, samples.directions, o);

  // 5. Every pixel's coefficients; ranges from the sampled pixels' quantiles; quantised.
  std::atomic<size_t> n_masked{0}, n_refit{0};
  Eigen::MatrixXf coeffs(k, static_cast<Eigen::Index>(pixels));
  const auto blocks = PcaCoefficientBlocks(pixels, o.threads);
  // The blocks of each of ParallelFor's chunks, solved on that chunk's thread.
  ParallelFor(pixels, o.threads, [&](size_t lo, size_t hi) {
    Eigen::MatrixXf part;
    size_t local_masked = 0, local_refit = 0;
    for (const auto& [start, count] : blocks) {
      if (start < lo || start >= hi) continue;
      solver.Solve(samples.values.data() + start * dim, count, &part, &local_masked, &local_refit);
      coeffs.middleCols(static_cast<Eigen::Index>(start), static_cast<Eigen::Index>(count)) = part;
    }
    n_masked += local_masked;
    n_refit += local_refit;
  });
  {
    Eigen::MatrixXf sampled(static_cast<Eigen::Index>(subset.size()), k);
    for (size_t i = 0; i < subset.size(); ++i)
      sampled.row(static_cast<Eigen::Index>(i)) = coeffs.col(static_cast<Eigen::Index>(subset[i])).transpose();
    model.quant_ = Ranges(sampled, o.quantile);
  }
  model.planes_.resize(k);
  for (int p = 0; p < k; ++p) {
    model.planes_[p] = cv::Mat(samples.height, samples.width, CV_8U);
    QuantisePcaPlane(coeffs, p, model.quant_[p], model.planes_[p].ptr<uint8_t>());
  }
  if (stats) {
    stats->masked_samples = n_masked;
    stats->refitted_pixels = n_refit;
    stats->time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  }
  return model;
}

cv::Mat PcaModel::Render(const Vec3& direction) const {
  const int k = basis_.components;
  std::vector<double> at(static_cast<size_t>(k + 1) * 3);
  basis_.Evaluate(direction, at.data());
  if (ycc()) {
    // mycc (Rti::render): plane p < 3·nc feeds only its own channel p mod 3 of (Y, Co, Cg),
    // a later plane only Y; the sum is then YCoCg → RGB (Color3::toRgb), linear, so it is
    // folded into the weights: R = Y + Co/2 − Cg/2, G = Y + Cg/2, B = Y − Co/2 − Cg/2.
    const int interleaved = 3 * ycc_planes_[1];
    for (int p = 0; p < k; ++p)
      for (int c = 0; c < 3; ++c) {
        const bool feeds = p < interleaved ? c == p % 3 : c == 0;
        if (!feeds) at[(p + 1) * 3 + c] = 0;
      }
    for (int p = 0; p <= k; ++p) {
      double* v = &at[p * 3];
      const double y = v[0], co = v[1], cg = v[2];
      v[0] = y + co / 2 - cg / 2;
      v[1] = y + cg / 2;
      v[2] = y - co / 2 - cg / 2;
    }
  }
  // out_c = B0c + Σ_p (byte_p·scale_p + min_p)·B_pc = base_c + Σ_p byte_p·s_pc
  float base[3], s[64][3];
  for (int c = 0; c < 3; ++c) {
    double v = at[c];
    for (int p = 0; p < k; ++p) {
      v += quant_[p].min * at[(p + 1) * 3 + c];
      s[p][c] = static_cast<float>(quant_[p].scale() * at[(p + 1) * 3 + c] / 255.0);
    }
    base[c] = static_cast<float>(v / 255.0);
  }
  cv::Mat out(height_, width_, CV_32FC3);
  const size_t n = static_cast<size_t>(width_) * height_;
  float* o = out.ptr<float>();
  for (size_t i = 0; i < n; ++i) {
    float r = base[0], g = base[1], bl = base[2];
    for (int p = 0; p < k; ++p) {
      const float byte = planes_[p].ptr<uint8_t>()[i];
      r += byte * s[p][0];
      g += byte * s[p][1];
      bl += byte * s[p][2];
    }
    o[i * 3 + 0] = bl;
    o[i * 3 + 1] = g;
    o[i * 3 + 2] = r;
  }
  return out;
}

cv::Mat PcaModel::PlaneFile(int j) const {
  const int k = basis_.components;
  cv::Mat rgb(height_, width_, CV_8UC3, cv::Scalar(0, 0, 0));
  for (int c = 0; c < 3; ++c) {
    const int p = 3 * j + c;
    if (p >= k) continue;
    const uint8_t* src = planes_[p].ptr<uint8_t>();
    uint8_t* dst = rgb.ptr<uint8_t>();
    const size_t n = static_cast<size_t>(width_) * height_;
    for (size_t i = 0; i < n; ++i) dst[i * 3 + c] = src[i];
  }
  return rgb;
}

Status PcaModel::Save(const std::string& folder) const {
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec) return MakeError(ErrorCode::kIo, folder, "cannot create the folder: {}", ec.message());
  const int files = (basis_.components + 2) / 3;
  for (int j = 0; j < files; ++j) {
    RIG_TRY(WriteJpeg((fs::path(folder) / fmt::format("plane_{}.jpg", j)).string(), PlaneFile(j),
                      kPcaPlaneColor, jpeg_quality_));
  }
  return WritePcaInfo(folder, width_, height_, basis_, quant_, lights_, jpeg_quality_, near_lamp_,
                      hdr_, ycc_planes_);
}

std::string PcaModel::relight_type() const {
  return std::string(ycc() ? "y" : "") + (basis_.rbf() ? "rbf" : "bilinear");
}

namespace {

nlohmann::ordered_json HdrValuesJson(const PcaHdrValues& v) {
  const auto& f = v.light_frame;
  return {{"encoding", HdrCurveName(v.curve.curve)},
          {"max", v.curve.max},
          {"floor", v.curve.floor},
          {"gamma", v.curve.gamma},
          {"lamp_radiance_rgb", v.lamp_radiance_rgb},
          {"light_frame",
           {{"h_offset_deg", f.h_offset_deg},
            {"v_offset_deg", f.v_offset_deg},
            {"h_sign", f.h_sign},
            {"v_sign", f.v_sign},
            {"lamp_distance_mm", f.lamp_distance_mm},
            {"field_height_mm", f.field_height_mm},
            {"surface_depth_mm", f.surface_depth_mm}}}};
}

// rig.values back; errors name the file.
Result<PcaHdrValues> HdrValuesFromJson(const nlohmann::json& j, const std::string& path) {
  PcaHdrValues v;
  auto curve = ParseHdrCurve(j.at("encoding").get<std::string>());
  if (!curve.ok()) return MakeError(ErrorCode::kInvalidInput, path, "rig.values: {}", curve.error().ToString());
  v.curve.curve = *curve;
  v.curve.max = j.at("max").get<double>();
  v.curve.floor = j.at("floor").get<double>();
  v.curve.gamma = j.value("gamma", 1.0);
  v.lamp_radiance_rgb = j.at("lamp_radiance_rgb").get<std::array<double, 3>>();
  const auto& f = j.at("light_frame");
  v.light_frame.h_offset_deg = f.at("h_offset_deg").get<double>();
  v.light_frame.v_offset_deg = f.at("v_offset_deg").get<double>();
  RIG_ASSIGN_OR_RETURN(v.light_frame.h_sign, JsonIntegerIn(f.at("h_sign"), -1, 1, path, "rig.values.light_frame.h_sign"));
  RIG_ASSIGN_OR_RETURN(v.light_frame.v_sign, JsonIntegerIn(f.at("v_sign"), -1, 1, path, "rig.values.light_frame.v_sign"));
  v.light_frame.lamp_distance_mm = f.value("lamp_distance_mm", 0.0);
  v.light_frame.field_height_mm = f.value("field_height_mm", 0.0);
  v.light_frame.surface_depth_mm = f.value("surface_depth_mm", 0.0);
  const bool lamp_ok = std::all_of(v.lamp_radiance_rgb.begin(), v.lamp_radiance_rgb.end(),
                                   [](double e) { return std::isfinite(e) && e > 0; });
  if (!(std::isfinite(v.curve.max) && v.curve.max > 0 && std::isfinite(v.curve.floor) &&
        std::isfinite(v.curve.gamma) && v.curve.gamma >= 0.25 && v.curve.gamma <= 4 &&
        v.curve.floor > 0 && v.curve.floor <= v.curve.max) || !lamp_ok ||
      std::abs(v.light_frame.h_sign) != 1 || std::abs(v.light_frame.v_sign) != 1) {
    return MakeError(ErrorCode::kInvalidInput, path,
                     "rig.values: max {} floor {} (0 < floor <= max), lamp radiance positive, "
                     "signs 1 or -1 needed", v.curve.max, v.curve.floor);
  }
  return v;
}

}  // namespace

std::string PcaInfoText(int width, int height, const PcaBasis& basis,
                        const std::vector<PlaneQuantisation>& quant,
                        const std::vector<Vec3>& lights, int jpeg_quality,
                        const std::string& near_lamp, const std::optional<PcaHdrValues>& hdr,
                        const std::array<int, 3>& ycc = {0, 0, 0}) {
  const int k = basis.components;
  nlohmann::ordered_json info;
  info["width"] = width;
  info["height"] = height;
  info["format"] = "jpg";
  info["type"] = basis.rbf() ? "rbf" : "bilinear";
  if (!basis.rbf()) info["resolution"] = basis.resolution;
  info["colorspace"] = ycc[0] > 0 ? "mycc" : "mrgb";
  if (basis.rbf()) info["sigma"] = basis.sigma;
  std::vector<double> flat;
  // An rbf basis is held at its own lights (exactly as read): those are the ones written.
  for (const auto& l : basis.rbf() ? basis.rbf_lights : lights) {
    for (double v : l) flat.push_back(basis.rbf() ? v : std::round(v * 1000) / 1000);
  }
  info["lights"] = flat;
  if (ycc[0] > 0)
    info["yccplanes"] = ycc;
  else
    info["nplanes"] = k;
  info["quality"] = jpeg_quality;
  info["colorprofile"] = "sRGB";
  info["basis"] = basis.stored;
  nlohmann::ordered_json material;
  std::vector<double> scale, bias, range;
  for (int p = 0; p < k; ++p) {
    scale.push_back(quant[p].scale());
    bias.push_back(quant[p].bias());
    range.push_back(basis.range[p]);
  }
  material["scale"] = scale;
  material["bias"] = bias;
  material["range"] = range;
  info["materials"] = nlohmann::ordered_json::array({material});
  // Ours, ignored by relight's readers: what produced the model.
  info["rig"] = {{"family", basis.rbf() ? "pca-rbf" : "pca-bilinear"},
                 {"prior", basis.prior == GridPrior::kBending ? "bending" : "membrane"},
                 {"smoothness", basis.smoothness},
                 {"light_loo_rms", basis.light_loo_rms},
                 {"eigenvalues", basis.eigenvalues}};
  if (!near_lamp.empty()) info["rig"]["near_lamp"] = near_lamp;
  if (hdr) info["rig"]["values"] = HdrValuesJson(*hdr);
  return info.dump() + "\n";
}

Status WritePcaInfo(const std::string& folder, int width, int height, const PcaBasis& basis,
                    const std::vector<PlaneQuantisation>& quant,
                    const std::vector<Vec3>& lights, int jpeg_quality,
                    const std::string& near_lamp,
                    const std::optional<PcaHdrValues>& hdr, const std::array<int, 3>& ycc) {
  std::error_code ec;
  const fs::path path = fs::path(folder) / "info.json";
  RIG_TRY(WriteFileAtomic(path, PcaInfoText(width, height, basis, quant, lights, jpeg_quality,
                                            near_lamp, hdr, ycc)));
  // Planes of an earlier, larger model in the same folder would be counted as its bytes
  // and confuse a reader that lists files: this model's are plane_0 .. plane_{files-1}.
  for (int n = (basis.components + 2) / 3;; ++n) {
    const fs::path stale = fs::path(folder) / fmt::format("plane_{}.jpg", n);
    if (!fs::exists(stale, ec)) break;
    fs::remove(stale, ec);
    if (ec) return MakeError(ErrorCode::kIo, stale.string(), "cannot remove: {}", ec.message());
  }
  return Ok();
}

namespace {

// Every plane's byte count and header against info.json's size, before any is decoded.
Status CheckPlaneHeaders(const std::string& folder, int files, int width, int height) {
  for (int j = 0; j < files; ++j) {
    const std::string plane = (fs::path(folder) / fmt::format("plane_{}.jpg", j)).string();
    std::error_code ec;
    const uint64_t bytes = fs::file_size(plane, ec);
    if (ec) return MakeError(ErrorCode::kNotFound, plane, "cannot open: {}", ec.message());
    if (bytes < MinJpegBytes(width, height)) {
      return MakeError(ErrorCode::kInvalidInput, plane,
                       "{} bytes cannot hold a {}x{} JPEG: the size info.json declares is not the file's",
                       bytes, width, height);
    }
    RIG_ASSIGN_OR_RETURN(auto reader, JpegReader::Open(plane));
    if (reader->width() != width || reader->height() != height || reader->channels() != 3) {
      return MakeError(ErrorCode::kInvalidInput, plane, "{}x{}x{}, info.json says {}x{}x3",
                       reader->width(), reader->height(), reader->channels(), width, height);
    }
  }
  return Ok();
}


}  // namespace

Result<PcaModel> PcaModel::FromInfo(const nlohmann::json& info, const std::string& path) {
  PcaModel m;
  try {
    const std::string type = info.at("type").get<std::string>();
    const std::string space = info.at("colorspace").get<std::string>();
    if ((type != "bilinear" && type != "rbf") || (space != "mrgb" && space != "mycc")) {
      return MakeError(ErrorCode::kInvalidInput, path,
                       "type '{}' colorspace '{}' is not read here: rig reads relight's {}", type,
                       space, kRelightTypesRead);
    }
    const bool rbf = type == "rbf";
    RIG_ASSIGN_OR_RETURN(m.width_, JsonIntegerIn(info.at("width"), 1, 65500, path, "width"));
    RIG_ASSIGN_OR_RETURN(m.height_, JsonIntegerIn(info.at("height"), 1, 65500, path, "height"));
    int k = 0;
    if (space == "mycc") {
      // [ny, nc, nc]: ny ≥ nc planes of Y, nc of each chroma channel (RtiBuilder::pickBasePCA)
      const auto& y = info.at("yccplanes");
      if (!y.is_array() || y.size() != 3)
        return MakeError(ErrorCode::kInvalidInput, path, "yccplanes: 3 numbers expected");
      for (int i = 0; i < 3; ++i) {
        RIG_ASSIGN_OR_RETURN(m.ycc_planes_[i], JsonIntegerIn(y[i], i == 0 ? 1 : 0, 64, path,
                                                            fmt::format("yccplanes[{}]", i)));
      }
      if (m.ycc_planes_[1] != m.ycc_planes_[2] || m.ycc_planes_[1] > m.ycc_planes_[0]) {
        return MakeError(ErrorCode::kInvalidInput, path,
                         "yccplanes: [{}, {}, {}], [ny, nc, nc] with nc <= ny expected",
                         m.ycc_planes_[0], m.ycc_planes_[1], m.ycc_planes_[2]);
      }
      k = m.ycc_planes_[0] + 2 * m.ycc_planes_[1];
      if (k > 64) return MakeError(ErrorCode::kInvalidInput, path, "yccplanes: {} planes, at most 64", k);
    } else {
      RIG_ASSIGN_OR_RETURN(k, JsonIntegerIn(info.at("nplanes"), 1, 64, path, "nplanes"));
    }
    int res = 0;
    PcaBasis& b = m.basis_;
    if (rbf) {
      // Rti::load: sigma and the lights the basis is held at (the rbf's nodes).
      RIG_ASSIGN_OR_RETURN(b.sigma, JsonNumber(info.at("sigma"), path, "sigma"));
      if (!(b.sigma > 1e-3 && b.sigma <= 100))
        return MakeError(ErrorCode::kInvalidInput, path, "sigma: {} outside (0.001, 100]", b.sigma);
      const auto& l = info.at("lights");
      if (!l.is_array() || l.empty() || l.size() % 3 != 0 || l.size() > 3 * 4096) {
        return MakeError(ErrorCode::kInvalidInput, path,
                         "lights: {} numbers, 3 per light (1..4096 lights) expected for type rbf",
                         l.is_array() ? l.size() : 0);
      }
      for (size_t i = 0; i < l.size(); i += 3) {
        Vec3 v;
        for (int c = 0; c < 3; ++c) {
          RIG_ASSIGN_OR_RETURN(v[c], JsonNumber(l[i + c], path, fmt::format("lights[{}]", i + c)));
          if (std::abs(v[c]) > 2)
            return MakeError(ErrorCode::kInvalidInput, path, "lights[{}]: {} is no direction", i + c, v[c]);
        }
        b.rbf_lights.push_back(v);
      }
    } else {
      RIG_ASSIGN_OR_RETURN(res, JsonIntegerIn(info.at("resolution"), 2, 64, path, "resolution"));
    }
    m.jpeg_quality_ = 95;
    if (info.contains("quality")) {
      RIG_ASSIGN_OR_RETURN(m.jpeg_quality_, JsonIntegerIn(info.at("quality"), 1, 100, path, "quality"));
    }
    b.components = k;
    b.resolution = res;
    const auto& basis = info.at("basis");
    const size_t want = static_cast<size_t>(k + 1) * b.nodes() * 3;
    if (!basis.is_array() || basis.size() != want) {
      return MakeError(ErrorCode::kInvalidInput, path, "'basis' has {} values, {} expected",
                       basis.is_array() ? basis.size() : 0, want);
    }
    b.stored.reserve(want);
    for (size_t i = 0; i < want; ++i) {
      RIG_ASSIGN_OR_RETURN(int v, JsonIntegerIn(basis[i], 0, 255, path, fmt::format("basis[{}]", i)));
      b.stored.push_back(v);
    }
    const auto& mat = info.at("materials").at(0);
    const auto scale = mat.at("scale").get<std::vector<double>>();
    const auto bias = mat.at("bias").get<std::vector<double>>();
    b.range = mat.at("range").get<std::vector<double>>();
    if (scale.size() != static_cast<size_t>(k) || bias.size() != scale.size() ||
        b.range.size() != scale.size()) {
      return MakeError(ErrorCode::kInvalidInput, path,
                       "materials: scale/bias/range sizes {} {} {} for {} planes", scale.size(),
                       bias.size(), b.range.size(), k);
    }
    for (int p = 0; p < k; ++p) {
      RIG_TRY(CheckFloatValue(scale[p], path, fmt::format("materials[0].scale[{}]", p)));
      RIG_TRY(CheckFloatValue(bias[p], path, fmt::format("materials[0].bias[{}]", p)));
      RIG_TRY(CheckFloatValue(b.range[p], path, fmt::format("materials[0].range[{}]", p)));
      if (b.range[p] == 0)
        return MakeError(ErrorCode::kInvalidInput, path, "materials[0].range[{}]: 0", p);
      RIG_TRY(CheckDequantisation(scale[p], -255.0 * bias[p] * scale[p], path,
                                  fmt::format("materials[0].scale[{}], bias[{}]", p, p)));
      // c = 255·(byte/255 − bias)·scale = byte·scale − 255·bias·scale
      PlaneQuantisation q;
      q.min = -255.0 * bias[p] * scale[p];
      q.max = q.min + 255.0 * scale[p];
      m.quant_.push_back(q);
    }
    b.values.resize(want);
    const int nodes = b.nodes();
    for (size_t i = 0; i < want; ++i) {
      const int p = static_cast<int>(i / (static_cast<size_t>(nodes) * 3));
      b.values[i] = p == 0 ? b.stored[i] : (b.stored[i] - 127) / b.range[p - 1];
    }
    if (info.contains("lights")) {
      const auto l = info.at("lights").get<std::vector<double>>();
      for (size_t i = 0; i + 2 < l.size(); i += 3) m.lights_.push_back({l[i], l[i + 1], l[i + 2]});
    }
    if (info.contains("rig")) {
      const auto& r = info.at("rig");
      b.prior = r.value("prior", std::string("bending")) == "membrane" ? GridPrior::kMembrane
                                                                      : GridPrior::kBending;
      b.smoothness = r.value("smoothness", 0.0);
      b.light_loo_rms = r.value("light_loo_rms", 0.0);
      if (r.contains("eigenvalues")) b.eigenvalues = r.at("eigenvalues").get<std::vector<double>>();
      m.near_lamp_ = r.value("near_lamp", std::string());
      if (r.contains("values")) {
        RIG_ASSIGN_OR_RETURN(PcaHdrValues v, HdrValuesFromJson(r.at("values"), path));
        m.hdr_ = v;
      }
    }
  } catch (const nlohmann::json::exception& e) {
    return MakeError(ErrorCode::kInvalidInput, path, "{}", e.what());
  }
  return m;
}

Status PcaModel::AddPlaneFile(const cv::Mat& rgb, const std::string& plane) {
  if (rgb.cols != width_ || rgb.rows != height_ || rgb.channels() != 3) {
    return MakeError(ErrorCode::kInvalidInput, plane, "{}x{}x{}, info.json says {}x{}x3", rgb.cols,
                     rgb.rows, rgb.channels(), width_, height_);
  }
  const int k = basis_.components;
  const int first = static_cast<int>(planes_.size());
  cv::Mat ch[3];
  cv::split(rgb, ch);
  for (int c = 0; c < 3 && first + c < k; ++c) planes_.push_back(ch[c].clone());
  return Ok();
}

Result<PcaModel> PcaModel::Load(const std::string& folder) {
  const std::string path = (fs::path(folder) / "info.json").string();
  RIG_ASSIGN_OR_RETURN(nlohmann::json info, ReadJsonObjectFile(path));
  RIG_ASSIGN_OR_RETURN(PcaModel m, FromInfo(info, path));
  const int k = m.basis_.components;
  RIG_TRY(CheckPlaneHeaders(folder, (k + 2) / 3, m.width_, m.height_));
  for (int j = 0; j < (k + 2) / 3; ++j) {
    const std::string plane = (fs::path(folder) / fmt::format("plane_{}.jpg", j)).string();
    RIG_ASSIGN_OR_RETURN(cv::Mat rgb, ReadJpeg(plane));
    RIG_TRY(m.AddPlaneFile(rgb, plane));
  }
  return m;
}

Result<PcaModel> PcaModel::AsStored(uint64_t* bytes) const {
  const std::string text =
      PcaInfoText(width_, height_, basis_, quant_, lights_, jpeg_quality_, near_lamp_, hdr_,
                  ycc_planes_);
  nlohmann::json info;
  try {
    info = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    return MakeError(ErrorCode::kInternal, "pca info.json", "{}", e.what());
  }
  RIG_ASSIGN_OR_RETURN(PcaModel m, FromInfo(info, "info.json"));
  uint64_t total = text.size();
  for (int j = 0; j < (basis_.components + 2) / 3; ++j) {
    RIG_ASSIGN_OR_RETURN(auto encoded, EncodeJpeg(PlaneFile(j), kPcaPlaneColor, jpeg_quality_));
    total += encoded.size();
    const std::string name = fmt::format("plane_{}.jpg", j);
    RIG_ASSIGN_OR_RETURN(cv::Mat rgb, DecodeJpeg(encoded, name));
    RIG_TRY(m.AddPlaneFile(rgb, name));
  }
  if (bytes != nullptr) *bytes = total;
  return m;
}

PcaBasis TruncatePcaBasis(const PcaBasis& basis, int k) {
  PcaBasis b = basis;
  k = std::clamp(k, 1, basis.components);
  const size_t n = static_cast<size_t>(k + 1) * basis.nodes() * 3;
  b.components = k;
  b.stored.resize(n);
  b.values.resize(n);
  b.range.resize(k);
  b.eigenvalues.resize(std::min<size_t>(b.eigenvalues.size(), k));
  return b;
}

uint64_t FolderBytes(const std::string& folder) {
  uint64_t total = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(folder, ec)) {
    if (e.is_regular_file(ec)) total += e.file_size(ec);
  }
  return total;
}

namespace {

class PcaFamily final : public ReflectanceModel {
 public:
  explicit PcaFamily(PcaModel m) : m_(std::move(m)) {
    spacing_deg_ = m_.lights().empty() ? 0 : SampleSpacingDeg(m_.lights());
    if (m_.hdr()) frame_ = m_.hdr()->light_frame;
  }
  std::string family() const override { return "pca-" + m_.relight_type(); }
  std::string Describe() const override {
    const auto& b = m_.basis();
    const std::string planes =
        m_.ycc() ? fmt::format("{} planes of Y, {} of each of Co and Cg (mycc)", m_.ycc_planes()[0],
                               m_.ycc_planes()[1])
                 : fmt::format("{} components", b.components);
    const std::string lights =
        b.rbf() ? fmt::format("Gaussians of width {:.3g} around {} lights (relight's rbf)", b.sigma,
                              b.rbf_lights.size())
                : fmt::format("{}x{} octahedral grid ({} prior, strength {:.3g})", b.resolution,
                              b.resolution, b.prior == GridPrior::kBending ? "bending" : "membrane",
                              b.smoothness);
    return fmt::format("{}: {}, {}, 8-bit planes, JPEG q{}", family(), planes, lights,
                       m_.jpeg_quality()) +
           (m_.hdr() ? fmt::format(", reflectance of radiance maps through a {} curve up to {:.4g}",
                                   HdrCurveName(m_.hdr()->curve.curve), m_.hdr()->curve.max)
                     : std::string());
  }
  int width() const override { return m_.width(); }
  int height() const override { return m_.height(); }
  ValueEncoding encoding() const override {
    return m_.hdr() ? ValueEncoding::kLinear : ValueEncoding::kSrgb;
  }
  const LightFrameConfig& light_frame() const override { return frame_; }
  std::array<double, 3> lamp_radiance_rgb() const override {
    return m_.hdr() ? m_.hdr()->lamp_radiance_rgb : std::array<double, 3>{1, 1, 1};
  }
  cv::Mat EvaluateRho(const Vec3& d) const override {
    cv::Mat v = m_.Render(d);
    float* p = v.ptr<float>();
    const size_t n = v.total() * 3;
    if (m_.hdr()) {
      // Codes below 0 (a model's undershoot) are no reflectance: ρ is 0 there, never negative.
      const HdrCodeCurve& c = m_.hdr()->curve;
      for (size_t i = 0; i < n; ++i) p[i] = static_cast<float>(c.Decode(std::max(0.0f, p[i]) * 255.0));
    } else {
      for (size_t i = 0; i < n; ++i) p[i] = SrgbDecode(p[i]);
    }
    return v;
  }
  cv::Mat EvaluateEncoded(const Vec3& d) const override {
    return m_.hdr() ? EvaluateRho(d) : m_.Render(d);  // a photographs' model holds code values
  }
  RegionCheck CheckRegion(const Vec3& d) const override {
    return CheckAgainstLamps(m_.lights(), spacing_deg_, d);
  }
  std::vector<Vec3> fitted_lights() const override { return m_.lights(); }
  Status Save(const std::string& path) const override { return m_.Save(path); }

 private:
  PcaModel m_;
  LightFrameConfig frame_;
  double spacing_deg_ = 0;
};

}  // namespace

std::unique_ptr<ReflectanceModel> WrapPca(PcaModel model) {
  return std::make_unique<PcaFamily>(std::move(model));
}

}  // namespace rig
