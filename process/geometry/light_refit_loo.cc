// Leave-one-out of the default model with given and with re-estimated light directions.
#include "process/geometry/light_refit_loo.h"

#include <filesystem>

#include <unistd.h>

#include "process/geometry/photometric_stereo.h"
#include "process/geometry/sphere_lights.h"
#include "process/model/holdout.h"

namespace rig {
namespace {

LightStack Without(const LightStack& s, int held) {
  LightStack out;
  out.width = s.width;
  out.height = s.height;
  for (size_t k = 0; k < s.size(); ++k) {
    if (static_cast<int>(k) == held) continue;
    out.names.push_back(s.names[k]);
    out.linear.push_back(s.linear[k]);
    if (!s.clipped.empty()) out.clipped.push_back(s.clipped[k]);
    out.directions.push_back(s.directions[k]);
  }
  return out;
}

}  // namespace

Result<std::vector<LightLooRow>> CompareLightsLoo(const RtiCapture& capture,
                                                  const LightStack& stack, int every, int rounds,
                                                  const PcaChoiceOptions& choice, int threads) {
  const LightSamples& all = capture.samples;
  if (static_cast<int>(stack.size()) != all.lights())
    return MakeError(ErrorCode::kInvalidInput, capture.lp, "the stack and the capture differ");
  std::vector<int> folds;
  for (int l = 0; l < all.lights(); l += std::max(1, every)) folds.push_back(l);
  PcaChoiceOptions co = choice;
  co.base.threads = threads;
  PsOptions ps_options;
  ps_options.threads = threads;
  const std::string tmp = (std::filesystem::temp_directory_path() /
                           ("rig-lights-loo-" + std::to_string(getpid()))).string();
  std::vector<LightLooRow> rows;
  for (bool reestimate : {false, true}) {
    auto score = LeaveOneOut(all, folds, [&](const LightSamples& fold, int held,
                                             const Vec3& light) -> Result<FoldPrediction> {
      LightSamples f = fold;
      Vec3 held_light = light;
      if (reestimate) {
        LightStack fs = Without(stack, held);
        f.directions = RefineLightsFromImages(fs, fs.directions, rounds, ps_options);
        fs.directions = f.directions;
        RIG_ASSIGN_OR_RETURN(PsResult ps, PhotometricStereo(fs, fs.directions, ps_options));
        held_light = EstimateLight(stack.linear[held],
                                   stack.clipped.empty() ? cv::Mat() : stack.clipped[held], ps,
                                   light);
      }
      RIG_ASSIGN_OR_RETURN(PcaAutoFit fit, FitPcaAuto(f, nullptr, co));
      std::filesystem::remove_all(tmp);
      RIG_TRY(fit.model.Save(tmp));
      RIG_ASSIGN_OR_RETURN(PcaModel back, PcaModel::Load(tmp));
      return FoldPrediction{back.Render(held_light), FolderBytes(tmp)};
    });
    std::filesystem::remove_all(tmp);
    if (!score.ok()) return score.error();
    LightLooRow row;
    row.lights = reestimate ? "re-estimated from the images" : "as given (.lp)";
    row.psnr_mean_mse_db = score->psnr_mean_mse_db;
    row.psnr_median_db = score->psnr_median_db;
    row.bytes_per_pixel = score->bytes_per_pixel;
    row.folds = static_cast<int>(folds.size());
    if (reestimate) {
      const auto dirs = RefineLightsFromImages(stack, stack.directions, rounds, ps_options);
      double sum = 0;
      for (size_t k = 0; k < dirs.size(); ++k) sum += AngleDeg(dirs[k], stack.directions[k]);
      row.mean_change_deg = sum / dirs.size();
    }
    rows.push_back(row);
  }
  return rows;
}

}  // namespace rig
