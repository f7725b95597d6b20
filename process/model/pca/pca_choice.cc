// The PCA size chosen by held-out error per byte: validation splits over lights for the
// model error of every (components, grid), the planes' own JPEG error and size for every
// quality, the smallest candidate within tolerance of the best within budget.
#include "process/model/pca/pca_choice.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "config/log.h"
#include "process/io/jpeg_io.h"

namespace rig {
namespace {

int Digits(int v) { return v >= 100 ? 3 : v >= 10 ? 2 : 1; }

// Characters of relight's "basis" array for the first k components (ints and commas).
double BasisJsonBytes(const PcaBasis& b, int k) {
  const size_t n = static_cast<size_t>(k + 1) * b.resolution * b.resolution * 3;
  double chars = 0;
  for (size_t i = 0; i < n && i < b.stored.size(); ++i) chars += Digits(b.stored[i]) + 1;
  return chars;
}

}  // namespace

LightSamples PcaChoicePickPixels(const LightSamples& s, const std::vector<size_t>& pixels) {
  LightSamples out;
  out.width = static_cast<int>(pixels.size());
  out.height = 1;
  out.directions = s.directions;
  const size_t row = static_cast<size_t>(s.lights()) * 3;
  out.values.resize(pixels.size() * row);
  for (size_t i = 0; i < pixels.size(); ++i)
    std::copy_n(s.values.data() + pixels[i] * row, row, out.values.data() + i * row);
  return out;
}

int PcaChoiceSplits(const PcaChoiceOptions& o) {
  return std::clamp(o.validation_splits, 1, std::max(2, o.validation_every));
}

std::vector<int> PcaChoiceHeldOutLights(int lights, const PcaChoiceOptions& o, int split) {
  const int every = std::max(2, o.validation_every);
  std::vector<int> held;
  for (int l = split * every / PcaChoiceSplits(o); l < lights; l += every) held.push_back(l);
  return held;
}

std::string PcaChoiceSplitWords(const PcaChoiceOptions& o) {
  const int every = std::max(2, o.validation_every), splits = PcaChoiceSplits(o);
  if (splits == 1) return fmt::format("every {}th light of the fit held out", every);
  if (splits == every) return fmt::format("every light of the fit held out once, in {} splits", splits);
  return fmt::format("every {}th light of the fit held out, in {} shifted splits", every, splits);
}

std::vector<size_t> PcaChoiceEvalPixels(size_t sampled, const PcaChoiceOptions& o) {
  std::vector<size_t> eval;
  // The pixels are shared by the splits: what moves the estimate is which lights are held
  // out, not which pixels are scored (8192 pixels in each of 6 splits chose as 1365 did).
  const size_t want = std::max<size_t>(256, o.validation_pixels / PcaChoiceSplits(o));
  const size_t step = std::max<size_t>(1, sampled / std::max<size_t>(1, want));
  for (size_t i = 0; i < sampled; i += step) eval.push_back(i);
  return eval;
}

cv::Rect PcaChoiceCrop(int width, int height) {
  const int max_side = 256;
  const int w = std::min(width, max_side), h = std::min(height, max_side);
  return {(width - w) / 2, (height - h) / 2, w, h};
}

PcaChoiceInput PcaChoiceInputOf(const LightSamples& s, const std::vector<size_t>& subset) {
  PcaChoiceInput in;
  in.pixels = s.pixels();
  in.sampled = PcaChoicePickPixels(s, subset);
  const cv::Rect r = PcaChoiceCrop(s.width, s.height);
  std::vector<size_t> picked;
  for (int y = 0; y < r.height; ++y)
    for (int x = 0; x < r.width; ++x)
      picked.push_back(static_cast<size_t>(r.y + y) * s.width + r.x + x);
  in.crop = PcaChoicePickPixels(s, picked);
  in.crop.width = r.width;
  in.crop.height = r.height;
  return in;
}

Result<PcaChoice> ChoosePca(const LightSamples& s, const PcaComponents& comps,
                            const PcaChoiceOptions& o) {
  return ChoosePca(PcaChoiceInputOf(s, comps.subset), comps, o);
}

namespace {

// The model error at held-out lights of one grid, for every number of components.
struct GridModelError {
  int res;
  std::vector<double> mse_by_k;  // index k
  PcaBasis full_basis;           // on all lights, for sizes
};


// 1. Model error at held-out lights, for every grid and every number of components, summed
//    over the splits: in each, the components without its validation lights (exact, from the
//    kept covariance), the grid fitted to the others, coefficients of a sample of pixels
//    through it.
Result<std::vector<GridModelError>> HeldOutModelErrors(const LightSamples& s,
                                                       const PcaComponents& comps,
                                                       const PcaChoiceOptions& o, int* kmax_io) {
  const int splits = PcaChoiceSplits(o);
  std::vector<std::vector<int>> held(splits);
  std::vector<PcaComponents> train(splits);
  for (int r = 0; r < splits; ++r) {
    held[r] = PcaChoiceHeldOutLights(s.lights(), o, r);
    train[r] = PcaComponentsWithout(comps, held[r], *kmax_io);
    // No more components than the other lights' samples span (fewer where some are degenerate).
    *kmax_io = std::min<int>(*kmax_io, static_cast<int>(train[r].vectors.cols()));
  }
  const int kmax = *kmax_io;
  if (kmax < 1) return MakeError(ErrorCode::kInvalidInput, "pca choice", "too few lights");
  const std::vector<size_t> eval = PcaChoiceEvalPixels(comps.subset.size(), o);  // into `sampled`
  const LightSamples picked = PcaChoicePickPixels(s, eval);
  std::vector<size_t> all_eval(eval.size());
  for (size_t i = 0; i < eval.size(); ++i) all_eval[i] = i;

  std::vector<GridModelError> by_grid;
  for (int res : o.resolutions) {
    GridModelError g{res, std::vector<double>(kmax + 1, 0), {}};
    std::vector<double> count(kmax + 1, 0);
    for (int r = 0; r < splits; ++r) {
      LightSamples fit_part = picked;
      for (auto it = held[r].rbegin(); it != held[r].rend(); ++it) fit_part = WithoutLight(fit_part, *it);
      RIG_ASSIGN_OR_RETURN(PcaBasis basis, FitPcaBasis(train[r], kmax, res, o.base.smoothness));
      for (int k : o.components) {
        if (k > kmax) continue;
        PcaOptions po = o.base;
        po.components = k;
        po.grid_resolution = res;
        RIG_ASSIGN_OR_RETURN(PcaModel m,
                             FitPcaCoefficients(fit_part, TruncatePcaBasis(basis, k), po, all_eval));
        double sum = 0;
        for (int l : held[r]) {
          const cv::Mat pred = m.Render(s.directions[l]);
          const float* pr = pred.ptr<float>();
          for (size_t i = 0; i < eval.size(); ++i) {
            for (int c = 0; c < 3; ++c) {
              const float v = std::clamp(std::nearbyint(pr[i * 3 + (2 - c)] * 255.0f), 0.0f, 255.0f);
              const double d = v - picked.value(i, l, c);
              sum += d * d;
            }
          }
        }
        g.mse_by_k[k] += sum;
        count[k] += static_cast<double>(held[r].size() * eval.size() * 3);
      }
    }
    for (int k = 0; k <= kmax; ++k)
      if (count[k] > 0) g.mse_by_k[k] /= count[k];
    RIG_ASSIGN_OR_RETURN(g.full_basis, FitPcaBasis(comps, kmax, res, o.base.smoothness));
    by_grid.push_back(std::move(g));
  }
  return by_grid;
}

// What JPEG costs per quality: bytes of every plane file scaled to the whole image
// (file_bytes[q][j]), and every plane's error in coefficient units² per pixel (plane_err[q][p]).
struct JpegCost {
  std::vector<std::vector<double>> file_bytes, plane_err;
};

// 2. What JPEG adds and what it costs, from the planes of a central crop fitted with all
//    components: per plane, its compression error in coefficient units times the mean
//    square of its basis function over the lights; bytes scaled to the whole image.
Result<JpegCost> JpegCosts(const LightSamples& crop, const PcaBasis& mid_basis,
                           const PcaChoiceOptions& o, int kmax, double pixels) {
  PcaOptions po = o.base;
  po.components = kmax;
  // What JPEG does to the planes hardly depends on how clipped samples were fitted around.
  po.mask = PcaMaskMode::kNone;
  std::vector<size_t> crop_index(crop.pixels());
  for (size_t i = 0; i < crop_index.size(); ++i) crop_index[i] = i;
  RIG_ASSIGN_OR_RETURN(PcaModel crop_model, FitPcaCoefficients(crop, mid_basis, po, crop_index));
  const int files = (kmax + 2) / 3;
  JpegCost cost;
  cost.file_bytes.assign(o.qualities.size(), std::vector<double>(files, 0));
  cost.plane_err.assign(o.qualities.size(), std::vector<double>(kmax, 0));
  const auto& planes = crop_model.planes();
  for (size_t qi = 0; qi < o.qualities.size(); ++qi) {
    for (int j = 0; j < files; ++j) {
      cv::Mat rgb(crop.height, crop.width, CV_8UC3, cv::Scalar(0, 0, 0));
      for (int c = 0; c < 3 && 3 * j + c < kmax; ++c) {
        cv::Mat ch[3];
        cv::split(rgb, ch);
        planes[3 * j + c].reshape(1, crop.height).copyTo(ch[c]);
        cv::merge(ch, 3, rgb);
      }
      RIG_ASSIGN_OR_RETURN(auto bytes, EncodeJpeg(rgb, kPcaPlaneColor, o.qualities[qi]));
      cost.file_bytes[qi][j] = static_cast<double>(bytes.size()) * pixels /
                               static_cast<double>(crop.pixels());
      RIG_ASSIGN_OR_RETURN(cv::Mat back, DecodeJpeg(bytes, "pca choice"));
      for (int c = 0; c < 3 && 3 * j + c < kmax; ++c) {
        const int p = 3 * j + c;
        double e = 0;
        for (int y = 0; y < rgb.rows; ++y) {
          const uint8_t* a = rgb.ptr<uint8_t>(y);
          const uint8_t* b = back.ptr<uint8_t>(y);
          for (int x = 0; x < rgb.cols; ++x) {
            const double d = static_cast<double>(a[x * 3 + c]) - b[x * 3 + c];
            e += d * d;
          }
        }
        const double scale = crop_model.quantisation()[p].scale();
        cost.plane_err[qi][p] = e / static_cast<double>(crop.pixels()) * scale * scale;
      }
    }
  }
  return cost;
}

// Mean square of each component's basis over the sampled lights and colours.
std::vector<double> BasisPower(const PcaBasis& basis, const std::vector<Vec3>& directions,
                               int kmax) {
  const int lights = static_cast<int>(directions.size());
  std::vector<double> power(kmax, 0);
  std::vector<double> at(static_cast<size_t>(kmax + 1) * 3);
  for (int l = 0; l < lights; ++l) {
    basis.Evaluate(directions[l], at.data());
    for (int p = 0; p < kmax; ++p)
      for (int c = 0; c < 3; ++c) power[p] += at[(p + 1) * 3 + c] * at[(p + 1) * 3 + c];
  }
  for (auto& v : power) v /= lights * 3.0;
  return power;
}

// 3. The best within budget (else the smallest), and the smallest within tolerance of it.
void PickCandidate(const PcaChoiceOptions& o, PcaChoice* choice) {
  for (size_t i = 0; i < choice->candidates.size(); ++i) {
    const auto& c = choice->candidates[i];
    if (c.within_budget && (choice->best < 0 || c.psnr_db > choice->candidates[choice->best].psnr_db))
      choice->best = static_cast<int>(i);
  }
  if (choice->best < 0) {
    // Nothing fits the budget: the smallest candidate, said so.
    for (size_t i = 0; i < choice->candidates.size(); ++i) {
      if (choice->best < 0 ||
          choice->candidates[i].bytes_per_pixel < choice->candidates[choice->best].bytes_per_pixel)
        choice->best = static_cast<int>(i);
    }
    choice->chosen = choice->best;
    return;
  }
  const double floor_db = choice->candidates[choice->best].psnr_db - o.tolerance_db;
  for (size_t i = 0; i < choice->candidates.size(); ++i) {
    const auto& c = choice->candidates[i];
    if (!c.within_budget || c.psnr_db < floor_db) continue;
    if (choice->chosen < 0 ||
        c.bytes_per_pixel < choice->candidates[choice->chosen].bytes_per_pixel)
      choice->chosen = static_cast<int>(i);
  }
}

}  // namespace

Result<PcaChoice> ChoosePca(const PcaChoiceInput& in, const PcaComponents& comps,
                            const PcaChoiceOptions& o) {
  const LightSamples& s = in.sampled;  // directions and the sampled pixels' samples
  if (s.pixels() != comps.subset.size() || in.crop.pixels() == 0) {
    return MakeError(ErrorCode::kInternal, "pca choice", "{} sampled pixels for {} in the subset",
                     s.pixels(), comps.subset.size());
  }
  const int lights = s.lights();
  int kmax = 0;
  for (int k : o.components) kmax = std::max(kmax, k);
  kmax = std::min<int>(kmax, static_cast<int>(comps.vectors.cols()));
  if (kmax < 1 || o.resolutions.empty() || o.qualities.empty()) {
    return MakeError(ErrorCode::kInvalidInput, "pca choice", "no candidates");
  }
  const double pixels = static_cast<double>(in.pixels);
  RIG_ASSIGN_OR_RETURN(std::vector<GridModelError> by_grid, HeldOutModelErrors(s, comps, o, &kmax));
  const PcaBasis& mid_basis = by_grid[by_grid.size() / 2].full_basis;
  RIG_ASSIGN_OR_RETURN(JpegCost jpeg, JpegCosts(in.crop, mid_basis, o, kmax, pixels));
  const std::vector<double> basis_power = BasisPower(mid_basis, s.directions, kmax);

  // Every candidate, and the choice.
  PcaChoice choice;
  choice.options = o.base;
  const double fixed_json = 400 + lights * 3 * 7.0;  // keys, materials, the lights' 3 decimals
  for (const auto& g : by_grid) {
    for (int k : o.components) {
      if (k > kmax) continue;
      for (size_t qi = 0; qi < o.qualities.size(); ++qi) {
        PcaCandidate c;
        c.components = k;
        c.resolution = g.res;
        c.quality = o.qualities[qi];
        c.validation_mse = g.mse_by_k[k];
        for (int p = 0; p < k; ++p) c.jpeg_mse += jpeg.plane_err[qi][p] * basis_power[p];
        c.psnr_db = 10 * std::log10(255.0 * 255.0 / std::max(c.validation_mse + c.jpeg_mse, 1e-9));
        double bytes = fixed_json + BasisJsonBytes(g.full_basis, k);
        for (int j = 0; j < (k + 2) / 3; ++j) bytes += jpeg.file_bytes[qi][j];
        c.bytes_per_pixel = bytes / pixels;
        c.within_budget = c.bytes_per_pixel <= o.max_bytes_per_pixel;
        choice.candidates.push_back(c);
      }
    }
  }
  PickCandidate(o, &choice);
  const auto& ch = choice.candidates[choice.chosen];
  const auto& best = choice.candidates[choice.best];
  choice.options.components = ch.components;
  choice.options.grid_resolution = ch.resolution;
  choice.options.jpeg_quality = ch.quality;
  choice.reason = fmt::format(
      "{} components on a {}x{} grid at JPEG q{}: {:.2f} dB at held-out lights ({}) — the smallest of {} candidates within {:.2f} dB of the best "
      "in the budget of {:.2f} B/px (the best: {} components, {}x{}, q{}, {:.2f} dB)",
      ch.components, ch.resolution, ch.resolution, ch.quality, ch.psnr_db, PcaChoiceSplitWords(o),
      choice.candidates.size(), o.tolerance_db, o.max_bytes_per_pixel, best.components,
      best.resolution, best.resolution, best.quality, best.psnr_db);
  if (!best.within_budget) {
    choice.reason = fmt::format("no candidate fits {:.2f} B/px; the smallest: {}",
                                o.max_bytes_per_pixel, choice.reason);
  }
  return choice;
}

PcaChoiceOptions PcaChoiceForBudget(double max_bytes_per_pixel) {
  PcaChoiceOptions o;
  o.max_bytes_per_pixel = max_bytes_per_pixel;
  if (max_bytes_per_pixel >= kPcaLargeCandidatesFromBytesPerPixel) {
    o.components.push_back(24);
    o.components.push_back(30);
  }
  return o;
}

int LargestCandidate(const PcaChoiceOptions& o) {
  int kmax = 1;
  for (int k : o.components) kmax = std::max(kmax, k);
  return kmax;
}

Result<PcaModel> FitPcaChosen(const LightSamples& samples, const PcaComponents& components,
                              const PcaOptions& po, PcaFitStats* stats) {
  RIG_ASSIGN_OR_RETURN(PcaBasis basis,
                       FitPcaBasis(components, po.components, po.grid_resolution, po.smoothness));
  return FitPcaCoefficients(samples, std::move(basis), po, components.subset, stats);
}

Result<PcaAutoFit> FitPcaAuto(const LightSamples& samples, const PcaComponents* given,
                              const PcaChoiceOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  PcaComponents own;
  if (!given) {
    RIG_ASSIGN_OR_RETURN(own, ComputePcaComponents(samples, o.base, LargestCandidate(o)));
    given = &own;
  }
  const auto t1 = std::chrono::steady_clock::now();
  PcaAutoFit out;
  RIG_ASSIGN_OR_RETURN(out.choice, ChoosePca(samples, *given, o));
  const auto t2 = std::chrono::steady_clock::now();
  RIG_ASSIGN_OR_RETURN(out.model,
                       FitPcaChosen(samples, *given, out.choice.options, &out.stats));
  const auto t3 = std::chrono::steady_clock::now();
  out.stats.time_s = std::chrono::duration<double>(t3 - t0).count();
  auto s = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
  Log("process")->debug("pca fit components_s={:.3f} choice_s={:.3f} model_s={:.3f}", s(t0, t1),
                        s(t1, t2), s(t2, t3));
  return out;
}

std::string PcaChoiceMarkdown(const PcaChoice& choice) {
  std::string md =
      "| components | grid | JPEG q | held-out PSNR (dB) | model MSE | JPEG MSE | B/px (est.) | |\n"
      "|---|---|---|---|---|---|---|---|\n";
  for (size_t i = 0; i < choice.candidates.size(); ++i) {
    const auto& c = choice.candidates[i];
    const char* mark = static_cast<int>(i) == choice.chosen ? "**chosen**"
                       : static_cast<int>(i) == choice.best ? "best"
                       : c.within_budget                    ? ""
                                                            : "over budget";
    md += fmt::format("| {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {} |\n", c.components,
                      c.resolution, c.quality, c.psnr_db, c.validation_mse, c.jpeg_mse,
                      c.bytes_per_pixel, mark);
  }
  return md;
}

}  // namespace rig
