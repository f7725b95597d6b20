// Scoring a subset of a capture's lights by the default model fitted on it alone.
#include "process/evaluate/light_subset.h"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "process/model/holdout.h"
#include "process/model/pca/pca.h"
#include "process/model/pca/pca_choice.h"

namespace rig {

Result<LightSubsetScore> ScoreLightSubset(const RtiCapture& capture, const std::vector<int>& fitted,
                                          const std::vector<int>& held_out,
                                          const std::string& scratch) {
  for (int l : held_out) {
    if (std::find(fitted.begin(), fitted.end(), l) != fitted.end()) {
      return MakeError(ErrorCode::kInvalidInput, capture.lp, "light {} is both fitted and held out",
                       l + 1);
    }
  }
  if (held_out.empty()) return MakeError(ErrorCode::kInvalidInput, capture.lp, "no held-out light");
  const LightSamples subset = OnlyLights(capture.samples, fitted);
  RIG_ASSIGN_OR_RETURN(PcaAutoFit fit, FitPcaAuto(subset, nullptr, PcaChoiceOptions{}));
  std::filesystem::remove_all(scratch);
  RIG_TRY(fit.model.Save(scratch));
  RIG_ASSIGN_OR_RETURN(PcaModel back, PcaModel::Load(scratch));
  LightSubsetScore out;
  out.model = fit.choice.reason;
  out.bytes_per_pixel = static_cast<double>(FolderBytes(scratch)) /
                        static_cast<double>(capture.samples.pixels());
  std::vector<double> mse, psnr;
  for (int l : held_out) {
    mse.push_back(EightBitMse(capture.samples, l, back.Render(capture.samples.directions[l])));
    psnr.push_back(PsnrFromMse(mse.back()));
  }
  double sum = 0;
  for (double m : mse) sum += m;
  out.psnr_mean_mse_db = PsnrFromMse(sum / static_cast<double>(mse.size()));
  std::sort(psnr.begin(), psnr.end());
  const size_t n = psnr.size();
  out.psnr_median_db = n % 2 ? psnr[n / 2] : 0.5 * (psnr[n / 2 - 1] + psnr[n / 2]);
  return out;
}

std::vector<int> LightsInNone(int lights, const std::vector<std::vector<int>>& sets) {
  std::vector<int> out;
  for (int l = 0; l < lights; ++l) {
    bool in_any = false;
    for (const auto& s : sets) in_any = in_any || std::find(s.begin(), s.end(), l) != s.end();
    if (!in_any) out.push_back(l);
  }
  return out;
}

}  // namespace rig
