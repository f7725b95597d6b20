// rig fit: fits a reflectance model to a multi-light capture (--lp: by default the most
// accurate model per byte, its size chosen from the data) or to radiance maps with known lamp
// angles (--list), or reports leave-one-out error of every family (--loo-report).
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "config/config.h"
#include "config/atomic_file.h"
#include "config/log.h"
#include "process/evaluate/rti_loo.h"
#include "process/export/lp_choice.h"
#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/export/relight_fit.h"
#include "process/model/any/load_model.h"
#include "process/model/light_direction.h"
#include "process/model/light_samples.h"
#include "process/model/session/map_fit.h"
#include "process/model/pca/pca_stream.h"
#include "process/model/any/rti_fit.h"
#include "rig/commands/command.h"
#include "config/console.h"

namespace rig {
namespace {

struct FitArgs {
  std::string list, lp, out, report, loo_report, config_path, basis, order_text, method, space,
      pixel_type, log_level, mask = "hinge", ptm_variant = "rgb";
  int downsample = 1, max_order = -1, components = 0, grid = 0, quality = 0, loo_every = 1,
      impute = 0, hsh_terms = 9, held_out_every = 6;
  double max_bpp = 3.4;
  long stream_mb = -1;  // -1: the default of the path (--list 1024, --lp 256); 0: always
  bool no_neural = false, linear = false;
};

void AddOptions(CLI::App& app, FitArgs* a) {
  auto* list = app.add_option("--list", a->list,
                              "LIST: one '<radiance.exr> <h_deg> <v_deg>' per line (paths "
                              "relative to the LIST's folder)");
  auto* lp = app.add_option("--lp", a->lp,
                            "RTI light file: a count, then '<image> <x> <y> <z>' per line");
  list->excludes(lp);
  app.add_option("--out", a->out,
                 "the model: a folder for pca (relight's web format), an EXR for sh/hsh/ptm; "
                 "with --lp, a .ptm (PTM, 6 terms) or .rti (HSH) file fitted straight from the "
                 "photographs for RTIViewer");
  app.add_option("--ptm-variant", a->ptm_variant, "--out X.ptm: rgb (default) or lrgb");
  app.add_option("--hsh-terms", a->hsh_terms, "--out X.rti: 9 (default), 16 (third order, needs 16 or more lights) or 4 HSH terms")
      ->check(CLI::IsMember({4, 9, 16}));
  app.add_option("--held-out-every", a->held_out_every,
                 "--out X.ptm|X.rti: hold out every n-th image, refit without them and print the "
                 "error there of the file as written (default 6; 0: none)")
      ->check(CLI::Range(0, 1000));
  app.add_option("--config", a->config_path, "configuration (lamp radiance, light frame, [process])");
  app.add_option("--basis", a->basis,
                 "--lp: auto (default), pca, sh, hsh, ptm; --list: sh, hsh, ptm (default: config)");
  app.add_option("--max-bytes-per-pixel", a->max_bpp,
                 "auto/pca: the largest model considered, whole model on disk (default 3.4)")
      ->check(CLI::Range(0.05, 1000.0));
  app.add_option("--components", a->components, "pca: components (default: chosen)")
      ->check(CLI::Range(1, 64));
  app.add_option("--grid", a->grid, "pca: octahedral grid nodes per side (default: chosen)")
      ->check(CLI::Range(2, 64));
  app.add_option("--jpeg-quality", a->quality, "pca: JPEG quality of the planes (default: chosen)")
      ->check(CLI::Range(1, 100));
  app.add_option("--mask", a->mask,
                 "pca: clipped/black samples: hinge (default: fitted around), drop, none");
  app.add_option("--impute-censored", a->impute,
                 "pca: fit the components around clipped/black samples too, N passes (default 0: "
                 "best against the photographs; more recovers what lies beyond clipping)")
      ->check(CLI::Range(0, 10));
  app.add_option("--order", a->order_text, "sh/hsh/ptm: an order, or 'auto' (default: config)");
  app.add_option("--max-order", a->max_order, "highest order considered by 'auto'");
  app.add_option("--method", a->method, "quadrature, ls or rls (default: config, else rls)");
  app.add_option("--space", a->space, "sh/hsh/ptm fit space: linear, srgb or log");
  app.add_option("--pixel-type", a->pixel_type, "EXR models: half or float (default: config)");
  app.add_option("--report", a->report, "write a Markdown report of the fit and the choice");
  app.add_option("--loo-report", a->loo_report,
                 "with --lp: leave-one-out PSNR of every family, refitting without each image "
                 "(Markdown, and two charts beside it)");
  app.add_option("--loo-every", a->loo_every,
                 "with --loo-report: hold out every n-th image only (default 1: all)")
      ->check(CLI::Range(1, 1000));
  app.add_flag("--loo-no-neural", a->no_neural, "with --loo-report: leave the neural family out");
  app.add_flag("--linear", a->linear,
               "with --lp, sh/hsh/ptm: the images are linear 8-bit, not sRGB");
  app.add_option("--downsample", a->downsample, "with --lp: shrink images by this factor first")
      ->check(CLI::Range(1, 64));
  app.add_option("--stream-above-mb", a->stream_mb,
                 "stream row bands when the samples exceed this many MB: --list (default "
                 "1024), and --lp with auto/pca (default 256: two passes over the JPEGs give "
                 "the same model byte for byte, faster and in a fraction of the memory; "
                 "--loo-report is refused above it)")
      ->check(CLI::Range(0L, 1L << 30));
  AddLogLevelOption(app, &a->log_level);
}

void PrintLooRow(const RtiLooRow& r) {
  ConsoleLine(stdout, RtiLooRowLine(r));
  std::fflush(stdout);
}

// The harmonic options from config and the command line.
Result<FitOptions> HarmonicOptions(const FitArgs& a, ProcessConfig pc) {
  if (!a.method.empty()) pc.fit_method = a.method;
  if (!a.space.empty()) pc.fit_space = a.space;
  if (a.max_order >= 0) pc.max_order = a.max_order;
  if (!a.order_text.empty()) {
    if (a.order_text == "auto") {
      pc.order = -1;
    } else {
      size_t used = 0;
      try {
        pc.order = std::stoi(a.order_text, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != a.order_text.size() || pc.order < 0) {
        return MakeError(ErrorCode::kInvalidInput, "--order",
                         "must be a non-negative number or 'auto', got '{}'", a.order_text);
      }
    }
  }
  return FitOptionsFromConfig(pc);
}

// The choice options of an auto/pca fit, as FitRti sets them from the request.
PcaChoiceOptions ChoiceOptionsOf(const RtiFitRequest& req) {
  PcaChoiceOptions co = req.choice;
  if (req.components > 0) co.components = {req.components};
  if (req.grid_resolution > 0) co.resolutions = {req.grid_resolution};
  if (req.jpeg_quality > 0) co.qualities = {req.jpeg_quality};
  return co;
}

// auto/pca on a capture whose samples exceed --stream-above-mb: FitPcaStreaming.
int RunLpStreamed(const FitArgs& a, const std::vector<LpEntry>& entries, const RtiFitRequest& req,
                  uint64_t sample_bytes) {
  std::printf("rig fit: %s: samples %.0f MB > --stream-above-mb %ld: streaming bands of rows\n",
              a.lp.c_str(), static_cast<double>(sample_bytes) / (1 << 20), a.stream_mb);
  std::fflush(stdout);
  PcaStreamOptions so;
  so.lp = a.lp;
  const PcaChoiceOptions co = ChoiceOptionsOf(req);
  Result<PcaStreamFit> fit = MakeError(ErrorCode::kInternal, a.out, "not fitted");
  Status written = WriteModelFolder(a.out, [&](const std::string& dir) -> Status {
    fit = FitPcaStreaming(entries, co, dir, so);
    if (!fit.ok()) return fit.error();
    return Ok();
  });
  if (!written.ok()) return ReportError("fit", written.error());
  if (!a.report.empty()) {
    std::string md = fmt::format(
        "# Model of {}\n\n{} images {}x{} (streamed); masked (at or below {} or at or above {} "
        "in any channel, per channel): {} sample-channels, {:.1f}% of all, in {:.1f}% of "
        "pixels\n\n## Choice\n\n{}.\n\nSamples fitted around: {} sample-channels ({} pixels "
        "solved around them, mask {}).\n\n",
        a.lp, fit->lights, fit->width, fit->height, co.base.thresholds.black_max,
        co.base.thresholds.clipped_min, fit->masked_samples, 100 * fit->masked_fraction,
        100 * fit->pixels_with_masked, fit->choice.reason, fit->stats.masked_samples,
        fit->stats.refitted_pixels, PcaMaskModeName(co.base.mask));
    md += PcaChoiceMarkdown(fit->choice);
    if (Status st = WriteFileAtomic(a.report, md); !st.ok()) return ReportError("fit", st.error());
  }
  const double bpp = static_cast<double>(ModelBytesOnDisk(a.out)) /
                     (static_cast<double>(fit->width) * fit->height);
  std::printf("rig fit: wrote %s (%.2f B/px): pca-bilinear (the streamed fit's candidates are "
              "PCA's only), %s; masked %.1f%% of samples (%.1f%% "
              "of pixels); streamed in %d bands: sample %.2f s, choice %.2f s, planes %.2f s\n",
              a.out.c_str(), bpp, fit->choice.reason.c_str(), 100 * fit->masked_fraction,
              100 * fit->pixels_with_masked, fit->bands, fit->gather_s, fit->choice_s,
              fit->write_s);
  return 0;
}

std::string LowerExtension(const std::string& path) {
  std::string e = std::filesystem::path(path).extension().string();
  for (char& ch : e) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return e;
}

// --out X.ptm | X.rti: relight's basis fitted straight from the photographs, written for
// RTIViewer, with the error of the file as written at images held out of its fit.
int RunLpRelightFile(const FitArgs& a, const RtiCapture& capture) {
  const bool ptm = LowerExtension(a.out) == ".ptm";
  RelightTarget t;
  t.type = ptm ? RelightType::kPtm : RelightType::kHsh;
  t.terms = ptm ? 6 : a.hsh_terms;
  t.lrgb = ptm && a.ptm_variant == "lrgb";
  if (ptm && a.ptm_variant != "rgb" && a.ptm_variant != "lrgb")
    return ReportError("fit", MakeError(ErrorCode::kInvalidInput, "--ptm-variant", "'{}': rgb or lrgb", a.ptm_variant));
  RelightFitOptions o;
  o.every = a.held_out_every;
  o.format = ptm ? "ptm" : "rti";
  std::printf("rig fit: %s: %s straight from %d images %dx%d (least squares in code values, "
              "masked samples left out)%s...\n",
              a.lp.c_str(), ptm ? (t.lrgb ? "PTM lrgb, 6 terms" : "PTM rgb, 6 terms per channel")
                                : fmt::format("HSH, {} terms per channel", t.terms).c_str(),
              capture.samples.lights(), capture.samples.width, capture.samples.height,
              o.every > 0 ? fmt::format("; then again without every {}th image, for its error", o.every).c_str() : "");
  std::fflush(stdout);
  auto fit = FitRelightToSamples(capture.samples, t, o);
  if (!fit.ok()) return ReportError("fit", fit.error().Within(a.lp));
  const Status saved = ptm ? WritePtm(a.out, fit->coefficients) : WriteRti(a.out, fit->coefficients);
  if (!saved.ok()) return ReportError("fit", saved.error());
  const double bpp = static_cast<double>(ModelBytesOnDisk(a.out)) / static_cast<double>(capture.samples.pixels());
  const std::string held =
      fit->held_out > 0
          ? fmt::format("held out {} images (every {}th), refitted without them and written: {:.2f} dB "
                        "at them", fit->held_out, o.every, fit->held_out_psnr_db)
          : std::string("no images held out");
  if (!a.report.empty()) {
    const std::string md = fmt::format(
        "# {} of {}\n\n{} images {}x{}; {}, fitted by least squares in the photographs' code values, "
        "masked samples (clipped, black) left out: {} pixels solved around them.\n\n"
        "- at its own images: {:.2f} dB (8-bit PSNR, unquantised)\n- {}\n- {:.2f} B/px\n",
        a.out, a.lp, capture.samples.lights(), capture.samples.width, capture.samples.height,
        fit->coefficients.Summary(), fit->refitted_pixels, fit->fitted_psnr_db, held, bpp);
    if (Status st = WriteFileAtomic(a.report, md); !st.ok()) return ReportError("fit", st.error());
  }
  std::printf("rig fit: wrote %s (%.2f B/px): %s; %s; at its own images %.2f dB; masked %.1f%% of "
              "samples; load %.2f s, fit %.2f s, held-out fit %.2f s\n",
              a.out.c_str(), bpp, fit->coefficients.Summary().c_str(), held.c_str(),
              fit->fitted_psnr_db, 100 * capture.masked_fraction, capture.load_time_s, fit->fit_s,
              fit->held_out_s);
  return 0;
}

int RunLp(FitArgs a, const Config& config) {
  // .ptm/.rti: relight's basis from the photographs, in memory.
  const std::string out_ext = LowerExtension(a.out);
  const bool relight_file = out_ext == ".ptm" || out_ext == ".rti";
  if (relight_file && !a.basis.empty() && a.basis != (out_ext == ".ptm" ? "ptm" : "hsh")) {
    return ReportError("fit", MakeError(ErrorCode::kInvalidInput, "--basis",
                                        "'{}' with --out {}: a .ptm holds a PTM, a .rti an HSH",
                                        a.basis, a.out));
  }
  // Above the bound, auto/pca stream; --loo-report refits in memory and is refused.
  const std::string family = a.basis.empty() ? "auto" : a.basis;
  const bool folder_family = !relight_file && (family == "auto" || family == "pca");
  std::vector<LpEntry> entries;
  uint64_t sample_bytes = 0;
  {
    auto read = ReadLp(a.lp);
    if (!read.ok()) return ReportError("fit", read.error());
    entries = std::move(*read);
    // An image that cannot be probed is reported by LoadRtiCapture, with its .lp line.
    auto bytes = RtiSampleBytes(entries, a.downsample);
    if (bytes.ok()) sample_bytes = *bytes;
  }
  // In memory the samples are held next to the decoded images (about twice their size);
  // streaming is byte-identical and was faster from 6 MP up (docs/model.md).
  if (a.stream_mb < 0) a.stream_mb = 256;
  const bool above = sample_bytes > static_cast<uint64_t>(a.stream_mb) * 1024 * 1024;
  if (above && !a.loo_report.empty()) {
    return ReportError(
        "fit", MakeError(ErrorCode::kInvalidInput, a.lp,
                         "--loo-report holds every sample in memory and refits it per image: "
                         "{:.0f} MB of samples is above --stream-above-mb {}; use --downsample, "
                         "or raise --stream-above-mb if the memory is there",
                         static_cast<double>(sample_bytes) / (1 << 20), a.stream_mb));
  }
  if (above && folder_family && a.downsample > 1) {
    return ReportError(
        "fit", MakeError(ErrorCode::kInvalidInput, a.lp,
                         "the streamed fit reads the images at full size: {:.0f} MB of samples "
                         "after --downsample {} is still above --stream-above-mb {}; use a "
                         "larger --downsample, or none",
                         static_cast<double>(sample_bytes) / (1 << 20), a.downsample, a.stream_mb));
  }
  const bool streamed = above && folder_family;
  const bool near = config.light_frame.lamp_distance_mm > 0 && config.light_frame.field_height_mm > 0;
  if (near && streamed) {
    return ReportError(
        "fit", MakeError(ErrorCode::kInvalidInput, a.lp,
                         "a near lamp ([light_frame] lamp_distance_mm of {}) divides the samples "
                         "by their fall-off in memory; {:.0f} MB of samples is above "
                         "--stream-above-mb {}: raise it, or use --downsample",
                         a.config_path, static_cast<double>(sample_bytes) / (1 << 20),
                         a.stream_mb));
  }
  auto capture = streamed ? Result<RtiCapture>(RtiCapture{}) : LoadRtiCapture(a.lp, a.downsample);
  if (!capture.ok()) return ReportError("fit", capture.error());
  std::string near_note;
  if (near) {
    // A near lamp: every sample divided by its pixel's fall-off (in linear units), so that the
    // fitted reflectance is the far lamp's; the .lp's directions are taken from the arm's centre.
    const NearLamp lamp = NearLamp::FromLightFrame(config.light_frame, capture->samples.height);
    const size_t clipped = DivideSamplesByFalloff(lamp, !a.linear, &capture->samples);
    capture->masked_samples += clipped;
    if (!capture->samples.values.empty())
      capture->masked_fraction = static_cast<double>(capture->masked_samples) /
                                 static_cast<double>(capture->samples.values.size());
    near_note = fmt::format(
        "{:.6g} mm, {:.6g} mm/px, surface at z = {:.6g} mm; samples divided by their fall-off "
        "({} codes), {} sample-channels pushed to 255 and masked",
        lamp.distance_mm, lamp.mm_per_px, lamp.plane_z_mm, a.linear ? "linear" : "sRGB", clipped);
    std::printf("rig fit: near lamp %s\n", near_note.c_str());
    std::fflush(stdout);
  }
  if (relight_file && a.loo_report.empty()) return RunLpRelightFile(a, *capture);
  RtiFitRequest req;
  req.family = a.basis.empty() ? "auto" : a.basis;
  req.near_lamp = near_note;
  req.choice = PcaChoiceForBudget(a.max_bpp);
  req.choice.base.impute_iterations = a.impute;
  req.linear = a.linear;
  req.components = a.components;
  req.grid_resolution = a.grid;
  req.jpeg_quality = a.quality;
  if (a.mask == "hinge") req.choice.base.mask = PcaMaskMode::kHinge;
  else if (a.mask == "drop") req.choice.base.mask = PcaMaskMode::kDrop;
  else if (a.mask == "none") req.choice.base.mask = PcaMaskMode::kNone;
  else return ReportError("fit", MakeError(ErrorCode::kInvalidInput, "--mask", "'{}': hinge, drop or none", a.mask));
  if (!a.loo_report.empty()) {
    RtiLooOptions lo;
    lo.every = a.loo_every;
    lo.neural = !a.no_neural;
    lo.choice = req.choice;  // the report's rows are the command's own candidates
    std::printf("rig fit: leave-one-out on %s (%d images %dx%d), refitting without each...\n",
                a.lp.c_str(), capture->samples.lights(), capture->samples.width,
                capture->samples.height);
    auto rows = WriteRtiLooReport(*capture, lo, a.loo_report, PrintLooRow);
    if (!rows.ok()) return ReportError("fit", rows.error());
    std::printf("rig fit: wrote %s and its charts beside it\n", a.loo_report.c_str());
    if (a.out.empty()) return 0;
    if (relight_file) return RunLpRelightFile(a, *capture);
  }
  ProcessConfig pc = config.process;
  if (a.space.empty()) pc.fit_space = "srgb";  // 8-bit photographs: fitted as they are encoded
  auto harmonic = HarmonicOptions(a, pc);
  if (!harmonic.ok()) return ReportError("fit", harmonic.error());
  req.harmonic = *harmonic;
  if (folder_family && std::filesystem::path(a.out).extension() == ".exr") {
    return ReportError("fit", MakeError(ErrorCode::kInvalidInput, a.out,
                                        "the {} model is a folder (relight's web format: "
                                        "info.json and JPEG planes); give a folder, or --basis "
                                        "sh|hsh|ptm for an EXR",
                                        req.family));
  }
  if (streamed) return RunLpStreamed(a, entries, req, sample_bytes);
  auto fit = FitRtiAcrossFamilies(*capture, req);
  if (!fit.ok()) return ReportError("fit", fit.error());
  // A folder model is written whole (the old one or the new one, never a mix); an EXR through
  // the one writer as it is.
  const std::string fam = fit->model->family();
  const bool web = RelightCoefficientsOf(*fit->model) != nullptr;  // relight's web folder
  Status saved = fam == "pca-bilinear" || fam == "neural" || web
                     ? WriteModelFolder(a.out, [&](const std::string& dir) { return fit->model->Save(dir); })
                     : fit->model->Save(a.out);
  if (!saved.ok()) return ReportError("fit", saved.error());
  if (!a.report.empty()) {
    if (Status st = WriteFileAtomic(a.report, fit->report); !st.ok()) return ReportError("fit", st.error());
  }
  const double bpp = static_cast<double>(ModelBytesOnDisk(a.out)) /
                     static_cast<double>(capture->samples.pixels());
  std::printf("rig fit: wrote %s (%.2f B/px): %s; masked %.1f%% of samples (%.1f%% of pixels); "
              "load %.2f s, fit %.2f s\n",
              a.out.c_str(), bpp, fit->summary.c_str(), 100 * capture->masked_fraction,
              100 * capture->pixels_with_masked, capture->load_time_s, fit->fit_time_s);
  return 0;
}

}  // namespace

int RunFit(int argc, char** argv) {
  CLI::App app{"Fit a reflectance model to a multi-light capture (--lp) or to radiance maps "
               "with known lamp angles (--list), or report leave-one-out error of every family.",
               "rig fit"};
  FitArgs a;
  AddOptions(app, &a);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(a.log_level)) return *rc;
  if (a.list.empty() && a.lp.empty()) {
    std::fprintf(stderr, "rig fit: one of --list or --lp is required\n");
    return 2;
  }
  if (a.out.empty() && a.loo_report.empty()) {
    std::fprintf(stderr, "rig fit: --out (or, with --lp, --loo-report) is required\n");
    return 2;
  }
  if (!a.loo_report.empty() && a.lp.empty()) {
    std::fprintf(stderr, "rig fit: --loo-report needs --lp\n");
    return 2;
  }
  if (!a.pixel_type.empty() && a.pixel_type != "half" && a.pixel_type != "float") {
    std::fprintf(stderr, "rig fit: --pixel-type must be half or float\n");
    return 2;
  }
  Config config;
  if (!a.config_path.empty()) {
    auto c = LoadConfigOrError(a.config_path);
    if (!c.ok()) return ReportError("fit", c.error());
    config = *c;
  }
  if (!a.lp.empty()) return RunLp(a, config);

  MapFitRequest req;
  req.list = a.list;
  req.out = a.out;
  if (!a.basis.empty()) config.process.basis = a.basis;
  if (!a.pixel_type.empty()) config.process.model_pixel_type = a.pixel_type;
  req.config = config;
  auto options = HarmonicOptions(a, config.process);
  if (!options.ok()) return ReportError("fit", options.error());
  req.options = *options;
  req.pixel_type = config.process.model_pixel_type == "half" ? ExrPixelType::kHalf
                                                             : ExrPixelType::kFloat;
  req.stream_above_bytes = static_cast<size_t>(a.stream_mb < 0 ? 1024 : a.stream_mb) * 1024 * 1024;
  auto fit = FitMaps(req);
  if (!fit.ok()) return ReportError("fit", fit.error());
  if (!a.report.empty() && !fit->report.empty()) {
    if (Status st = WriteFileAtomic(a.report, fit->report); !st.ok()) return ReportError("fit", st.error());
  }
  std::printf("rig fit: %s\n", fit->summary.c_str());
  return 0;
}

}  // namespace rig
