// Debevec-Malik response recovery (Schur-reduced normal equations) and the table-driven merge.
#include "process/hdr/hdr.h"
#include "config/atomic_file.h"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <sstream>

#include <immintrin.h>

#include <Eigen/Dense>
#include <opencv2/core.hpp>

#include "config/log.h"

namespace rig {
namespace {

// Accumulates one 8-bit frame row into the row sums: den[k] += w_c(z_k), num[k] += wg_c(z_k)
// with c = k % 3 (BGR interleaved), through split tables w[c * 256 + z], wg[c * 256 + z].
// Scalar; the AVX2 version below does the same with gathers, 24 samples at a time.
void AccumulateRow8(const uint8_t* p, int m, const float* w, const float* wg, float* den, float* num) {
  for (int k = 0; k < m; k += 3) {
    den[k] += w[p[k]], num[k] += wg[p[k]];
    den[k + 1] += w[256 + p[k + 1]], num[k + 1] += wg[256 + p[k + 1]];
    den[k + 2] += w[512 + p[k + 2]], num[k + 2] += wg[512 + p[k + 2]];
  }
}

__attribute__((target("avx2"))) void AccumulateRow8Avx2(const uint8_t* p, int m, const float* w,
                                                        const float* wg, float* den, float* num) {
  // Lane i of vector v (v = 0, 1, 2) holds sample 8v + i of a 24-sample block, channel
  // (8v + i) % 3: its table offset.
  const __m256i off[3] = {_mm256_setr_epi32(0, 256, 512, 0, 256, 512, 0, 256),
                          _mm256_setr_epi32(512, 0, 256, 512, 0, 256, 512, 0),
                          _mm256_setr_epi32(256, 512, 0, 256, 512, 0, 256, 512)};
  int k = 0;
  for (; k + 24 <= m; k += 24) {
    for (int v = 0; v < 3; ++v) {
      const __m128i bytes = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(p + k + 8 * v));
      const __m256i idx = _mm256_add_epi32(_mm256_cvtepu8_epi32(bytes), off[v]);
      const __m256 gw = _mm256_i32gather_ps(w, idx, 4);
      const __m256 gwg = _mm256_i32gather_ps(wg, idx, 4);
      float* d = den + k + 8 * v;
      float* n = num + k + 8 * v;
      _mm256_storeu_ps(d, _mm256_add_ps(_mm256_loadu_ps(d), gw));
      _mm256_storeu_ps(n, _mm256_add_ps(_mm256_loadu_ps(n), gwg));
    }
  }
  AccumulateRow8(p + k, m - k, w, wg, den + k, num + k);
}


namespace fs = std::filesystem;

constexpr int kBins = 256;  // recovery resolution (16-bit input is binned by z >> 8)

int LevelsOf(const cv::Mat& m) { return m.depth() == CV_16U ? 65536 : 256; }

// The hat weight over [lo, hi]: zero at and beyond both ends, peak in the middle.
inline double Hat(double z, double lo, double hi) {
  if (z <= lo || z >= hi) return 0.0;
  const double mid = 0.5 * (lo + hi);
  return z <= mid ? z - lo : hi - z;
}

// Reads a pixel's level in channel c, in recovery bins (16-bit levels are divided by 256).
inline float BinAt(const cv::Mat& img, int x, int y, int c) {
  if (img.depth() == CV_16U) return img.ptr<uint16_t>(y)[3 * x + c] * (1.0f / 256.0f);
  return img.ptr<uint8_t>(y)[3 * x + c];
}

// Half-size of a sample patch: a sample is the mean level of a (2r+1)^2 patch in a flat part
// of the image, which divides the noise (and the quantisation step) of a single pixel by
// about 2r+1 and gives a fractional level.
constexpr int kPatchRadius = 2;

// One sample: a patch's mean level in one channel for every frame of its bracket (negative:
// the frame does not record the patch, some pixel of it is black or clipped).
struct ResponseSample {
  int bracket = 0, x = 0, y = 0;
  std::vector<float> z;
};

// Mean level of the patch around (x, y) in channel c, or -1 if any pixel is at either end;
// `grad` receives the patch's gradient (difference of opposite half-patch means, in levels).
float PatchMean(const cv::Mat& img, int x, int y, int c, float* grad) {
  const float top = kBins - 1;
  float sum = 0, left = 0, right = 0, up = 0, down = 0;
  for (int dy = -kPatchRadius; dy <= kPatchRadius; ++dy) {
    for (int dx = -kPatchRadius; dx <= kPatchRadius; ++dx) {
      const float z = BinAt(img, x + dx, y + dy, c);
      if (z <= 0 || z >= top) return -1;
      sum += z;
      if (dx < 0) left += z;
      if (dx > 0) right += z;
      if (dy < 0) up += z;
      if (dy > 0) down += z;
    }
  }
  constexpr float kHalf = kPatchRadius * (2 * kPatchRadius + 1);
  *grad = (std::abs(right - left) + std::abs(down - up)) / kHalf;
  return sum / ((2 * kPatchRadius + 1) * (2 * kPatchRadius + 1));
}

// Chooses sample patches of channel c in one bracket: one candidate per cell of a grid over
// the image (the flattest of a few seeded random positions in the cell, so samples spread
// over the image and are no plain grid); the flatter half is kept (away from edges), and from
// it samples are taken at evenly spaced values of a radiance proxy (the sum of levels over the
// bracket, monotone in radiance), so that they spread over the intensity range.
// Patches recorded by fewer than two frames (the rest black or clipped) say nothing about g.
std::vector<ResponseSample> ChooseSamples(const Bracket& frames, int bracket_index, int c, int wanted,
                                  uint64_t seed) {
  const int w = frames[0].image.cols, h = frames[0].image.rows;
  const int m = kPatchRadius;
  std::vector<ResponseSample> out;
  if (w < 2 * m + 1 || h < 2 * m + 1 || wanted <= 0) return out;
  const int n = static_cast<int>(frames.size());
  const int iw = w - 2 * m, ih = h - 2 * m;  // patch centres lie in [m, w - m)
  // About 8 cells per wanted sample: enough choice per bin, few enough to stay cheap.
  const double cell = std::max(1.0, std::sqrt(double(iw) * ih / (8.0 * wanted)));
  const int cols = std::max(1, int(iw / cell)), rows = std::max(1, int(ih / cell));
  std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ull + bracket_index * 131 + c);
  constexpr int kTries = 4;
  struct Candidate {
    ResponseSample s;
    float gradient;
    float proxy;
  };
  std::vector<Candidate> cands;
  cands.reserve(size_t(cols) * rows);
  std::vector<float> z(n);
  for (int cy = 0; cy < rows; ++cy) {
    for (int cx = 0; cx < cols; ++cx) {
      const int x0 = m + int(int64_t(cx) * iw / cols), x1 = m + int(int64_t(cx + 1) * iw / cols);
      const int y0 = m + int(int64_t(cy) * ih / rows), y1 = m + int(int64_t(cy + 1) * ih / rows);
      Candidate best{{}, 1e30f, 0};
      for (int t = 0; t < kTries; ++t) {
        const int x = x0 + int(rng() % uint64_t(std::max(1, x1 - x0)));
        const int y = y0 + int(rng() % uint64_t(std::max(1, y1 - y0)));
        int recorded = 0;
        float grad_sum = 0, proxy = 0;
        for (int j = 0; j < n; ++j) {
          float g = 0;
          z[j] = PatchMean(frames[j].image, x, y, c, &g);
          if (z[j] >= 0) {
            ++recorded;
            grad_sum += g;
            proxy += z[j];
          } else {
            // Clipped or black: count it at the end it is at, for the radiance proxy.
            proxy += BinAt(frames[j].image, x, y, c) >= kBins / 2 ? kBins - 1 : 0;
          }
        }
        if (recorded < 2) continue;
        const float gradient = grad_sum / recorded;
        if (gradient < best.gradient) best = {{bracket_index, x, y, z}, gradient, proxy};
      }
      if (!best.s.z.empty()) cands.push_back(std::move(best));
    }
  }
  if (cands.empty()) return out;
  // Avoid edges: keep the flatter half of the candidates.
  std::vector<float> grads;
  for (const auto& cd : cands) grads.push_back(cd.gradient);
  std::nth_element(grads.begin(), grads.begin() + grads.size() / 2, grads.end());
  const float max_gradient = grads[grads.size() / 2];
  std::vector<Candidate*> flat;
  for (auto& cd : cands) {
    if (cd.gradient <= max_gradient) flat.push_back(&cd);
  }
  // Spread over radiance: targets evenly spaced in the proxy's value (not its rank, which
  // would follow the image's histogram and take one large flat region many times: samples of
  // few distinct radiances constrain g only on a comb of levels, and it oscillates between).
  std::sort(flat.begin(), flat.end(),
            [](const Candidate* a, const Candidate* b) { return a->proxy < b->proxy; });
  const float lo = flat.front()->proxy, hi = flat.back()->proxy;
  const int take = std::min<int>(wanted, int(flat.size()));
  std::vector<bool> used(flat.size(), false);
  for (int k = 0; k < take; ++k) {
    const float target = lo + (hi - lo) * (k + 0.5f) / take;
    auto it = std::lower_bound(flat.begin(), flat.end(), target,
                               [](const Candidate* a, float v) { return a->proxy < v; });
    // The nearest unused candidate on either side of the target.
    int up = int(it - flat.begin()), down = up - 1;
    while (up < int(flat.size()) && used[up]) ++up;
    while (down >= 0 && used[down]) --down;
    int pick = -1;
    if (up < int(flat.size()) && (down < 0 || flat[up]->proxy - target <= target - flat[down]->proxy)) {
      pick = up;
    } else if (down >= 0) {
      pick = down;
    }
    if (pick < 0) break;
    used[pick] = true;
    out.push_back(std::move(flat[pick]->s));
  }
  return out;
}

// The plain alternative (for comparison): single pixels on a regular grid of about `wanted`
// points, as OpenCV's CalibrateDebevec takes them.
std::vector<ResponseSample> GridSamples(const Bracket& frames, int bracket_index, int c, int wanted) {
  const int w = frames[0].image.cols, h = frames[0].image.rows;
  const int cols = std::max(1, int(std::round(std::sqrt(double(wanted) * w / h))));
  const int rows = std::max(1, (wanted + cols - 1) / cols);
  std::vector<ResponseSample> out;
  for (int r = 0; r < rows; ++r) {
    for (int q = 0; q < cols && int(out.size()) < wanted; ++q) {
      ResponseSample s{bracket_index, int((q + 0.5) * w / cols), int((r + 0.5) * h / rows), {}};
      for (const auto& f : frames) s.z.push_back(BinAt(f.image, s.x, s.y, c));
      out.push_back(std::move(s));
    }
  }
  return out;
}

// Solves the Debevec-Malik least squares for one channel on kBins levels:
//   minimise sum_ij [w(z_ij)(g(z_ij) - ln E_i - ln t_j)]^2 + lambda^2 sum_z [w(z) g''(z)]^2
// with g(mid) = 0, where a fractional level z reads g by linear interpolation. The per-sample
// unknowns ln E_i are eliminated (Schur complement of the normal equations: each is a weighted
// mean of its sample's g(z_ij) - ln t_j), leaving a dense kBins x kBins symmetric positive
// definite system, solved by LDLT.
Result<std::vector<double>> SolveChannel(std::span<const Bracket> brackets,
                                         const std::vector<ResponseSample>& samples, int c,
                                         double lambda) {
  Eigen::MatrixXd s = Eigen::MatrixXd::Zero(kBins, kBins);
  Eigen::VectorXd r = Eigen::VectorXd::Zero(kBins);
  // One data row: weight w, g read at levels lv[0..1] with coefficients cf[0..1].
  struct Row {
    int lv[2];
    double cf[2];
    double w2, lt;
  };
  std::vector<Row> rows;
  int equations = 0;
  double data_weight = 0;  // sum of squared data-row weights
  for (const ResponseSample& smp : samples) {
    const Bracket& frames = brackets[smp.bracket];
    rows.clear();
    double a = 0, b = 0;
    for (size_t j = 0; j < frames.size(); ++j) {
      const double z = smp.z[j];
      const double w = z < 0 ? 0.0 : Hat(z, 0, kBins - 1);
      if (w <= 0) continue;
      const int z0 = std::min(int(z), kBins - 2);
      const double f = z - z0;
      const double w2 = w * w, lt = std::log(frames[j].exposure.count());
      rows.push_back({{z0, z0 + 1}, {1 - f, f}, w2, lt});
      a += w2;
      b += w2 * lt;
    }
    if (rows.size() < 2) continue;
    equations += int(rows.size());
    data_weight += a;
    // Normal equations of this sample's rows w (a_z . g - E) = w lt, with the unknown E:
    //   G += w2 a a^T, C = -sum w2 a, D = sum w2 = a_sum, rhs_g += w2 lt a, rhs_E = -sum w2 lt.
    // Schur complement: S = G - C C^T / D, r = rhs_g - C rhs_E / D.
    for (const Row& p : rows) {
      for (int u = 0; u < 2; ++u) {
        r(p.lv[u]) += p.w2 * p.lt * p.cf[u];
        for (int v = 0; v < 2; ++v) s(p.lv[u], p.lv[v]) += p.w2 * p.cf[u] * p.cf[v];
      }
    }
    for (const Row& p : rows) {
      for (int u = 0; u < 2; ++u) {
        const double cu = p.w2 * p.cf[u];
        r(p.lv[u]) -= cu * b / a;
        for (const Row& q : rows) {
          for (int v = 0; v < 2; ++v) s(p.lv[u], q.lv[v]) -= cu * q.w2 * q.cf[v] / a;
        }
      }
    }
  }
  if (equations < kBins / 2) {
    return MakeError(ErrorCode::kInvalidInput, "",
                     "too few usable samples for response recovery ({} equations in channel "
                     "{}): the brackets need frames that record the same pixels",
                     equations, "BGR"[c]);
  }
  // lambda is relative to the data: the smoothness rows are scaled so that their total
  // squared weight at lambda = 1 equals the data rows' (the paper's absolute lambda makes the
  // curve smoother with fewer samples and rougher with more; this one means the same for any
  // sample count, frame count or bit depth).
  double level_weight = 0;
  for (int z = 1; z < kBins - 1; ++z) level_weight += Hat(z, 0, kBins - 1) * Hat(z, 0, kBins - 1);
  const double scale = data_weight / level_weight;
  for (int z = 1; z < kBins - 1; ++z) {
    const double k = lambda * Hat(z, 0, kBins - 1);
    const double k2 = k * k * scale;
    const int idx[3] = {z - 1, z, z + 1};
    const double v[3] = {1, -2, 1};
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) s(idx[i], idx[j]) += k2 * v[i] * v[j];
    }
  }
  s(kBins / 2, kBins / 2) += 1.0;  // the anchor row g(mid) = 0
  Eigen::LDLT<Eigen::MatrixXd> ldlt(s);
  Eigen::VectorXd g = ldlt.solve(r);
  if (ldlt.info() != Eigen::Success || !g.allFinite()) {
    return MakeError(ErrorCode::kInvalidInput, "",
                     "the response system of channel {} is singular", "BGR"[c]);
  }
  const double anchor = g(kBins / 2);  // exactly 0 up to round-off; remove it anyway
  std::vector<double> out(kBins);
  for (int z = 0; z < kBins; ++z) out[z] = g(z) - anchor;
  return out;
}

// Expands a kBins curve to 65536 levels by linear interpolation between bin centres.
std::vector<double> ExpandBins(const std::vector<double>& g) {
  std::vector<double> out(65536);
  for (int z = 0; z < 65536; ++z) {
    const double pos = (z - 127.5) / 256.0;
    const int b0 = std::clamp(int(std::floor(pos)), 0, kBins - 2);
    const double f = pos - b0;
    out[z] = g[b0] * (1 - f) + g[b0 + 1] * f;
  }
  const double anchor = out[32768];
  for (double& v : out) v -= anchor;
  return out;
}

std::string FormatExposures(std::span<const LdrFrame> frames) {
  std::string s;
  for (const auto& f : frames) {
    if (!s.empty()) s += ' ';
    s += fmt::format("{:.9g}", f.exposure.count());
  }
  return s;
}

Status WriteTextAtomically(const std::string& path, const std::string& text) {
  return WriteFileAtomic(path, text);
}

}  // namespace

std::string ResponseId(const ResponseCurve& c) {
  // FNV-1a over the bit patterns: saved values are printed with 17 digits, so a curve read
  // back has exactly the same id.
  uint64_t h = 1469598103934665603ull;
  auto mix = [&h](const void* p, size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  };
  mix(&c.levels, sizeof c.levels);
  const unsigned char lin = c.linear ? 1 : 0;
  mix(&lin, 1);
  for (const auto& ch : c.log_exposure) {
    for (double v : ch) mix(&v, sizeof v);
  }
  return fmt::format("g-{:016x}", h);
}

ResponseCurve LinearResponse(int levels) {
  ResponseCurve c;
  c.levels = levels;
  c.linear = true;
  const double mid = levels / 2;
  for (auto& ch : c.log_exposure) {
    ch.resize(levels);
    ch[0] = std::log(0.5 / mid);
    for (int z = 1; z < levels; ++z) ch[z] = std::log(z / mid);
  }
  c.id = fmt::format("linear-{}", levels);
  return c;
}

Status ValidateBracket(std::span<const LdrFrame> frames) {
  if (frames.empty()) return MakeError(ErrorCode::kInvalidInput, "", "empty bracket");
  for (size_t i = 0; i < frames.size(); ++i) {
    const LdrFrame& f = frames[i];
    if (f.image.empty()) return MakeError(ErrorCode::kInvalidInput, f.source, "empty image");
    if (f.image.type() != CV_8UC3 && f.image.type() != CV_16UC3) {
      return MakeError(ErrorCode::kInvalidInput, f.source,
                       "image type {} (a bracket needs 8- or 16-bit three-channel frames)",
                       f.image.type());
    }
    const double t = f.exposure.count();
    if (!(t > 0) || !std::isfinite(t)) {
      return MakeError(ErrorCode::kInvalidInput, f.source, "exposure time {} s is not positive",
                       t);
    }
    if (i == 0) continue;
    const LdrFrame& p = frames[i - 1];
    const LdrFrame& first = frames[0];
    if (f.image.size() != first.image.size()) {
      return MakeError(ErrorCode::kInvalidInput, f.source, "size {}x{} differs from {}x{} of {}",
                       f.image.cols, f.image.rows, first.image.cols, first.image.rows,
                       first.source);
    }
    if (f.image.type() != first.image.type()) {
      return MakeError(ErrorCode::kInvalidInput, f.source, "{}-bit frame in a {}-bit bracket ({})",
                       f.image.depth() == CV_16U ? 16 : 8, first.image.depth() == CV_16U ? 16 : 8,
                       first.source);
    }
    if (t == p.exposure.count()) {
      return MakeError(ErrorCode::kInvalidInput, f.source,
                       "duplicate exposure time {:.6g} s (same as {})", t, p.source);
    }
    if (t < p.exposure.count()) {
      return MakeError(ErrorCode::kInvalidInput, f.source,
                       "exposure times must increase: {:.6g} s after {:.6g} s of {}", t,
                       p.exposure.count(), p.source);
    }
  }
  if (frames.size() < 2) {
    return MakeError(ErrorCode::kInvalidInput, frames[0].source,
                     "a bracket needs at least two exposures (this is the only one)");
  }
  return Ok();
}

Result<ResponseCurve> RecoverResponse(std::span<const Bracket> brackets,
                                      const ResponseOptions& o) {
  if (brackets.empty()) {
    return MakeError(ErrorCode::kInvalidInput, "", "no brackets to recover the response from");
  }
  if (!(o.lambda >= 0) || o.samples < 1) {
    return MakeError(ErrorCode::kInvalidInput, "",
                     "lambda must be >= 0 and samples >= 1 (lambda {}, samples {})", o.lambda,
                     o.samples);
  }
  for (const auto& b : brackets) RIG_TRY(ValidateBracket(b));
  const int levels = LevelsOf(brackets[0][0].image);
  for (const auto& b : brackets) {
    if (LevelsOf(b[0].image) != levels) {
      return MakeError(ErrorCode::kInvalidInput, b[0].source,
                       "all brackets of one response must share one bit depth ({})",
                       brackets[0][0].source);
    }
  }
  const int nb = static_cast<int>(brackets.size());
  const int per_bracket = (o.samples + nb - 1) / nb;
  // ResponseSample selection: one task per (bracket, channel).
  std::vector<std::vector<ResponseSample>> chosen(size_t(nb) * 3);
  ParallelFor(nb * 3, o.threads, [&](int b, int e) {
    for (int k = b; k < e; ++k) {
      chosen[k] = o.grid_sampling
                      ? GridSamples(brackets[k / 3], k / 3, k % 3, per_bracket)
                      : ChooseSamples(brackets[k / 3], k / 3, k % 3, per_bracket, o.seed);
    }
  });
  std::array<std::vector<ResponseSample>, 3> samples;
  for (int k = 0; k < nb * 3; ++k) {
    samples[k % 3].insert(samples[k % 3].end(), chosen[k].begin(), chosen[k].end());
  }
  std::array<std::optional<Result<std::vector<double>>>, 3> solved;
  ParallelFor(3, o.threads, [&](int b, int e) {
    for (int c = b; c < e; ++c) solved[c] = SolveChannel(brackets, samples[c], c, o.lambda);
  });
  ResponseCurve curve;
  curve.levels = levels;
  for (int c = 0; c < 3; ++c) {
    if (!solved[c]->ok()) return solved[c]->error().Within(brackets[0][0].source);
    curve.log_exposure[c] = levels == kBins ? std::move(*solved[c]).value()
                                            : ExpandBins(solved[c]->value());
  }
  curve.id = ResponseId(curve);
  Log("process")->debug("response recovered id={} brackets={} samples={} lambda={}", curve.id,
                        nb, samples[1].size(), o.lambda);
  return curve;
}

Status SaveResponse(const ResponseCurve& c, const std::string& path) {
  for (const auto& ch : c.log_exposure) {
    if (int(ch.size()) != c.levels) {
      return MakeError(ErrorCode::kInvalidInput, path, "curve has {} values for {} levels",
                       ch.size(), c.levels);
    }
  }
  std::string text;
  text.reserve(size_t(c.levels) * 80 + 256);
  text += "# rig camera response: Debevec-Malik g(z) = ln(exposure) per level, anchored g(mid)=0\n";
  text += fmt::format("# levels={}\n# linear={}\n# id={}\n", c.levels, c.linear ? 1 : 0,
                      c.id.empty() ? ResponseId(c) : c.id);
  text += "level,B,G,R\n";
  for (int z = 0; z < c.levels; ++z) {
    text += fmt::format("{},{:.17g},{:.17g},{:.17g}\n", z, c.log_exposure[0][z],
                        c.log_exposure[1][z], c.log_exposure[2][z]);
  }
  return WriteTextAtomically(path, text);
}

Result<ResponseCurve> LoadResponse(const std::string& path) {
  std::ifstream in(path);
  if (!in) {
    std::error_code ec;
    return MakeError(fs::exists(path, ec) ? ErrorCode::kIo : ErrorCode::kNotFound, path,
                     "cannot open response file");
  }
  ResponseCurve c;
  c.levels = 0;
  std::string id, line;
  int line_no = 0;
  bool header_seen = false;
  while (std::getline(in, line)) {
    ++line_no;
    const std::string where = path + ":" + std::to_string(line_no);
    if (line.empty()) continue;
    if (line[0] == '#') {
      if (line.rfind("# levels=", 0) == 0) c.levels = std::atoi(line.c_str() + 9);
      if (line.rfind("# linear=", 0) == 0) c.linear = line.substr(9) == "1";
      if (line.rfind("# id=", 0) == 0) id = line.substr(5);
      continue;
    }
    if (!header_seen) {
      header_seen = true;
      if (line.rfind("level,", 0) == 0) continue;
    }
    if (c.levels != 256 && c.levels != 65536) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "'# levels=' must come first and be 256 or 65536");
    }
    for (auto& ch : c.log_exposure) {
      if (ch.empty()) ch.reserve(c.levels);
    }
    int z = -1;
    double v[3];
    char tail = 0;
    if (std::sscanf(line.c_str(), "%d,%lf,%lf,%lf%c", &z, &v[0], &v[1], &v[2], &tail) != 4 ||
        z != int(c.log_exposure[0].size()) || z >= c.levels) {
      return MakeError(ErrorCode::kInvalidInput, where, "expected 'level,B,G,R' for level {}",
                       c.log_exposure[0].size());
    }
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(v[k])) {
        return MakeError(ErrorCode::kInvalidInput, where, "value is not finite");
      }
      c.log_exposure[k].push_back(v[k]);
    }
  }
  if (c.levels == 0 || int(c.log_exposure[0].size()) != c.levels) {
    return MakeError(ErrorCode::kInvalidInput, path, "{} of {} levels present (truncated file?)",
                     c.log_exposure[0].size(), c.levels);
  }
  c.id = c.linear && id == fmt::format("linear-{}", c.levels) ? id : ResponseId(c);
  if (!id.empty() && id != c.id) {
    return MakeError(ErrorCode::kCorrupt, path,
                     "values do not match the stored id {} (they hash to {}): edited or damaged",
                     id, c.id);
  }
  return c;
}

double NoiseModel::Variance(const ResponseCurve& r, int c, int z) const {
  const auto& g = r.log_exposure[c];
  const int levels = int(g.size());
  const int z0 = std::clamp(z - 1, 0, levels - 1), z1 = std::clamp(z + 1, 0, levels - 1);
  const double slope = (g[z1] - g[z0]) / std::max(1, z1 - z0);
  const double e = std::exp(-(g[z] - g[levels / 2]));
  return quant[c] * slope * slope + shot[c] * e + read[c] * e * e;
}

namespace {

// Squared differences of neighbouring exposures binned by the pair of levels (8-bit: every
// pair; 16-bit: 256 bins a side): the count, the mean d^2 and the mean features of each bin.
struct NoiseBin {
  double n = 0, d2 = 0, f[3] = {0, 0, 0};
};

// One channel's bins over every neighbouring pair of frames, every `row_step`-th row; the
// samples binned are counted in *count.
std::vector<NoiseBin> NoiseBins(std::span<const LdrFrame> frames, const ResponseCurve& response,
                                int c, int lo, int hi, int row_step, int64_t* count) {
  const auto& g = response.log_exposure[c];
  const int levels = response.levels;
  const bool sixteen = levels == 65536;
  const int n = int(frames.size());
  const int w = frames[0].image.cols, h = frames[0].image.rows;
  // The three features of each level (NoiseModel::Variance with unit coefficients).
  std::vector<std::array<double, 3>> feature(levels);
  for (int z = 0; z < levels; ++z) {
    const int z0 = std::max(z - 1, 0), z1 = std::min(z + 1, levels - 1);
    const double slope = (g[z1] - g[z0]) / std::max(1, z1 - z0);
    const double e = std::exp(-(g[z] - g[levels / 2]));
    feature[z] = {slope * slope, e, e * e};
  }
  const int shift = sixteen ? 8 : 0;
  std::vector<NoiseBin> bins(256 * 256);
  *count = 0;
  for (int j = 0; j + 1 < n; ++j) {
    const double lt0 = std::log(frames[j].exposure.count()), lt1 = std::log(frames[j + 1].exposure.count());
    for (int y = j % row_step; y < h; y += row_step) {
      for (int x = 0; x < w; ++x) {
        int z0, z1;
        if (sixteen) {
          z0 = frames[j].image.ptr<uint16_t>(y)[3 * x + c];
          z1 = frames[j + 1].image.ptr<uint16_t>(y)[3 * x + c];
        } else {
          z0 = frames[j].image.ptr<uint8_t>(y)[3 * x + c];
          z1 = frames[j + 1].image.ptr<uint8_t>(y)[3 * x + c];
        }
        if (z0 <= lo || z0 >= hi || z1 <= lo || z1 >= hi) continue;
        const double d = (g[z0] - lt0) - (g[z1] - lt1);
        // Not noise: motion, a flicker (raising this to 1.5 or 3 changes nothing measurable).
        if (std::abs(d) > 0.7) continue;
        NoiseBin& bin = bins[(z0 >> shift) * 256 + (z1 >> shift)];
        bin.n += 1;
        bin.d2 += d * d;
        for (int i = 0; i < 3; ++i) bin.f[i] += feature[z0][i] + feature[z1][i];
        ++*count;
      }
    }
  }
  return bins;
}

// A non-negative least squares in three unknowns: the best of the 7 subsets of terms whose
// unconstrained solution is non-negative (columns scaled for conditioning).
Eigen::Vector3d NonNegativeSolve3(const Eigen::Matrix3d& a, const Eigen::Vector3d& b, double yy) {
  Eigen::Vector3d scale;
  for (int i = 0; i < 3; ++i) scale(i) = a(i, i) > 0 ? 1.0 / std::sqrt(a(i, i)) : 0.0;
  const Eigen::Matrix3d as = scale.asDiagonal() * a * scale.asDiagonal();
  const Eigen::Vector3d bs = scale.cwiseProduct(b);
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector3d next = Eigen::Vector3d::Zero();
  for (int mask = 1; mask < 8; ++mask) {
    std::vector<int> idx;
    for (int i = 0; i < 3; ++i)
      if ((mask >> i & 1) && scale(i) > 0) idx.push_back(i);
    if (idx.empty()) continue;
    const int q = int(idx.size());
    Eigen::MatrixXd sub(q, q);
    Eigen::VectorXd rhs(q);
    for (int u = 0; u < q; ++u) {
      rhs(u) = bs(idx[u]);
      for (int v = 0; v < q; ++v) sub(u, v) = as(idx[u], idx[v]);
    }
    const Eigen::VectorXd sol = sub.ldlt().solve(rhs);
    if (!sol.allFinite() || (sol.array() < 0).any()) continue;
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    for (int u = 0; u < q; ++u) t(idx[u]) = sol(u);
    const double residual = yy - 2 * t.dot(bs) + t.dot(as * t);
    if (residual < best) {
      best = residual;
      next = t;
    }
  }
  return next.cwiseProduct(scale);
}

// Iteratively reweighted least squares: a bin's mean d^2 has variance 2 v^2 / n under
// Gaussian noise, so it weighs n / v^2 with v the current prediction (the first pass weighs
// by n alone). False when no pass gives positive terms.
bool FitNoiseTerms(const std::vector<const NoiseBin*>& used, Eigen::Vector3d* theta) {
  *theta = Eigen::Vector3d::Zero();
  bool have = false;
  for (int pass = 0; pass < 5; ++pass) {
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    double yy = 0;
    for (const NoiseBin* bin : used) {
      const Eigen::Vector3d f(bin->f[0], bin->f[1], bin->f[2]);
      double wt = bin->n;
      if (have) {
        const double v = theta->dot(f);
        if (!(v > 0)) continue;
        wt /= v * v;
      }
      a += wt * f * f.transpose();
      b += wt * bin->d2 * f;
      yy += wt * bin->d2 * bin->d2;
    }
    const Eigen::Vector3d next = NonNegativeSolve3(a, b, yy);
    if (!(next.sum() > 0)) break;
    *theta = next;
    have = true;
  }
  return have;
}

}  // namespace

NoiseModel FitNoise(std::span<const LdrFrame> frames, const ResponseCurve& response,
                    std::array<int, 3> black_level, std::array<int, 3> saturation_level) {
  NoiseModel m;
  const int n = int(frames.size());
  if (n < 2) return m;
  const int levels = response.levels;
  const int w = frames[0].image.cols, h = frames[0].image.rows;
  // At most ~64k pixels per neighbouring pair and channel, in whole rows spread over the
  // image (contiguous reads): a few ms for any image size.
  const int rows_wanted = int((65536 + w - 1) / w);
  const int row_step = std::max(1, h / rows_wanted);
  m.ok = true;
  for (int c = 0; c < 3; ++c) {
    const int lo = std::max(black_level[c], 0), hi = saturation_level[c] < 0 ? levels - 1 : saturation_level[c];
    int64_t count = 0;
    std::vector<NoiseBin> bins = NoiseBins(frames, response, c, lo, hi, row_step, &count);
    m.pairs[c] = count;
    if (count < 1000) {
      m.ok = false;
      continue;
    }
    std::vector<const NoiseBin*> used;
    for (NoiseBin& bin : bins) {
      if (bin.n == 0) continue;
      bin.d2 /= bin.n;
      for (double& f : bin.f) f /= bin.n;
      used.push_back(&bin);
    }
    Eigen::Vector3d theta;
    if (!FitNoiseTerms(used, &theta)) {
      m.ok = false;
      continue;
    }
    m.quant[c] = theta(0);
    m.shot[c] = theta(1);
    m.read[c] = theta(2);
  }
  return m;
}

const char* MergeWeightingName(MergeWeighting w) {
  switch (w) {
    case MergeWeighting::kHat: return "hat";
    case MergeWeighting::kPhoton: return "photon";
    case MergeWeighting::kNoise: return "noise";
  }
  return "?";
}

Result<MergeWeighting> ParseMergeWeighting(const std::string& name) {
  if (name == "hat") return MergeWeighting::kHat;
  if (name == "photon") return MergeWeighting::kPhoton;
  if (name == "noise") return MergeWeighting::kNoise;
  return MakeError(ErrorCode::kInvalidInput, "merge_weighting",
                   "unknown merge weighting '{}' (hat, photon or noise)", name);
}

namespace {

// Per frame and channel one table of (w(z), w(z)(g(z) - ln t)) pairs: the merge is then two
// look-ups and two adds per sample, and one exp per pixel and channel.
struct MergeEntry {
  float w, wg;
};

// The black and saturation levels per channel, checked against the frames' levels.
Status MergeLevels(std::span<const LdrFrame> frames, const ResponseCurve& response,
                   const MergeOptions& o, int levels, std::array<int, 3>* lo,
                   std::array<int, 3>* hi) {
  if (response.levels != levels) {
    return MakeError(ErrorCode::kInvalidInput, frames[0].source,
                     "{}-level frames need a {}-level response (the response has {})", levels,
                     levels, response.levels);
  }
  for (const auto& ch : response.log_exposure) {
    if (int(ch.size()) != levels) {
      return MakeError(ErrorCode::kInvalidInput, "", "response {} is malformed", response.id);
    }
  }
  for (int c = 0; c < 3; ++c) {
    (*lo)[c] = o.black_level[c] < 0 ? 0 : o.black_level[c];
    (*hi)[c] = o.saturation_level[c] < 0 ? levels - 1 : o.saturation_level[c];
    if ((*lo)[c] >= (*hi)[c] - 1 || (*hi)[c] > levels - 1) {
      return MakeError(ErrorCode::kInvalidInput, "",
                       "channel {}: black level {} and saturation level {} leave no range",
                       "BGR"[c], (*lo)[c], (*hi)[c]);
    }
  }
  return Ok();
}

// The tables: [frame][channel][level]. With a fitted noise model the weight is the inverse
// variance per level and channel, with the hat's ends: it falls to zero over the last 1/16 of
// the range at either end (as the hat does), where a recovered g is least sure (docs/hdr.md:
// 1/32 lets the simulator's toe count too much).
std::vector<MergeEntry> MergeTables(std::span<const LdrFrame> frames, const ResponseCurve& response,
                                    const MergeOptions& o, const NoiseModel& noise, int levels,
                                    const std::array<int, 3>& lo, const std::array<int, 3>& hi) {
  const int n = static_cast<int>(frames.size());
  std::vector<MergeEntry> lut(size_t(n) * 3 * levels);
  std::vector<std::array<float, 3>> inv_var;
  if (noise.ok) {
    inv_var.resize(levels);
    for (int c = 0; c < 3; ++c) {
      const double ramp = (hi[c] - lo[c]) / 16.0;
      for (int z = 0; z < levels; ++z) {
        const double v = noise.Variance(response, c, z);
        const double taper = std::min(1.0, Hat(z, lo[c], hi[c]) / ramp);
        inv_var[z][c] = v > 0 && std::isfinite(v) ? float(taper / v) : 0.f;
      }
    }
  }
  for (int j = 0; j < n; ++j) {
    const double lt = std::log(frames[j].exposure.count());
    for (int c = 0; c < 3; ++c) {
      MergeEntry* t = &lut[(size_t(j) * 3 + c) * levels];
      const double g_mid = response.log_exposure[c][levels / 2];
      for (int z = 0; z < levels; ++z) {
        double w = Hat(z, lo[c], hi[c]) / (levels / 2);
        if (noise.ok) {
          w = inv_var[z][c];
        } else if (o.weighting != MergeWeighting::kHat) {
          w *= std::exp(response.log_exposure[c][z] - g_mid);
        }
        t[z] = {float(w), float(w * (response.log_exposure[c][z] - lt))};
      }
    }
  }
  return lut;
}

// The same tables split into w and wg arrays per frame (the 8-bit path): [frame][w|wg][c][z].
std::vector<float> SplitTables8(const std::vector<MergeEntry>& lut, int n) {
  std::vector<float> split(size_t(n) * 2 * 3 * 256);
  for (int j = 0; j < n; ++j)
    for (int c = 0; c < 3; ++c)
      for (int z = 0; z < 256; ++z) {
        const MergeEntry& e = lut[(size_t(j) * 3 + c) * 256 + z];
        split[(size_t(j) * 2 + 0) * 768 + c * 256 + z] = e.w;
        split[(size_t(j) * 2 + 1) * 768 + c * 256 + z] = e.wg;
      }
  return split;
}

// What the merge of every row shares.
struct MergeRows {
  std::span<const LdrFrame> frames;
  const std::vector<MergeEntry>& lut;
  const std::vector<float>& split;  // 8-bit only
  int levels;
  std::array<int, 3> hi;
  std::array<float, 3> sat_value;  // lower bound for a channel saturated everywhere
  bool have_avx2;
};

// One row's ln radiance (k = 3x + c) into lnv; the samples with no usable value listed.
void MergeRowLog(const MergeRows& mr, int y, std::vector<float>& lnv, std::vector<float>& num,
                 std::vector<float>& den, std::vector<int>* unrecorded) {
  const int n = static_cast<int>(mr.frames.size());
  const int m = static_cast<int>(lnv.size());
  if (mr.levels != 65536) {
    // 8-bit: frame by frame over the row (each frame's row streams once through its tables
    // while the row's sums stay in cache), with AVX2 gathers where the CPU has them.
    std::fill(num.begin(), num.end(), 0.f);
    std::fill(den.begin(), den.end(), 0.f);
    for (int j = 0; j < n; ++j) {
      const float* w = &mr.split[size_t(j) * 2 * 3 * 256];
      (mr.have_avx2 ? AccumulateRow8Avx2 : AccumulateRow8)(mr.frames[j].image.ptr<uint8_t>(y), m,
                                                           w, w + 3 * 256, den.data(), num.data());
    }
    for (int k = 0; k < m; ++k) {
      if (den[k] > 0) {
        lnv[k] = num[k] / den[k];
      } else {
        lnv[k] = 0;
        unrecorded->push_back(k);
      }
    }
    return;
  }
  const int levels = mr.levels;
  for (int k = 0; k < m; k += 3) {
    float num16[3] = {0, 0, 0}, den16[3] = {0, 0, 0};
    for (int j = 0; j < n; ++j) {
      const MergeEntry* t = &mr.lut[size_t(j) * 3 * levels];
      const uint16_t* p = mr.frames[j].image.ptr<uint16_t>(y);
      const int z0 = p[k], z1 = p[k + 1], z2 = p[k + 2];
      const MergeEntry e0 = t[z0], e1 = t[levels + z1], e2 = t[2 * levels + z2];
      den16[0] += e0.w, num16[0] += e0.wg;
      den16[1] += e1.w, num16[1] += e1.wg;
      den16[2] += e2.w, num16[2] += e2.wg;
    }
    for (int c = 0; c < 3; ++c) {
      if (den16[c] > 0) {
        lnv[k + c] = num16[c] / den16[c];
      } else {
        lnv[k + c] = 0;
        unrecorded->push_back(k + c);
      }
    }
  }
}

// Rows [y0, y1) of the map: radiance, flags, and the rows' saturated and black counts.
void MergeRowRange(const MergeRows& mr, int y0, int y1, RadianceMap* map, std::vector<int>* sat_rows,
                   std::vector<int>* black_rows) {
  const int width = mr.frames[0].image.cols;
  const bool sixteen = mr.levels == 65536;
  const int m = width * 3;
  std::vector<float> lnv(m), num(sixteen ? 0 : m), den(sixteen ? 0 : m);
  for (int y = y0; y < y1; ++y) {
    uint8_t* fl = map->flags.ptr<uint8_t>(y);
    std::memset(fl, 0, width);
    std::vector<int> unrecorded;  // indices k = 3x + c with no usable sample
    MergeRowLog(mr, y, lnv, num, den, &unrecorded);
    float* out = map->radiance.ptr<float>(y);
    cv::Mat lnm(1, m, CV_32F, lnv.data()), outm(1, m, CV_32F, out);
    cv::exp(lnm, outm);
    for (int k : unrecorded) {
      const int c = k % 3, x = k / 3;
      // Saturated if even the shortest exposure is at or above the saturation level;
      // otherwise black (or a gap in the bracket: black in one, clipped in the next).
      const int z_short = sixteen ? mr.frames[0].image.ptr<uint16_t>(y)[k]
                                  : mr.frames[0].image.ptr<uint8_t>(y)[k];
      if (z_short >= mr.hi[c]) {
        out[k] = mr.sat_value[c];
        fl[x] = kFlagSaturated;
      } else {
        out[k] = 0;
        if (fl[x] == kFlagOk) fl[x] = kFlagBlack;
      }
    }
    for (int x = 0; x < width; ++x) {
      (*sat_rows)[y] += fl[x] == kFlagSaturated;
      (*black_rows)[y] += fl[x] == kFlagBlack;
    }
  }
}

// A bracket too short at either end, beyond the fraction allowed.
Status CheckRecorded(std::span<const LdrFrame> frames, const RadianceMap& map,
                     const MergeOptions& o) {
  const double total = double(map.radiance.cols) * map.radiance.rows;
  if (o.max_unrecorded_fraction >= 1.0) return Ok();
  if (map.saturated_pixels > o.max_unrecorded_fraction * total) {
    return MakeError(ErrorCode::kInvalidInput, frames.front().source,
                     "bracket too short: {:.1f}% of the pixels are saturated even in the "
                     "shortest exposure ({:.6g} s); add shorter exposures",
                     100.0 * map.saturated_pixels / total, frames.front().exposure.count());
  }
  if (map.black_pixels > o.max_unrecorded_fraction * total) {
    return MakeError(ErrorCode::kInvalidInput, frames.back().source,
                     "bracket too short: {:.1f}% of the pixels are black even in the longest "
                     "exposure ({:.6g} s); add longer exposures",
                     100.0 * map.black_pixels / total, frames.back().exposure.count());
  }
  return Ok();
}

// The map's header: its frames, response, units, flags and weighting.
void MergeAttributes(std::span<const LdrFrame> frames, const ResponseCurve& response,
                     const MergeOptions& o, const NoiseModel& noise, RadianceMap* map) {
  std::string sources;
  for (const auto& f : frames) {
    if (!sources.empty()) sources += ' ';
    sources += fs::path(f.source).filename().string();
  }
  auto& a = map->attributes;
  a["exposures_s"] = FormatExposures(frames);
  a["frames"] = sources;
  a["response_id"] = response.id.empty() ? ResponseId(response) : response.id;
  a["response_linear"] = response.linear ? "1" : "0";
  a["radiance_units"] = "relative: exp(g(z) - ln t) with g(mid level) = 0, per channel";
  a["flags"] =
      "0 ok; 1 a channel saturated in every exposure (holds the lower bound from the shortest "
      "exposure); 2 a channel black in every exposure (holds 0)";
  a["saturated_pixels"] = std::to_string(map->saturated_pixels);
  a["black_pixels"] = std::to_string(map->black_pixels);
  // The weighting asked for (what `rig process` compares to decide a map is up to date), and
  // below it, the one used with its fitted terms.
  a["merge_weighting_option"] = MergeWeightingName(o.weighting);
  if (noise.ok) {
    a["merge_weighting"] = fmt::format(
        "inverse variance, fitted per channel B,G,R: quantisation {:.3g},{:.3g},{:.3g} x g'^2; "
        "shot {:.3g},{:.3g},{:.3g} x exp(-G); read {:.3g},{:.3g},{:.3g} x exp(-2G); "
        "G = g(z) - g(mid)",
        noise.quant[0], noise.quant[1], noise.quant[2], noise.shot[0], noise.shot[1],
        noise.shot[2], noise.read[0], noise.read[1], noise.read[2]);
  } else {
    a["merge_weighting"] = o.weighting == MergeWeighting::kHat ? "hat" : "hat x exposure (photon noise)";
  }
}

}  // namespace

Result<RadianceMap> MergeBracket(std::span<const LdrFrame> frames, const ResponseCurve& response,
                                 const MergeOptions& o) {
  RIG_TRY(ValidateBracket(frames));
  const int levels = LevelsOf(frames[0].image);
  std::array<int, 3> lo, hi;
  RIG_TRY(MergeLevels(frames, response, o, levels, &lo, &hi));
  const int n = static_cast<int>(frames.size());
  NoiseModel noise;
  if (o.weighting == MergeWeighting::kNoise) noise = FitNoise(frames, response, lo, hi);
  const std::vector<MergeEntry> lut = MergeTables(frames, response, o, noise, levels, lo, hi);
  const std::vector<float> split = levels == 256 ? SplitTables8(lut, n) : std::vector<float>{};
  std::array<float, 3> sat_value;
  for (int c = 0; c < 3; ++c) {
    sat_value[c] = float(std::exp(response.log_exposure[c][hi[c]] -
                                  std::log(frames[0].exposure.count())));
  }
  // RIG_NO_SIMD=1 forces the scalar path (the tests compare the two).
  const bool have_avx2 = __builtin_cpu_supports("avx2") && !std::getenv("RIG_NO_SIMD");
  const MergeRows rows{frames, lut, split, levels, hi, sat_value, have_avx2};

  const int width = frames[0].image.cols, height = frames[0].image.rows;
  RadianceMap map;
  map.radiance.create(height, width, CV_32FC3);
  map.flags.create(height, width, CV_8UC1);
  std::vector<int> sat_rows(height, 0), black_rows(height, 0);
  ParallelFor(height, o.threads, [&](int y0, int y1) {
    MergeRowRange(rows, y0, y1, &map, &sat_rows, &black_rows);
  }, 4);
  map.saturated_pixels = std::accumulate(sat_rows.begin(), sat_rows.end(), 0);
  map.black_pixels = std::accumulate(black_rows.begin(), black_rows.end(), 0);
  RIG_TRY(CheckRecorded(frames, map, o));
  MergeAttributes(frames, response, o, noise, &map);
  return map;
}

Status WriteRadianceMap(const std::string& path, const RadianceMap& map, ExrPixelType type,
                        int threads, ExrCompression compression) {
  if (map.radiance.type() != CV_32FC3 || map.radiance.empty()) {
    return MakeError(ErrorCode::kInvalidInput, path, "radiance must be a non-empty CV_32FC3");
  }
  const bool flags = !map.flags.empty();
  if (flags && (map.flags.type() != CV_8UC1 || map.flags.size() != map.radiance.size())) {
    return MakeError(ErrorCode::kInvalidInput, path, "flags must be CV_8UC1 of the map's size");
  }
  std::vector<std::string> names = {"B", "G", "R"};
  if (flags) names.push_back("flags");
  const int width = map.radiance.cols, nch = int(names.size());
  return WriteExrStriped(path, width, map.radiance.rows, names, map.attributes, type, threads,
                         [&](int y0, int y1, float* out) {
                           for (int y = y0; y < y1; ++y) {
                             float* o = out + size_t(y - y0) * width * nch;
                             const float* r = map.radiance.ptr<float>(y);
                             if (!flags) {
                               std::memcpy(o, r, sizeof(float) * 3 * width);
                               continue;
                             }
                             const uint8_t* f = map.flags.ptr<uint8_t>(y);
                             for (int x = 0; x < width; ++x) {
                               o[4 * x] = r[3 * x];
                               o[4 * x + 1] = r[3 * x + 1];
                               o[4 * x + 2] = r[3 * x + 2];
                               o[4 * x + 3] = f[x];
                             }
                           }
                         }, compression);
}

Result<ExrPixelType> ParseExrPixelType(const std::string& name) {
  if (name == "half") return ExrPixelType::kHalf;
  if (name == "float") return ExrPixelType::kFloat;
  return MakeError(ErrorCode::kInvalidInput, "", "pixel type '{}' (expected half or float)",
                   name);
}

}  // namespace rig
