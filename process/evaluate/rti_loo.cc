// Leave-one-out of every family on a multi-light capture, refitting without each image.
#include "process/evaluate/rti_loo.h"
#include "config/atomic_file.h"
#include "config/console.h"
#include "process/io/image_io.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <algorithm>
#include <fstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include "process/evaluate/plot.h"
#include "process/export/lp_choice.h"
#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/model/any/load_model.h"
#include "process/model/holdout.h"
#include "process/model/neural/neural.h"
#include "process/model/harmonic/loo.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::vector<int> Folds(int lights, int every) {
  std::vector<int> out;
  for (int l = 0; l < lights; l += std::max(1, every)) out.push_back(l);
  return out;
}

std::string Protocol(int folds, int lights) {
  return folds == lights ? fmt::format("all {} refitted", lights)
                         : fmt::format("{} of {} refitted", folds, lights);
}

// A fold counted done when its prediction is made (or it failed).
struct FoldDone {
  ProgressTask& task;
  int held;
  ~FoldDone() { task.Advance(1, fmt::format("image {} held out", held + 1)); }
};

// The PCA family with the choice inside every fold.
// `across_families`: the default's choice, PCA beside relight's bases in 8-bit planes
// (FitLpAuto); otherwise the PCA family's own.
Result<RtiLooRow> PcaRow(const RtiCapture& cap, const PcaChoiceOptions& co,
                         const std::vector<int>& folds, const std::string& setting,
                         const std::string& tmp, bool across_families = false) {
  const int kmax = LargestCandidate(co);
  RIG_ASSIGN_OR_RETURN(PcaComponents full, ComputePcaComponents(cap.samples, co.base, kmax));
  ProgressTask task(across_families ? "the default refitted without each held-out image"
                                    : "pca refitted without each held-out image",
                    static_cast<int64_t>(folds.size()));
  size_t basis_folds = 0;
  // How the choice moves with the image left out: every fold's size on disk and what it took.
  std::vector<double> fold_bpp;
  std::map<std::string, int> fold_choices;
  const double pixels = static_cast<double>(cap.samples.pixels());
  auto score = LeaveOneOut(cap.samples, folds, [&](const LightSamples& fold, int held,
                                                   const Vec3& light) -> Result<FoldPrediction> {
    const FoldDone counted{task, held};
    // Imputing censored samples reads every light of a pixel, the held-out one too: the
    // fold's components are then computed from the fold; otherwise they are exactly the kept
    // covariance without the held-out light's rows and columns.
    PcaComponents comps;
    if (co.base.mask != PcaMaskMode::kNone && co.base.impute_iterations > 0) {
      RIG_ASSIGN_OR_RETURN(comps, ComputePcaComponents(fold, co.base, kmax));
    } else {
      comps = PcaComponentsWithout(full, {held}, kmax);
    }
    std::filesystem::remove_all(tmp);  // no planes of a larger fold's model left behind
    if (across_families) {
      RIG_ASSIGN_OR_RETURN(LpAutoFit fit, FitLpAuto(fold, &comps, co));
      RIG_TRY(fit.model->Save(tmp));
      fold_bpp.push_back(static_cast<double>(FolderBytes(tmp)) / pixels);
      ++fold_choices[LpChosenWords(fit.choice)];
      if (fit.choice.basis_chosen >= 0) {
        ++basis_folds;
        RIG_ASSIGN_OR_RETURN(RelightCoefficients back, ReadRelightWeb(tmp));
        cv::Mat encoded = RenderRelight(back, light);
        encoded *= 1.0 / 255.0;  // relight's values are codes
        return FoldPrediction{encoded, FolderBytes(tmp)};
      }
    } else {
      RIG_ASSIGN_OR_RETURN(PcaAutoFit fit, FitPcaAuto(fold, &comps, co));
      RIG_TRY(fit.model.Save(tmp));
    }
    RIG_ASSIGN_OR_RETURN(PcaModel back, PcaModel::Load(tmp));
    return FoldPrediction{back.Render(light), FolderBytes(tmp)};
  });
  if (!score.ok()) return score.error();
  const auto t0 = Clock::now();
  RtiLooRow row;
  row.family = "pca-bilinear";
  // What the same choice takes on every image, as `rig fit` would.
  if (across_families) {
    RIG_ASSIGN_OR_RETURN(LpAutoFit fit, FitLpAuto(cap.samples, nullptr, co));
    const size_t n = fit.choice.pca.candidates.size() + fit.choice.bases.size();
    if (fit.choice.basis_chosen >= 0)
      row.family = RelightTypeName(fit.choice.bases[fit.choice.basis_chosen].target.type);
    const auto [lo, hi] = std::minmax_element(fold_bpp.begin(), fold_bpp.end());
    int most = 0;
    for (const auto& [what, count] : fold_choices) most = std::max(most, count);
    row.setting = fmt::format(
        "{}; all images: {} (of {} candidates); a basis in {} of {} folds; the folds' sizes "
        "{:.2f}-{:.2f} B/px, {} distinct choices (the commonest in {})",
        setting, LpChosenWords(fit.choice), n, basis_folds, folds.size(),
        fold_bpp.empty() ? 0.0 : *lo, fold_bpp.empty() ? 0.0 : *hi, fold_choices.size(), most);
  } else {
    RIG_ASSIGN_OR_RETURN(PcaAutoFit fit, FitPcaAuto(cap.samples, nullptr, co));
    const PcaOptions& chosen = fit.choice.options;
    const size_t n_candidates = fit.choice.candidates.size();
    row.setting = fmt::format("{}; all images: k {}, {}x{} grid, q{} (of {} candidate{})", setting,
                              chosen.components, chosen.grid_resolution, chosen.grid_resolution,
                              chosen.jpeg_quality, n_candidates, n_candidates == 1 ? "" : "s");
  }
  row.protocol = Protocol(static_cast<int>(folds.size()), cap.samples.lights());
  row.psnr_mean_mse_db = score->psnr_mean_mse_db;
  row.psnr_median_db = score->psnr_median_db;
  row.bytes_per_pixel = score->bytes_per_pixel;
  row.fit_time_s = SecondsSince(t0);
  return row;
}

Result<RtiLooRow> NeuralRow(const RtiCapture& cap, const std::vector<int>& folds,
                            const std::string& tmp, int threads) {
  NeuralOptions no;
  no.threads = threads;
  ProgressTask task("neural refitted without each held-out image", static_cast<int64_t>(folds.size()));
  auto score = LeaveOneOut(cap.samples, folds, [&](const LightSamples& fold, int held,
                                                   const Vec3& light) -> Result<FoldPrediction> {
    const FoldDone counted{task, held};
    RIG_ASSIGN_OR_RETURN(NeuralModel m, FitNeural(fold, no));
    std::filesystem::remove_all(tmp);
    RIG_TRY(m.Save(tmp));
    RIG_ASSIGN_OR_RETURN(NeuralModel back, NeuralModel::Load(tmp));
    return FoldPrediction{back.Render(light), NeuralModel::BytesOnDisk(tmp)};
  });
  if (!score.ok()) return score.error();
  const auto t0 = Clock::now();
  RIG_ASSIGN_OR_RETURN(NeuralModel m, FitNeural(cap.samples, no));
  RtiLooRow row;
  row.family = "neural";
  row.label = "rig neural (9 codes)";
  row.setting = fmt::format("{} codes, decoder {}x{}, {} epochs", no.latent, no.decoder_layers,
                            no.hidden, no.epochs);
  row.protocol = Protocol(static_cast<int>(folds.size()), cap.samples.lights());
  row.psnr_mean_mse_db = score->psnr_mean_mse_db;
  row.psnr_median_db = score->psnr_median_db;
  row.bytes_per_pixel = score->bytes_per_pixel;
  row.fit_time_s = SecondsSince(t0);
  return row;
}

// The fixed bases with the exact leave-one-out of a linear least-squares fit (the hat
// matrix): refitting without an image gives the same prediction, and nothing is chosen.
Result<std::vector<RtiLooRow>> HarmonicRows(const RtiCapture& cap, const std::string& tmp) {
  RtiImages images;
  const LightSamples& s = cap.samples;
  for (int l = 0; l < s.lights(); ++l) {
    cv::Mat enc(s.height, s.width, CV_8UC3), rad(s.height, s.width, CV_32FC3);
    for (size_t p = 0; p < s.pixels(); ++p) {
      for (int c = 0; c < 3; ++c) {
        const uint8_t v = s.value(p, l, c);
        enc.ptr<uint8_t>()[p * 3 + (2 - c)] = v;
        rad.ptr<float>()[p * 3 + (2 - c)] = SrgbDecode(v / 255.0f);
      }
    }
    images.encoded.push_back(enc);
    images.radiance.push_back(rad);
  }
  const std::vector<LooSpec> specs = {{BasisKind::kPtm, 2, FitMethod::kLs, FitSpace::kSrgb},
                                      {BasisKind::kHsh, 2, FitMethod::kLs, FitSpace::kSrgb},
                                      {BasisKind::kHsh, 3, FitMethod::kLs, FitSpace::kSrgb},
                                      {BasisKind::kSh, 4, FitMethod::kLs, FitSpace::kSrgb}};
  const auto loo = RtiLeaveOneOut(images, s.directions, specs, false, 1e6);
  std::vector<RtiLooRow> rows;
  for (size_t i = 0; i < loo.size(); ++i) {
    const auto& r = loo[i];
    if (!r.supported) {
      // Said, not dropped: the basis cannot be fitted stably to these lights.
      RtiLooRow row;
      row.family = r.basis;
      row.setting = fmt::format("order {} ({} terms), ls, sRGB", r.order, r.terms);
      row.protocol = "refused: " + r.refusal;
      row.psnr_mean_mse_db = row.psnr_median_db = row.bytes_per_pixel = row.fit_time_s =
          std::numeric_limits<double>::quiet_NaN();
      row.label = fmt::format("rig {} {} terms", r.basis, r.terms);
      rows.push_back(row);
      continue;
    }
    RtiFitRequest req;
    req.family = r.basis;
    req.harmonic.basis = specs[i].basis;
    req.harmonic.order = specs[i].order;
    req.harmonic.max_order = specs[i].order;
    req.harmonic.method = FitMethod::kLs;
    req.harmonic.transform.space = FitSpace::kSrgb;
    const auto t0 = Clock::now();
    RIG_ASSIGN_OR_RETURN(RtiFitResult fit, FitRti(cap, req));
    const double fit_s = SecondsSince(t0);
    const std::string path = tmp + ".exr";
    RIG_TRY(fit.model->Save(path));
    RtiLooRow row;
    row.family = r.basis;
    row.setting = fmt::format("order {} ({} terms), ls, sRGB, half EXR", r.order, r.terms);
    row.protocol = "exact (hat matrix), all refitted";
    row.psnr_mean_mse_db = r.psnr_mean_mse_db;
    row.psnr_median_db = r.psnr_median_db;
    row.bytes_per_pixel = static_cast<double>(ModelBytesOnDisk(path)) /
                          static_cast<double>(s.pixels());
    row.fit_time_s = fit_s;
    row.label = fmt::format("rig {} {} terms", r.basis, r.terms);
    fs::remove(path);
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

std::vector<RtiLooRow> RelightPublishedIconRows() {
  auto row = [](const char* family, const char* setting, double mean, double median, double bpp,
                double seconds) {
    RtiLooRow r;
    r.family = std::string("relight ") + family;
    r.setting = setting;
    r.protocol = "all 72 refitted (published)";
    r.psnr_mean_mse_db = mean;
    r.psnr_median_db = median;
    r.bytes_per_pixel = bpp;
    r.fit_time_s = seconds;
    r.published = true;
    r.label = r.family + " (published)";
    return r;
  };
  // ../shared/docs/rti-formats.md and the issue: relight-cli 2026.03, -I srgb; fit times of
  // one quiet-machine run (rbf 0.50 s, bilinear 0.64 s; hsh and ptm "0.6-1.0 s").
  return {row("rbf", "9 PCA planes, JPEG q95", 26.11, 29.51, 3.35, 0.50),
          row("bilinear", "9 PCA planes, 8x8 grid, JPEG q95", 25.98, 32.41, 3.35, 0.64),
          row("hsh", "9 terms per channel", 22.73, 26.11, 4.27, 0.8),
          row("ptm", "6 terms per channel", 20.09, 23.02, 2.75, 0.8)};
}

Result<std::vector<RtiLooRow>> RtiLooTable(const RtiCapture& cap, const RtiLooOptions& o,
                                           const std::function<void(const RtiLooRow&)>& on_row) {
  const std::string tmp =
      (fs::temp_directory_path() / fmt::format("rig-loo-{}", ::getpid())).string();
  std::vector<RtiLooRow> rows;
  // One step a row (the three PCA rows, the harmonic bases, the neural model), each row's
  // folds shown inside it.
  ProgressTask table("leave-one-out table", 3 + (o.harmonic ? 1 : 0) + (o.neural ? 1 : 0));
  auto add = [&](RtiLooRow r) {
    if (on_row) on_row(r);
    rows.push_back(std::move(r));
  };
  const int lights = cap.samples.lights();
  const auto folds = Folds(lights, o.every);
  struct Cleanup {
    std::string path;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  } cleanup{tmp};

  {
    RIG_ASSIGN_OR_RETURN(RtiLooRow r, PcaRow(cap, o.choice, folds,
                                             fmt::format("default: auto within {:.1f} B/px",
                                                         o.choice.max_bytes_per_pixel),
                                             tmp, true));
    r.is_default = true;
    r.label = fmt::format("rig default (auto, <= {:.1f} B/px)", o.choice.max_bytes_per_pixel);
    add(r);
    table.Advance(1, "the default done");
  }
  {
    // The candidates `rig fit --max-bytes-per-pixel <large_budget>` has.
    PcaChoiceOptions big = PcaChoiceForBudget(o.large_budget);
    big.base = o.choice.base;
    big.tolerance_db = o.choice.tolerance_db;
    big.validation_every = o.choice.validation_every;
    big.validation_splits = o.choice.validation_splits;
    big.validation_pixels = o.choice.validation_pixels;
    RIG_ASSIGN_OR_RETURN(RtiLooRow r,
                         PcaRow(cap, big, folds,
                                fmt::format("auto within {:.0f} B/px", o.large_budget), tmp, true));
    r.label = fmt::format("rig auto, <= {:.0f} B/px", o.large_budget);
    add(r);
    table.Advance(1, fmt::format("auto within {:.0f} B/px done", o.large_budget));
  }
  {
    // relight's own settings (9 planes on its 8x8 grid, q95) filled our way.
    PcaChoiceOptions fixed = o.choice;
    fixed.components = {9};
    fixed.resolutions = {8};
    fixed.qualities = {95};
    fixed.max_bytes_per_pixel = 1e9;
    RIG_ASSIGN_OR_RETURN(RtiLooRow r, PcaRow(cap, fixed, folds, "k 9, 8x8 grid, q95 (relight's sizes)", tmp));
    r.label = "rig pca at relight's sizes (9, 8x8)";
    add(r);
    table.Advance(1, "pca at relight's sizes done");
  }
  if (o.harmonic) {
    RIG_ASSIGN_OR_RETURN(auto hrows, HarmonicRows(cap, tmp));
    for (auto& r : hrows) add(r);
    table.Advance(1, "harmonic done");
  }
  if (o.neural) {
    RIG_ASSIGN_OR_RETURN(RtiLooRow r, NeuralRow(cap, Folds(lights, o.neural_every), tmp, o.threads));
    add(r);
    table.Advance(1, "neural done");
  }
  return rows;
}

std::string RtiLooRowLine(const RtiLooRow& r) {
  if (!std::isfinite(r.psnr_mean_mse_db)) {
    return fmt::format("  {:<14} {:<40} {}", r.family, r.setting, r.protocol);
  }
  return fmt::format("  {:<14} {:<40} {:6.2f} / {:6.2f} dB  {:6.2f} B/px  {:6.2f} s", r.family,
                     r.setting, r.psnr_mean_mse_db, r.psnr_median_db, r.bytes_per_pixel,
                     r.fit_time_s);
}

std::string RtiLooMarkdown(const RtiCapture& cap, const std::vector<RtiLooRow>& rows) {
  std::string md = fmt::format(
      "# Leave-one-out on {}\n\n{} images {}x{}. Every model is refitted without each "
      "held-out image (every choice — size, grid, smoothness, ranges, quality — made inside the "
      "fold), written as it ships, read back, rendered at the held-out light and compared with "
      "the photograph in 8-bit sRGB: PSNR of the mean MSE over the held-out images, and the "
      "median of their PSNRs. Bytes: the whole model on disk. Fit time: one fit on all images, "
      "this machine.\n\n"
      "| family | setting | protocol | PSNR mean-MSE / median (dB) | B/px | fit (s) |\n"
      "|---|---|---|---|---|---|\n",
      cap.lp, cap.samples.lights(), cap.samples.width, cap.samples.height);
  auto num = [](double v) { return std::isfinite(v) ? fmt::format("{:.2f}", v) : std::string("—"); };
  for (const auto& r : rows) {
    md += fmt::format("| {}{} | {} | {} | {} / {} | {} | {} |\n", r.is_default ? "**" : "",
                      r.family + (r.is_default ? "**" : ""), r.setting, r.protocol,
                      num(r.psnr_mean_mse_db), num(r.psnr_median_db), num(r.bytes_per_pixel),
                      num(r.fit_time_s));
  }
  return md;
}

Status WriteRtiLooCharts(const std::vector<RtiLooRow>& rows, const std::string& prefix) {
  for (int chart = 0; chart < 2; ++chart) {
    std::vector<PlotSeries> series;
    std::vector<PlotMarker> markers;
    for (const auto& r : rows) {
      PlotSeries s;
      s.label = r.label.empty() ? r.family : r.label;
      s.x = {chart == 0 ? r.bytes_per_pixel : r.fit_time_s};
      s.y = {r.psnr_mean_mse_db};
      s.line = false;
      series.push_back(s);
      if (r.is_default)
        markers.push_back({s.x[0], s.y[0], PlotMarker::Style::kBigRing, {0, 0, 230}, "rig fit default"});
      if (r.published)
        markers.push_back({s.x[0], s.y[0], PlotMarker::Style::kSquare, {90, 90, 90}, ""});
    }
    PlotOptions po;
    po.width = 1100;
    po.title = chart == 0 ? "Leave-one-out PSNR against model size"
                          : "Leave-one-out PSNR against fit time";
    po.x_label = chart == 0 ? "bytes per pixel on disk" : "fit time on all images (s)";
    po.y_label = "PSNR, 8-bit sRGB, mean MSE (dB)";
    po.log_x = true;
    po.notes = {"grey squares: relight-cli's published figures on the same capture"};
    const cv::Mat img = DrawPlot(series, markers, po);
    const std::string path = prefix + (chart == 0 ? "-psnr-bytes.png" : "-psnr-time.png");
    RIG_TRY(WriteImageFile(path, img));
  }
  return Ok();
}

Result<std::vector<RtiLooRow>> WriteRtiLooReport(
    const RtiCapture& capture, const RtiLooOptions& options, const std::string& markdown_path,
    const std::function<void(const RtiLooRow&)>& on_row) {
  RIG_ASSIGN_OR_RETURN(auto rows, RtiLooTable(capture, options, on_row));
  // relight-cli's published figures belong to the shared icon only.
  if (capture.samples.lights() == 72 && capture.samples.width == 402 &&
      capture.samples.height == 395) {
    for (auto& r : RelightPublishedIconRows()) rows.push_back(r);
  }
  RIG_TRY(WriteFileAtomic(markdown_path, RtiLooMarkdown(capture, rows)));
  const fs::path p(markdown_path);
  RIG_TRY(WriteRtiLooCharts(rows, (p.parent_path() / p.stem()).string()));
  return rows;
}

}  // namespace rig
