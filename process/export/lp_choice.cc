// The choice across families per byte (see lp_choice.h).
#include "process/export/lp_choice.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/export/relight_fit.h"
#include "process/io/jpeg_io.h"
#include "process/model/pca/pca.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

double LpChoiceSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::string LpBasisName(const RelightTarget& t) {
  return fmt::format("{} {}", RelightTypeName(t.type), t.terms);
}

// The mask the final fit leaves out (LoadRtiCapture's), applied to samples gathered without it.
void LpChoiceMask(const PcaChoiceOptions& o, LightSamples* s) {
  if (o.base.mask != PcaMaskMode::kNone) MaskLdrSamples(s, o.base.thresholds);
}

// Mean square of every term's weight over the lights: what a coefficient's error costs in the
// renders at those lights (errors of different planes taken as independent, as PCA's are).
std::vector<double> LpWeightPower(const RelightTarget& t, const std::vector<Vec3>& lights) {
  std::vector<double> power(t.terms, 0);
  double w[kMaxRelightTerms];
  for (const Vec3& d : lights) {
    RelightWeights(t.type, t.terms, d, w);
    for (int j = 0; j < t.terms; ++j) power[j] += w[j] * w[j];
  }
  for (double& p : power) p /= std::max<size_t>(1, lights.size());
  return power;
}

// 8-bit MSE at the held-out lights of the coefficients fitted without them.
double LpHeldOutMse(const LightSamples& picked, const RelightCoefficients& c, const std::vector<int>& held) {
  double sum = 0;
  const size_t n = picked.pixels();
  for (int l : held) {
    const cv::Mat r = RenderRelight(c, picked.directions[l]);
    const float* pr = r.ptr<float>();
    for (size_t i = 0; i < n; ++i)
      for (int ch = 0; ch < 3; ++ch) {
        const float v = std::clamp(std::nearbyint(pr[i * 3 + (2 - ch)]), 0.0f, 255.0f);
        const double d = v - picked.value(i, l, ch);
        sum += d * d;
      }
  }
  return sum / static_cast<double>(std::max<size_t>(1, held.size() * n * 3));
}

// Every quality's plane files for the crop's coefficients: their bytes (scaled to the image)
// and the renders' error they add, from each plane's error through 8 bits and JPEG.
Result<std::vector<BasisCandidate>> LpJpegCandidates(const RelightCoefficients& crop, const RelightTarget& t,
                                                   const PcaChoiceOptions& o, double pixels) {
  const std::vector<double> power = LpWeightPower(t, crop.lights);
  std::vector<BasisCandidate> out;
  const int nplanes = 3 * t.terms;
  for (int q : o.qualities) {
    WebWriteOptions wo;
    wo.quality = q;
    const RelightWebPlanes planes = QuantiseRelightWeb(crop, wo);
    BasisCandidate c;
    c.target = t;
    c.quality = q;
    // info.json as written, the crop's ranges standing for the image's (the same digits).
    double bytes = static_cast<double>(RelightWebInfo(crop, planes, wo).size());
    for (size_t j = 0; j < planes.files.size(); ++j) {
      RIG_ASSIGN_OR_RETURN(auto enc, EncodeJpeg(planes.files[j], JpegColor::kYcbcr, q));
      bytes += static_cast<double>(enc.size()) * pixels / static_cast<double>(crop.width * crop.height);
      RIG_ASSIGN_OR_RETURN(cv::Mat back, DecodeJpeg(enc, "lp choice"));
      for (int k = 0; k < 3 && static_cast<int>(3 * j) + k < nplanes; ++k) {
        const int p = static_cast<int>(3 * j) + k, term = p / 3, channel = p % 3;  // R, G, B
        const double scale = planes.scale[p], bias = planes.bias[p];
        double e = 0;
        for (int y = 0; y < crop.height; ++y) {
          const uint8_t* b = back.ptr<uint8_t>(y);
          const float* orig = crop.planes[term].ptr<float>(y);
          for (int x = 0; x < crop.width; ++x) {
            const double d = (b[3 * x + k] - 255.0 * bias) * scale - orig[3 * x + (2 - channel)];
            e += d * d;
          }
        }
        c.jpeg_mse += e / static_cast<double>(crop.width * crop.height) * power[term] / 3.0;
      }
    }
    c.bytes_per_pixel = bytes / pixels;
    c.within_budget = c.bytes_per_pixel <= o.max_bytes_per_pixel;
    out.push_back(c);
  }
  return out;
}

// Every basis at every quality on the PCA choice's splits and crop.
Result<std::vector<BasisCandidate>> LpScoreBases(const PcaChoiceInput& in, const PcaChoiceOptions& o) {
  const LightSamples& s = in.sampled;
  LightSamples picked = PcaChoicePickPixels(s, PcaChoiceEvalPixels(s.pixels(), o));
  LpChoiceMask(o, &picked);
  // What 8 bits and JPEG do to the planes hardly depends on how masked samples were fitted
  // around (as for PCA's planes): the crop is fitted by one pseudo-inverse.
  const LightSamples& crop = in.crop;
  RelightFitOptions fo;
  fo.every = 0;
  fo.threads = o.base.threads;
  fo.fitted_psnr = false;
  std::vector<BasisCandidate> out;
  for (const RelightTarget& t : LpChoiceBases()) {
    double sum = 0, count = 0;
    for (int r = 0; r < PcaChoiceSplits(o); ++r) {
      const std::vector<int> held = PcaChoiceHeldOutLights(s.lights(), o, r);
      std::vector<int> kept;
      for (int l = 0; l < s.lights(); ++l)
        if (std::find(held.begin(), held.end(), l) == held.end()) kept.push_back(l);
      if (static_cast<int>(kept.size()) < t.terms) continue;
      RIG_ASSIGN_OR_RETURN(RelightFit fold, FitRelightToSamples(OnlyLights(picked, kept), t, fo));
      sum += LpHeldOutMse(picked, fold.coefficients, held) * static_cast<double>(held.size());
      count += static_cast<double>(held.size());
    }
    if (count == 0) continue;
    RIG_ASSIGN_OR_RETURN(RelightFit whole, FitRelightToSamples(crop, t, fo));
    RIG_ASSIGN_OR_RETURN(auto cands, LpJpegCandidates(whole.coefficients, t, o,
                                                    static_cast<double>(in.pixels)));
    for (auto& c : cands) {
      c.validation_mse = sum / count;
      c.psnr_db = 10 * std::log10(255.0 * 255.0 / std::max(c.validation_mse + c.jpeg_mse, 1e-9));
      out.push_back(c);
    }
  }
  return out;
}

std::string LpPcaWords(const PcaCandidate& c) {
  return fmt::format("pca {} components, {}x{} grid, q{}", c.components, c.resolution,
                     c.resolution, c.quality);
}
std::string LpBasisWords(const BasisCandidate& c) {
  return fmt::format("{} terms rgb, 8-bit planes, q{}", LpBasisName(c.target), c.quality);
}

}  // namespace

std::vector<RelightTarget> LpChoiceBases() {
  return {{RelightType::kHsh, 4, false}, {RelightType::kPtm, 6, false}, {RelightType::kHsh, 9, false}};
}

std::string LpChosenWords(const LpChoice& c) {
  if (c.basis_chosen >= 0) return LpBasisWords(c.bases[c.basis_chosen]);
  if (c.pca.chosen >= 0) return LpPcaWords(c.pca.candidates[c.pca.chosen]);
  return "nothing";
}

Result<LpChoice> ChooseLpModel(const PcaChoiceInput& in, const PcaComponents& comps,
                               const PcaChoiceOptions& o, bool with_bases) {
  LpChoice out;
  RIG_ASSIGN_OR_RETURN(out.pca, ChoosePca(in, comps, o));
  out.family = "pca-bilinear";
  out.reason = out.pca.reason;
  const auto& pca_best = out.pca.candidates[out.pca.best];
  out.best_psnr_db = pca_best.psnr_db;
  out.best = LpPcaWords(pca_best);
  if (!with_bases) return out;
  RIG_ASSIGN_OR_RETURN(out.bases, LpScoreBases(in, o));

  // One rule across both families, PCA's: the best within budget (else the smallest of all),
  // then the smallest within the tolerance of it.
  struct Entry { bool basis; int index; double psnr, bpp; bool within; };
  std::vector<Entry> all;
  for (size_t i = 0; i < out.pca.candidates.size(); ++i) {
    const auto& c = out.pca.candidates[i];
    all.push_back({false, static_cast<int>(i), c.psnr_db, c.bytes_per_pixel, c.within_budget});
  }
  for (size_t i = 0; i < out.bases.size(); ++i) {
    const auto& c = out.bases[i];
    all.push_back({true, static_cast<int>(i), c.psnr_db, c.bytes_per_pixel, c.within_budget});
  }
  int best = -1, chosen = -1;
  for (size_t i = 0; i < all.size(); ++i)
    if (all[i].within && (best < 0 || all[i].psnr > all[best].psnr)) best = static_cast<int>(i);
  if (best < 0) {
    for (size_t i = 0; i < all.size(); ++i)
      if (best < 0 || all[i].bpp < all[best].bpp) best = static_cast<int>(i);
    chosen = best;
  } else {
    for (size_t i = 0; i < all.size(); ++i) {
      if (!all[i].within || all[i].psnr < all[best].psnr - o.tolerance_db) continue;
      if (chosen < 0 || all[i].bpp < all[chosen].bpp) chosen = static_cast<int>(i);
    }
  }
  auto words = [&](const Entry& e) {
    return e.basis ? LpBasisWords(out.bases[e.index]) : LpPcaWords(out.pca.candidates[e.index]);
  };
  out.best_psnr_db = all[best].psnr;
  out.best = words(all[best]);
  const Entry& ch = all[chosen];
  if (ch.basis) {
    out.pca.chosen = -1;
    out.basis_chosen = ch.index;
    out.family = RelightTypeName(out.bases[ch.index].target.type);
  } else {
    const auto& c = out.pca.candidates[ch.index];
    out.pca.chosen = ch.index;
    out.pca.options.components = c.components;
    out.pca.options.grid_resolution = c.resolution;
    out.pca.options.jpeg_quality = c.quality;
  }
  out.reason = fmt::format(
      "{}: {:.2f} dB at held-out lights ({}) — the smallest "
      "of {} candidates ({} pca, {} of relight's bases in 8-bit planes) within {:.2f} dB of the "
      "best in the budget of {:.2f} B/px (the best: {}, {:.2f} dB)",
      words(ch), ch.psnr, PcaChoiceSplitWords(o), all.size(), out.pca.candidates.size(),
      out.bases.size(), o.tolerance_db, o.max_bytes_per_pixel, out.best, all[best].psnr);
  if (!all[best].within)
    out.reason = fmt::format("no candidate fits {:.2f} B/px; the smallest: {}", o.max_bytes_per_pixel, out.reason);
  return out;
}

Result<LpAutoFit> FitLpAuto(const LightSamples& samples, const PcaComponents* given,
                            const PcaChoiceOptions& o, bool with_bases, const std::string& near_lamp) {
  const auto t0 = Clock::now();
  PcaComponents own;
  if (!given) {
    RIG_ASSIGN_OR_RETURN(own, ComputePcaComponents(samples, o.base, LargestCandidate(o)));
    given = &own;
  }
  LpAutoFit out;
  // A near lamp's division is recorded in the model, and only the PCA folder has the field.
  RIG_ASSIGN_OR_RETURN(out.choice, ChooseLpModel(PcaChoiceInputOf(samples, given->subset), *given,
                                                 o, with_bases && near_lamp.empty()));
  if (out.choice.basis_chosen < 0) {
    RIG_ASSIGN_OR_RETURN(PcaModel m, FitPcaChosen(samples, *given, out.choice.pca.options, &out.stats));
    m.set_near_lamp(near_lamp);
    out.model = WrapPca(std::move(m));
  } else {
    const BasisCandidate& c = out.choice.bases[out.choice.basis_chosen];
    RelightFitOptions fo;
    fo.every = 0;
    fo.threads = o.base.threads;
    fo.fitted_psnr = false;
    RIG_ASSIGN_OR_RETURN(RelightFit fit, FitRelightToSamples(samples, c.target, fo));
    out.refitted_pixels = fit.refitted_pixels;
    out.model = WrapRelight(std::move(fit.coefficients), "", c.quality);
  }
  out.time_s = LpChoiceSince(t0);
  return out;
}

std::string LpChoiceMarkdown(const LpChoice& choice) {
  std::string md = "PCA's candidates:\n\n" + PcaChoiceMarkdown(choice.pca);
  if (choice.bases.empty()) return md;
  md += "\nrelight's bases, rgb, in 8-bit JPEG planes (its web format):\n\n"
        "| basis | JPEG q | held-out PSNR (dB) | model MSE | planes' MSE | B/px (est.) | |\n"
        "|---|---|---|---|---|---|---|\n";
  for (size_t i = 0; i < choice.bases.size(); ++i) {
    const auto& c = choice.bases[i];
    const char* mark = static_cast<int>(i) == choice.basis_chosen ? "**chosen**"
                       : c.within_budget                          ? ""
                                                                  : "over budget";
    md += fmt::format("| {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {} |\n", LpBasisName(c.target),
                      c.quality, c.psnr_db, c.validation_mse, c.jpeg_mse, c.bytes_per_pixel, mark);
  }
  return md;
}

Result<RtiFitResult> FitRtiAcrossFamilies(const RtiCapture& cap, const RtiFitRequest& req) {
  const bool sized = req.components > 0 || req.grid_resolution > 0 || req.jpeg_quality > 0;
  if (req.family != "auto" || sized) return FitRti(cap, req);
  if (const auto below = LightsBelowHorizon(cap); !below.empty()) return FitRti(cap, req);  // its refusal
  RtiFitResult out;
  out.report = RtiReportHeader(cap, req);
  RIG_ASSIGN_OR_RETURN(LpAutoFit fit, FitLpAuto(cap.samples, nullptr, req.choice, true, req.near_lamp));
  out.fit_time_s = fit.time_s;
  out.family = fit.model->family();
  out.summary = fmt::format("{}, {}", out.family, fit.choice.reason);
  out.report += fmt::format(
      "## Choice\n\n{}.\n\nSamples fitted around: {} ({} pixels solved around masked samples, "
      "mask {}).\n\n",
      fit.choice.reason, fit.choice.basis_chosen < 0 ? fmt::format("{} sample-channels", fit.stats.masked_samples) : std::string("the masked samples left out"),
      fit.choice.basis_chosen < 0 ? fit.stats.refitted_pixels : fit.refitted_pixels,
      PcaMaskModeName(req.choice.base.mask));
  out.report += LpChoiceMarkdown(fit.choice);
  out.model = std::move(fit.model);
  return out;
}

}  // namespace rig
