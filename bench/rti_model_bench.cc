// Model families on a real multi-light capture: leave-one-out PSNR (refitting without each
// image, 8-bit sRGB) against bytes per pixel on disk and fit time, with relight's published
// figures on the shared icon beside them.
//   rti_model_bench [--lp FILE.lp] [--every N] [--k 3,6,9] [--res 8,12] [--quality 95]
//                   [--mask hinge,drop,none]
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "process/model/holdout.h"
#include "process/model/pca/pca.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/harmonic/loo.h"

namespace {

std::vector<int> Ints(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stoi(item));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace rig;
  std::string lp = std::string(RIG_SHARED_DIR_FOR_BENCH) + "/data/rti/neuralrti-example/dirs.lp";
  int every = 1;
  std::vector<int> ks = {9}, resolutions = {12}, qualities = {95};
  std::vector<std::string> masks = {"hinge"};
  bool automatic = false;
  int impute = 1;
  double budget = 3.4;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i], v = argv[i + 1];
    if (a == "--lp") lp = v;
    else if (a == "--auto") automatic = v == "1";
    else if (a == "--budget") budget = std::stod(v);
    else if (a == "--impute") impute = std::stoi(v);
    else if (a == "--every") every = std::stoi(v);
    else if (a == "--k") ks = Ints(v);
    else if (a == "--res") resolutions = Ints(v);
    else if (a == "--quality") qualities = Ints(v);
    else if (a == "--mask") {
      masks.clear();
      std::stringstream ss(v);
      std::string m;
      while (std::getline(ss, m, ',')) masks.push_back(m);
    } else {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    }
  }
  auto entries = ReadLp(lp);
  if (!entries.ok()) {
    std::fprintf(stderr, "%s\n", entries.error().ToString().c_str());
    return 1;
  }
  std::vector<cv::Mat> images;
  std::vector<Vec3> lights;
  for (const auto& e : *entries) {
    images.push_back(cv::imread(e.image, cv::IMREAD_COLOR));
    lights.push_back(e.direction);
  }
  const LightSamples all = SamplesFromImages(images, lights);
  std::vector<int> held;
  for (int l = 0; l < all.lights(); l += every) held.push_back(l);
  std::printf("%s: %d images %dx%d, %zu held out one at a time (refit without each)\n\n",
              lp.c_str(), all.lights(), all.width, all.height, held.size());
  std::printf("| family | k | grid | JPEG q | mask | LOO PSNR mean-MSE / median (dB) | B/px | fit s (all images) |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  const std::string tmp = (std::filesystem::temp_directory_path() /
                           fmt::format("rti_model_bench_{}", ::getpid())).string();
  if (automatic) {
    PcaChoiceOptions co = PcaChoiceForBudget(budget);
    co.base.impute_iterations = impute;
    auto full = ComputePcaComponents(all, co.base, LargestCandidate(co));
    if (!full.ok()) return 1;
    std::vector<std::string> chosen;
    auto score = LeaveOneOut(all, held, [&](const LightSamples& fold, int l, const Vec3& light)
                                            -> Result<FoldPrediction> {
      // Imputation reads every light of a pixel: a fold's components are then its own.
      PcaComponents comps;
      if (co.base.mask != PcaMaskMode::kNone && co.base.impute_iterations > 0) {
        RIG_ASSIGN_OR_RETURN(comps, ComputePcaComponents(fold, co.base, LargestCandidate(co)));
      } else {
        comps = PcaComponentsWithout(*full, {l}, LargestCandidate(co));
      }
      RIG_ASSIGN_OR_RETURN(PcaAutoFit fit, FitPcaAuto(fold, &comps, co));
      const auto& c = fit.choice.candidates[fit.choice.chosen];
      chosen.push_back(fmt::format("{}/{}/q{}", c.components, c.resolution, c.quality));
      std::filesystem::remove_all(tmp);  // no planes of a larger fold's model left behind
    RIG_TRY(fit.model.Save(tmp));
      RIG_ASSIGN_OR_RETURN(PcaModel back, PcaModel::Load(tmp));
      return FoldPrediction{back.Render(light), FolderBytes(tmp)};
    });
    if (!score.ok()) {
      std::fprintf(stderr, "%s\n", score.error().ToString().c_str());
      return 1;
    }
    const auto t0 = std::chrono::steady_clock::now();
    auto fit = FitPcaAuto(all, nullptr, co);
    const double fit_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("| pca auto (budget %.2f) | | | | hinge | %.2f / %.2f | %.2f | %.2f |\n\n", budget,
                score->psnr_mean_mse_db, score->psnr_median_db, score->bytes_per_pixel, fit_s);
    std::printf("choice on all images: %s\n\n%s\nper fold:", fit->choice.reason.c_str(),
                PcaChoiceMarkdown(fit->choice).c_str());
    for (size_t i = 0; i < chosen.size(); ++i) std::printf(" %d:%s", held[i] + 1, chosen[i].c_str());
    std::printf("\nper image PSNR:");
    for (size_t i = 0; i < score->mse.size(); ++i) std::printf(" %d:%.1f", held[i] + 1, PsnrFromMse(score->mse[i]));
    std::printf("\n");
    std::filesystem::remove_all(tmp);
    return 0;
  }
  for (int k : ks) {
    for (int res : resolutions) {
      for (int q : qualities) {
        for (const auto& mask : masks) {
          PcaOptions o;
          o.components = k;
          o.grid_resolution = res;
          o.jpeg_quality = q;
          o.mask = mask == "none" ? PcaMaskMode::kNone
                   : mask == "drop" ? PcaMaskMode::kDrop : PcaMaskMode::kHinge;
          auto score = LeaveOneOut(all, held, [&](const LightSamples& fold, int, const Vec3& light)
                                                  -> Result<FoldPrediction> {
            RIG_ASSIGN_OR_RETURN(PcaModel m, FitPca(fold, o));
            std::filesystem::remove_all(tmp);
    RIG_TRY(m.Save(tmp));
            RIG_ASSIGN_OR_RETURN(PcaModel back, PcaModel::Load(tmp));
            return FoldPrediction{back.Render(light), FolderBytes(tmp)};
          });
          if (!score.ok()) {
            std::fprintf(stderr, "%s\n", score.error().ToString().c_str());
            return 1;
          }
          const auto t0 = std::chrono::steady_clock::now();
          PcaFitStats stats;
          auto full = FitPca(all, o, &stats);
          const double fit_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          std::printf("| pca-bilinear | %d | %d | %d | %s | %.2f / %.2f | %.2f | %.2f |\n", k, res, q,
                      mask.c_str(), score->psnr_mean_mse_db, score->psnr_median_db,
                      score->bytes_per_pixel, fit_s);
          std::fflush(stdout);
        }
      }
    }
  }
  std::filesystem::remove_all(tmp);
  std::printf("\nrelight-cli on the same icon (../shared/docs/rti-formats.md): rbf 9 planes 26.11 / 29.51 "
              "at 3.35 B/px; bilinear 25.98 / 32.41 at 3.35; hsh 9 22.73 / 26.11 at 4.27; ptm 20.09 / "
              "23.02 at 2.75 (all 72 held out); every 6th: rbf 24.52 / 30.61, bilinear 26.59 / 34.13\n");
  return 0;
}
