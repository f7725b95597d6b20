// Running a session end to end: devices, ground truth, capture daemon, model, summary.
#include "rig/commands/session_run.h"

#include <chrono>
#include <cstdio>

#include "config/console.h"
#include "config/log.h"
#include "rig/backends.h"
#include "rig/commands/command.h"
#include "capture/daemon/daemon.h"
#include "capture/devices/signals.h"

namespace rig {

int RunSession(Session& session, bool resuming, bool process, bool progress) {
  auto log = Log("session");
  const Config& config = session.config();
  auto devices = MakeDevices(config);
  if (!devices.ok()) return ReportError(resuming ? "resume" : "capture", devices.error());
  const SessionLayout& layout = session.layout();
  if (devices->write_truth && !fs::exists(layout.truth() / "scene.json")) {
    Status st = devices->write_truth(layout.truth(), PlanGrid(config.grid));
    if (!st.ok()) return ReportError("capture", st.error().Within("truth"));
  }
  EnableProgress(progress);
  CaptureOptions options;
  options.settle_scale = devices->settle_scale;
  options.process = process;
  options.progress = progress;
  CaptureDaemon daemon(session, *devices->camera, *devices->motor, *devices->lamp, options);
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  const auto t_last = std::chrono::steady_clock::now();
  std::printf("%s\n", summary.ToString().c_str());
  if (!st.ok()) {
    // A first run that stored nothing (no camera found, a wrong port) leaves no session
    // behind: `rig capture` can simply run again with the right configuration.
    if (!resuming && summary.frames_captured == 0 && session.RemoveIfNothingStored()) {
      if (st.error().code == ErrorCode::kInterrupted) return 128 + StopSignal();
      ReportError("capture", st.error());
      std::fprintf(stderr, "rig: nothing was captured; the session folder %s was removed\n",
                   layout.root.string().c_str());
      return st.error().code == ErrorCode::kInvalidInput ? 2 : 1;
    }
    if (st.error().code == ErrorCode::kInterrupted) return 128 + StopSignal();
    ReportError(resuming ? "resume" : "capture", st.error());
    std::fprintf(stderr, "rig: nothing captured is lost; fix the device and run 'rig resume %s'\n",
                 layout.root.string().c_str());
    return st.error().code == ErrorCode::kInvalidInput ? 2 : 1;
  }
  int rc = summary.processing.failed.empty() ? 0 : 1;
  if (process && rc == 0) {
    Status fit = FitSessionModel(session, daemon.map_store().get());
    if (fit.ok()) {
      Log("session")->info("model written {:.2f} s after the capture's end (the processing tail "
                           "included: {:.2f} s)",
                           std::chrono::duration<double>(std::chrono::steady_clock::now() - t_last).count(),
                           summary.processing_tail_s);
    }
    if (!fit.ok()) {
      ReportError("process", fit.error());
      rc = 1;
    }
  }
  std::printf("session %s: %s\n", layout.root.string().c_str(), rc == 0 ? "complete" : "captured; processing failed");
  return rc;
}

}  // namespace rig

#include "process/model/model_stream.h"

namespace rig {

namespace {

// What a leave-one-out RMS error in the fit space is measured in.
std::string FitSpaceUnit(const std::string& space) {
  if (space == "log") return "of ln(reflectance + eps), reflectance = radiance / lamp radiance";
  if (space == "srgb") return "of sRGB-encoded reflectance (radiance / lamp radiance)";
  return "of reflectance (radiance / lamp radiance), linear";
}

}  // namespace

Status FitSessionModel(const Session& session, const MapStore* maps) {
  auto log = Log("process");
  const Config& config = session.config();
  const SessionLayout& layout = session.layout();
  StreamFitInput in;
  std::vector<double> h, v;
  std::vector<std::string> keys;
  for (const Pose& p : PlanGrid(config.grid)) {
    fs::path path = layout.Hdr(p.Name());
    if (!fs::exists(path)) {
      log->warn("pose={} has no radiance map; the model is fitted without it", p.Name());
      continue;
    }
    keys.push_back(p.Name());
    in.paths.push_back(path.string());
    in.directions.push_back(LightDirection(p.h_deg, p.v_deg, config.light_frame));
    h.push_back(p.h_deg);
    v.push_back(p.v_deg);
  }
  if (in.paths.size() < 2)
    return MakeError(ErrorCode::kInvalidInput, layout.hdr().string(),
                     "{} radiance map(s): too few to fit a model", in.paths.size());
  in.weights = GridQuadratureWeights(h, v);
  in.light_frame = config.light_frame;
  in.lamp_radiance_rgb = config.lamp.radiance_rgb;
  // The maps in memory when every one is held (the session's run kept them as they were
  // merged), else the files.
  std::unique_ptr<MapBands> bands;
  std::string source = "the radiance map files";
  if (maps != nullptr) {
    if (maps->off()) {
      log->info("the model is fitted from the files: {}", maps->off_reason());
    } else if (auto b = maps->Bands(keys); b.ok()) {
      bands = std::move(b).value();
      source = "the maps in memory";
    } else {
      log->info("the model is fitted from the files: {}", b.error().ToString());
    }
  }
  if (!bands) {
    RIG_ASSIGN_OR_RETURN(bands, OpenMapFiles(in.paths));
  }
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
  options.threads = config.process.threads;
  ExrPixelType type = config.process.model_pixel_type == "float" ? ExrPixelType::kFloat : ExrPixelType::kHalf;
  in.compression = *ParseExrCompression(config.process.model_compression);  // validated on load
  std::error_code ec;
  // model/ inside the session, never through a link.
  RIG_ASSIGN_OR_RETURN(fs::path model_dir, EnsureSessionFolder(layout.root, "model"));
  fs::path out = model_dir / "model.exr";
  RIG_ASSIGN_OR_RETURN(StreamFitOutput fit, FitModelFromBands(*bands, in, options, out.string(), type));
  log->info("model fitted from {}", source);
  if (in.near_lamp.near()) {
    log->info("near lamp {:.0f} mm: samples divided by their fall-off, {} px tiles ({} projectors)",
              in.near_lamp.distance_mm, fit.near_tile_px, fit.projectors);
  }
  // What each order costs and gives, beside the model, and its size on disk.
  const auto model_bytes = fs::file_size(out, ec);
  const double pixels = static_cast<double>(fit.width) * static_cast<double>(fit.height);
  const double bpp = ec || pixels <= 0 ? 0.0 : static_cast<double>(model_bytes) / pixels;
  std::string md = fmt::format(
      "# Reflectance model of {}\n\nbasis {}, method {}, fit space {}; chosen order {} "
      "({} terms); leave-one-out RMS error {:.5g} {} (the selection's own "
      "estimate); {:.1f} bytes per pixel on disk; fitted in {:.2f} s\n\n"
      "| order | terms | supported | LOO RMS error ({}) | condition | λ (relative) |\n"
      "|---|---|---|---|---|---|\n",
      layout.root.string(), config.process.basis, config.process.fit_method, config.process.fit_space,
      fit.selection.order, fit.selection.projector.basis.size(), fit.loo_rmse,
      FitSpaceUnit(config.process.fit_space), bpp, fit.time_s, FitSpaceUnit(config.process.fit_space));
  for (const auto& o : fit.selection.orders) {
    md += o.supported ? fmt::format("| {} | {} | yes | {:.5g} | {:.3g} | {:.3g} |\n", o.order, o.terms,
                                    o.loo_rmse, o.condition, o.lambda_relative)
                      : fmt::format("| {} | {} | no: {} | | | |\n", o.order, o.terms, o.refusal);
  }
  md += fmt::format("\npixels with missing samples: {}, flagged: {}\n", fit.missing.pixels_with_missing,
                    fit.missing.flagged);
  Status st = WriteFileAtomic(layout.model() / "report.md", md);
  if (!st.ok()) log->warn("{}", st.error().ToString());
  log->info("model written file={} order={} terms={} loo_rmse={:.5g} time_s={:.2f}", out.string(),
            fit.selection.order, fit.selection.projector.basis.size(), fit.loo_rmse, fit.time_s);
  ConsoleLine(stdout, fmt::format("model: {} (order {}, {} terms, {:.1f} B/px; leave-one-out RMS "
                                  "error {:.4g} {}; {:.2f} s)",
                                  out.string(), fit.selection.order,
                                  fit.selection.projector.basis.size(), bpp, fit.loo_rmse,
                                  FitSpaceUnit(config.process.fit_space), fit.time_s));
  return Ok();
}

}  // namespace rig
