// The session's model after a capture, in named steps: the maps the grid has, where they are
// read from (memory or files), the lamp radiance, the fit, the report.
#include "capture/daemon/session_model.h"

#include <cmath>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include "capture/plan/pose.h"
#include "config/console.h"
#include "config/log.h"
#include "process/model/any/load_model.h"
#include "process/model/pca/pca_hdr.h"
#include "process/model/session/map_fit.h"
#include "process/model/session/model_stream.h"
#include "process/model/session/family_choice.h"
#include "process/model/session/pca_session.h"

namespace rig {
namespace {

// The fit's input from the session's grid: every pose with a radiance map, its direction and
// quadrature weight; `keys` receives the pose names in the same order.
Result<StreamFitInput> SessionMapInput(const Session& session, std::vector<std::string>* keys) {
  const Config& config = session.config();
  const SessionLayout& layout = session.layout();
  StreamFitInput in;
  std::vector<double> h, v;
  // An adaptive grid takes only the poses its choice chose: the others are not missing.
  const bool adaptive = config.grid.mode == "adaptive";
  int allowed = 0;
  for (const Pose& p : PlanGrid(config.grid)) {
    ++allowed;
    fs::path path = layout.Hdr(p.Name());
    if (!fs::exists(path)) {
      if (!adaptive)
        Log("process")->warn("pose={} has no radiance map; the model is fitted without it", p.Name());
      continue;
    }
    keys->push_back(p.Name());
    in.paths.push_back(path.string());
    in.directions.push_back(LightDirection(p.h_deg, p.v_deg, config.light_frame));
    h.push_back(p.h_deg);
    v.push_back(p.v_deg);
  }
  if (in.paths.size() < 2)
    return MakeError(ErrorCode::kInvalidInput, layout.hdr().string(),
                     "{} radiance map(s): too few to fit a model", in.paths.size());
  if (adaptive)
    Log("process")->info("adaptive grid: the model is fitted from the {} poses taken of {} allowed",
                         in.paths.size(), allowed);
  in.weights = GridQuadratureWeights(h, v);
  in.light_frame = config.light_frame;
  in.lamp_radiance_rgb = config.lamp.radiance_rgb;
  return in;
}

// The maps in memory when every one is held (the session's run kept them as they were
// merged), else the files; *source says which.
Result<std::unique_ptr<MapBands>> SessionBands(const MapStore* maps,
                                               const std::vector<std::string>& keys,
                                               const std::vector<std::string>& paths,
                                               std::string* source) {
  auto log = Log("process");
  *source = "the radiance map files";
  if (maps != nullptr) {
    if (maps->off()) {
      log->info("the model is fitted from the files: {}", maps->off_reason());
    } else if (auto b = maps->Bands(keys); b.ok()) {
      *source = "the maps in memory";
      return std::move(b).value();
    } else {
      log->info("the model is fitted from the files: {}", b.error().ToString());
    }
  }
  return OpenMapFiles(paths);
}

// model/report.md: the choice, and what each order costs and gives.
std::string SessionFitReport(const Session& session, const StreamFitOutput& fit, double bpp) {
  const ProcessConfig& process = session.config().process;
  const std::string unit = FitSpaceUnit(process.fit_space);
  const double rms = fit.selection.data_rms;
  std::string md = fmt::format(
      "# Reflectance model of {}\n\nbasis {}, method {}, fit space {}; chosen order {} "
      "({} terms); leave-one-out RMS error {:.5g} {} (the selection's own "
      "estimate), {} of the samples' RMS {:.5g}; {:.1f} bytes per pixel on disk; fitted in "
      "{:.2f} s\n\n",
      session.layout().root.string(), process.basis, process.fit_method, process.fit_space,
      fit.selection.order, fit.selection.projector.basis.size(), fit.loo_rmse, unit,
      LooRelativeCell(fit.loo_rmse, rms), rms, bpp, fit.time_s);
  md += SelectionTable(fit.selection, unit);
  md += fmt::format("\npixels with missing samples: {}, flagged: {}\n", fit.missing.pixels_with_missing,
                    fit.missing.flagged);
  return md;
}

// The PCA family's session model (model/pca/, relight's web format with the HDR values in
// info.json), fitted band by band from `bands` — the maps in memory or their files, the same
// values either way, so the same model — its value curve and size chosen per byte on the
// maps' central region (FitPcaHdrFromBands), the folder written whole.
Status FitSessionPca(const Session& session, MapBands& bands, const StreamFitInput& in,
                     const std::string& source, const SessionFamilyChoice* family) {
  auto log = Log("process");
  const Config& config = session.config();
  const SessionLayout& layout = session.layout();
  if (in.near_lamp.near()) {
    return MakeError(ErrorCode::kInvalidInput, layout.config().string(),
                     "[process] model_family = \"pca\" does not model a near lamp's fall-off yet: "
                     "use \"harmonic\" with [light_frame] lamp_distance_mm");
  }
  RIG_ASSIGN_OR_RETURN(fs::path model_dir, EnsureSessionFolder(layout.root, "model"));
  PcaHdrChoiceOptions o;
  o.max_bytes_per_pixel = config.process.pca_max_bytes_per_pixel;
  o.threads = config.process.threads;
  const fs::path out = model_dir / "pca";
  PcaSessionFit fit;
  RIG_TRY(WriteModelFolder(out.string(), [&](const std::string& dir) -> Status {
    RIG_ASSIGN_OR_RETURN(fit, FitPcaHdrFromBands(bands, in.directions, in.lamp_radiance_rgb,
                                                 config.light_frame, o, dir, 32,
                                                 family ? &family->pca : nullptr));
    return Ok();
  }));
  const double pixels = static_cast<double>(fit.width) * fit.height;
  const double bpp = static_cast<double>(FolderBytes(out.string())) / pixels;
  log->info("model fitted from {}", source);
  const cv::Rect& r = fit.choice_region;
  const std::string report = fmt::format(
      "# The session's model\n\nPCA of the reflectance (radiance / lamp radiance) of {} radiance "
      "maps, {:.2f} B/px on disk, fitted in {:.2f} s from {} (the choice {:.2f} s, the curve and "
      "components {:.2f} s, every pixel's coefficients and the planes {:.2f} s).\n\n{}.\n\n"
      "Every candidate fitted to the {}x{} pixels at ({}, {}){} without {} lamps ({}), written, "
      "read back and scored at the lamps held out (relative RMS of linear reflectance):\n\n{}",
      in.directions.size(), bpp, fit.time_s, source, fit.choice_s, fit.gather_s, fit.write_s,
      fit.choice.reason, r.width, r.height, r.x, r.y,
      r.width == fit.width && r.height == fit.height ? " (the whole image)" : " (the central region)",
      ChoiceHeldOutLamps(in.directions, o).size(), HeldOutRuleName(in.directions, o),
      family ? SessionFamilyMarkdown(*family) : PcaHdrChoiceMarkdown(fit.choice));
  Status st = WriteFileAtomic(layout.model() / "report.md", report);
  if (!st.ok()) log->warn("{}", st.error().ToString());
  ConsoleLine(stdout, fmt::format("model: {} (pca, {} components, {}x{} grid, JPEG q{}, {} curve, "
                                  "{:.1f} B/px; {:.2f} s)",
                                  out.string(), fit.components, fit.choice.options.grid_resolution,
                                  fit.choice.options.grid_resolution, fit.choice.options.jpeg_quality,
                                  HdrCurveName(fit.curve.curve), bpp, fit.time_s));
  return Ok();
}

}  // namespace

std::string FitSpaceUnit(const std::string& space) {
  if (space == "log") return "of ln(reflectance + eps), reflectance = radiance / lamp radiance";
  if (space == "srgb") return "of sRGB-encoded reflectance (radiance / lamp radiance)";
  return "of reflectance (radiance / lamp radiance), linear";
}

Status FitSessionModel(const Session& session, const MapStore* maps) {
  auto log = Log("process");
  const Config& config = session.config();
  const SessionLayout& layout = session.layout();
  std::vector<std::string> keys;
  RIG_ASSIGN_OR_RETURN(StreamFitInput in, SessionMapInput(session, &keys));
  std::string source;
  RIG_ASSIGN_OR_RETURN(std::unique_ptr<MapBands> bands, SessionBands(maps, keys, in.paths, &source));
  // A near lamp ([light_frame] lamp_distance_mm > 0): per-pixel fall-off, per-tile directions.
  in.near_lamp = NearLamp::FromLightFrame(config.light_frame, bands->height());
  const auto& patch = config.process.reference_patch_px;
  if (patch[2] > 0 && patch[3] > 0) {
    // Lamp radiance from the reference patch: only the patch of each map is read.
    RIG_ASSIGN_OR_RETURN(in.lamp_radiance_rgb,
                         LampRadianceFromPatch(*bands, patch, config.process.reference_reflectance,
                                               in.near_lamp, in.directions));
    log->info("lamp radiance from the reference patch: R={:.4g} G={:.4g} B={:.4g}",
              in.lamp_radiance_rgb[0], in.lamp_radiance_rgb[1], in.lamp_radiance_rgb[2]);
  }
  RIG_ASSIGN_OR_RETURN(FitOptions options, FitOptionsFromConfig(config.process));
  ExrPixelType type = config.process.model_pixel_type == "float" ? ExrPixelType::kFloat : ExrPixelType::kHalf;
  std::string family = config.process.model_family;
  std::unique_ptr<SessionFamilyChoice> choice;
  std::string family_note;
  if (family == "auto" && in.near_lamp.near()) {
    family = "harmonic";
    family_note = "\n## The family\n\nharmonic: the lamp is near ([light_frame] lamp_distance_mm), "
                  "and only the harmonic family models its fall-off.\n";
    log->info("model family: harmonic (a near lamp: only the harmonic family models its fall-off)");
  } else if (family == "auto" && in.directions.size() < 8) {
    family = "harmonic";
    family_note = fmt::format("\n## The family\n\nharmonic: {} radiance maps, and the PCA family "
                              "needs 8 or more.\n", in.directions.size());
    log->info("model family: harmonic ({} maps: the PCA family needs 8 or more)", in.directions.size());
  } else if (family == "auto") {
    ProgressTask task("choosing the model's family", 1);
    RIG_ASSIGN_OR_RETURN(std::vector<cv::Mat> region, ReadChoiceRegion(*bands));
    PcaHdrChoiceOptions po;
    po.max_bytes_per_pixel = config.process.pca_max_bytes_per_pixel;
    po.threads = config.process.threads;
    po.warn_over_budget = false;  // the family's choice weighs the bytes itself
    FitOptions fold = options;
    fold.threads = config.process.threads;
    auto chosen = ChooseSessionFamily(region, in.directions, in.lamp_radiance_rgb, fold,
                                      type == ExrPixelType::kFloat ? 4 : 2, po);
    if (!chosen.ok()) return chosen.error().Within("the model family's choice");
    choice = std::make_unique<SessionFamilyChoice>(std::move(*chosen));
    family = choice->family;
    task.Advance(1);
    log->info("model family: {} ({:.2f} s)", choice->reason, choice->time_s);
    family_note = "\n" + SessionFamilyMarkdown(*choice);
  }
  if (family == "pca") return FitSessionPca(session, *bands, in, source, choice.get());
  options.threads = config.process.threads;
  in.compression = *ParseExrCompression(config.process.model_compression, /*lossy=*/true);  // validated on load
  // model/ inside the session, never through a link.
  RIG_ASSIGN_OR_RETURN(fs::path model_dir, EnsureSessionFolder(layout.root, "model"));
  fs::path out = model_dir / "model.exr";
  RIG_ASSIGN_OR_RETURN(StreamFitOutput fit, FitModelFromBands(*bands, in, options, out.string(), type));
  log->info("model fitted from {}", source);
  if (in.near_lamp.near()) {
    log->info("near lamp {:.0f} mm: samples divided by their fall-off, {} px tiles ({} projectors)",
              in.near_lamp.distance_mm, fit.near_tile_px, fit.projectors);
  }
  std::error_code ec;
  const auto model_bytes = fs::file_size(out, ec);
  const double pixels = static_cast<double>(fit.width) * static_cast<double>(fit.height);
  const double bpp = ec || pixels <= 0 ? 0.0 : static_cast<double>(model_bytes) / pixels;
  Status st = WriteFileAtomic(layout.model() / "report.md",
                              SessionFitReport(session, fit, bpp) + family_note);
  if (!st.ok()) log->warn("{}", st.error().ToString());
  log->info("model written file={} order={} terms={} loo_rmse={:.5g} time_s={:.2f}", out.string(),
            fit.selection.order, fit.selection.projector.basis.size(), fit.loo_rmse, fit.time_s);
  const std::string share = LooRelativeCell(fit.loo_rmse, fit.selection.data_rms);
  ConsoleLine(stdout, fmt::format("model: {} (order {}, {} terms, {:.1f} B/px; leave-one-out RMS "
                                  "error {:.4g} {}{}; {:.2f} s)",
                                  out.string(), fit.selection.order,
                                  fit.selection.projector.basis.size(), bpp, fit.loo_rmse,
                                  FitSpaceUnit(config.process.fit_space),
                                  share.empty() ? "" : ", " + share + " of the samples' RMS", fit.time_s));
  return Ok();
}

}  // namespace rig
