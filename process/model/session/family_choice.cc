// The session's model family chosen per byte at held-out lamps (see family_choice.h).
#include "process/model/session/family_choice.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include "process/model/harmonic/model.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

double ChoiceSeconds(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

double RelativeOf(const std::vector<double>& per_lamp) {
  double s = 0;
  for (double e : per_lamp) s += e;
  return std::sqrt(s);
}

// The harmonic family fitted to the maps without the held-out lamps (its order and λ chosen
// from those maps alone) and scored at the held-out lamps.
Result<FamilyCandidate> ScoreHarmonic(const std::vector<cv::Mat>& radiance,
                                      const std::vector<Vec3>& directions,
                                      const std::vector<int>& held,
                                      const std::array<double, 3>& lamp,
                                      const FitOptions& options, int value_bytes) {
  const auto t0 = Clock::now();
  FitInput in;
  in.lamp_radiance_rgb = lamp;
  for (size_t l = 0; l < radiance.size(); ++l) {
    if (std::find(held.begin(), held.end(), static_cast<int>(l)) != held.end()) continue;
    in.radiance.push_back(radiance[l]);
    in.directions.push_back(directions[l]);
  }
  RIG_ASSIGN_OR_RETURN(FitOutput fit, FitModel(in, options));
  FamilyCandidate c;
  c.family = "harmonic";
  const int terms = static_cast<int>(fit.model.basis().size());
  c.what = fmt::format("{} order {}, {} terms", fit.model.basis().name(), fit.selection.order, terms);
  c.size = fit.selection.order;
  c.bytes_per_pixel = static_cast<double>(terms) * 3 * value_bytes;
  c.per_lamp = HeldOutErrors(*WrapHarmonic(std::move(fit.model)), radiance, directions, held, lamp);
  c.held_out_relative = RelativeOf(c.per_lamp);
  c.fit_s = ChoiceSeconds(t0);
  return c;
}

}  // namespace

Result<SessionFamilyChoice> ChooseSessionFamily(const std::vector<cv::Mat>& radiance,
                                                const std::vector<Vec3>& directions,
                                                const std::array<double, 3>& lamp,
                                                const FitOptions& harmonic, int value_bytes,
                                                const PcaHdrChoiceOptions& pca) {
  const auto t0 = Clock::now();
  SessionFamilyChoice out;
  const std::vector<int> held = ChoiceHeldOutLamps(directions, pca);
  out.held_out = static_cast<int>(held.size());
  out.held_out_rule = HeldOutRuleName(directions, pca);
  const auto tp = Clock::now();
  RIG_ASSIGN_OR_RETURN(out.pca, ChoosePcaHdr(radiance, directions, lamp, pca));
  const PcaHdrCandidate& p = out.pca.candidates[out.pca.chosen];
  out.pca_candidate.family = "pca";
  out.pca_candidate.what = fmt::format("{}, {} components, {}x{} grid, JPEG q{}", p.curve,
                                       p.components, p.resolution, p.resolution, p.quality);
  out.pca_candidate.size = p.components;
  out.pca_candidate.bytes_per_pixel = p.bytes_per_pixel;
  out.pca_candidate.per_lamp = p.per_lamp;
  out.pca_candidate.held_out_relative = p.held_out_relative;
  out.pca_candidate.fit_s = ChoiceSeconds(tp);
  RIG_ASSIGN_OR_RETURN(out.harmonic_candidate,
                       ScoreHarmonic(radiance, directions, held, lamp, harmonic, value_bytes));
  FamilyCandidate& a = out.pca_candidate;
  FamilyCandidate& b = out.harmonic_candidate;
  const bool pca_better = a.held_out_relative <= b.held_out_relative;
  FamilyCandidate& better = pca_better ? a : b;
  for (FamilyCandidate* c : {&a, &b}) PairedExcess(c->per_lamp, better.per_lamp, &c->excess, &c->excess_se);
  FamilyCandidate& smaller = a.bytes_per_pixel <= b.bytes_per_pixel ? a : b;
  FamilyCandidate& larger = &smaller == &a ? b : a;
  const bool smaller_within = smaller.excess <= pca.noise_z * smaller.excess_se;
  const FamilyCandidate& chosen = smaller_within ? smaller : larger;
  out.family = chosen.family;
  out.reason = fmt::format(
      "{} ({}, {:.1f} B/px): {:.4f} relative error at the {} lamps held out against {}'s {:.4f} "
      "({}, {:.1f} B/px) — {}", chosen.family, chosen.what, chosen.bytes_per_pixel,
      chosen.held_out_relative, out.held_out, (&chosen == &a ? b : a).family,
      (&chosen == &a ? b : a).held_out_relative, (&chosen == &a ? b : a).what,
      (&chosen == &a ? b : a).bytes_per_pixel,
      &chosen == &smaller
          ? (&smaller == &better ? "the smaller and the more accurate"
                                 : fmt::format("the smaller, within {:g} standard error of the other",
                                               pca.noise_z))
          : fmt::format("the larger: the smaller's excess error is {:.1f} standard errors",
                        smaller.excess_se > 0 ? smaller.excess / smaller.excess_se : INFINITY));
  out.time_s = ChoiceSeconds(t0);
  return out;
}

std::string SessionFamilyMarkdown(const SessionFamilyChoice& c) {
  std::string md = fmt::format(
      "## The family\n\nBoth families fitted to the maps without the same {} lamps ({}), "
      "each making its own choices from the rest, and scored there (relative RMS of linear "
      "reflectance); the smaller model unless the other's lower error is beyond one standard "
      "error of the paired excess across those lamps. {}.\n\n"
      "| family | model | B/px | held-out relative error | excess of its square (± standard "
      "error) | fit s | |\n|---|---|---|---|---|---|---|\n", c.held_out, c.held_out_rule, c.reason);
  for (const FamilyCandidate* f : {&c.pca_candidate, &c.harmonic_candidate})
    md += fmt::format("| {} | {} | {:.2f} | {:.4f} | {:.2e} ± {:.2e} | {:.2f} | {} |\n", f->family,
                      f->what, f->bytes_per_pixel, f->held_out_relative, f->excess, f->excess_se,
                      f->fit_s, f->family == c.family ? "**chosen**" : "");
  md += "\nThe harmonic model's bytes are its coefficient planes as the session's model file "
        "holds them uncompressed; the PCA model's are its files as written.\n\n### The PCA "
        "candidates\n\n" + PcaHdrChoiceMarkdown(c.pca);
  return md;
}

}  // namespace rig
