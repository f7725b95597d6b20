// Radiance maps with known lamp angles, fitted in memory or streamed.
#include "process/model/session/map_fit.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>

#include <fmt/format.h>

#include "process/model/light_direction.h"
#include "process/model/session/map_store.h"
#include "process/model/session/model_stream.h"
#include "config/console.h"

namespace rig {
Result<std::vector<MapListEntry>> ReadMapList(const std::string& list) {
  std::ifstream f(list);
  if (!f) return MakeError(ErrorCode::kNotFound, list, "cannot open the list");
  const std::filesystem::path folder = std::filesystem::path(list).parent_path();
  std::vector<MapListEntry> out;
  std::string line;
  int lineno = 0;
  while (std::getline(f, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream is(line);
    MapListEntry e;
    std::string extra;
    if (!(is >> e.path >> e.h_deg >> e.v_deg) || (is >> extra)) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("{}:{}", list, lineno),
                       "expected '<radiance.exr> <h_deg> <v_deg>', got '{}'", line);
    }
    if (!std::isfinite(e.h_deg) || !std::isfinite(e.v_deg) || std::abs(e.h_deg) > 360 ||
        std::abs(e.v_deg) > 360) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("{}:{}", list, lineno),
                       "angles {} {} are not degrees in [-360, 360]", e.h_deg, e.v_deg);
    }
    if (out.size() >= 100000) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("{}:{}", list, lineno),
                       "more than 100000 maps in one list");
    }
    std::filesystem::path p(e.path);
    if (p.is_relative()) p = folder / p;
    e.path = p.string();
    out.push_back(e);
  }
  if (out.empty()) return MakeError(ErrorCode::kInvalidInput, list, "the list names no maps");
  return out;
}

namespace {

// " (3.21% of the samples' RMS)": a LOO error's scale, for the one-line summaries.
std::string LooScale(double loo_rmse, double data_rms) {
  const std::string cell = LooRelativeCell(loo_rmse, data_rms);
  return cell.empty() ? "" : " (" + cell + " of the samples' RMS)";
}

// A radiance map and its validity (from the HDR merge's "flags" channel, when present).
Status LoadRadiance(const std::string& path, cv::Mat* bgr, cv::Mat* valid) {
  RIG_ASSIGN_OR_RETURN(ExrImage img, ReadExr(path));
  cv::Mat planes[3];
  for (int c = 0; c < 3; ++c) {
    for (size_t i = 0; i < img.channel_names.size(); ++i) {
      if (img.channel_names[i] == std::string(1, "BGR"[c])) planes[c] = img.channels[i];
      if (img.channel_names[i] == "flags") {
        *valid = img.channels[i] == 0;
        *valid /= 255;
      }
    }
    if (planes[c].empty()) {
      return MakeError(ErrorCode::kInvalidInput, path, "no '{}' channel (a radiance map is needed)",
                       "BGR"[c]);
    }
  }
  cv::merge(planes, 3, *bgr);
  return Ok();
}

// The band-wise fit's input for the maps of `paths` with the list's directions and lamp.
StreamFitInput StreamInputOf(const FitInput& input, const std::vector<std::string>& paths) {
  StreamFitInput sin;
  sin.paths = paths;
  sin.directions = input.directions;
  sin.weights = input.weights;
  sin.lamp_radiance_rgb = input.lamp_radiance_rgb;
  sin.light_frame = input.light_frame;
  return sin;
}

// A near lamp ([light_frame] lamp_distance_mm > 0): the session's fit, FitModelFromBands with
// the same StreamFitInput (fall-off per pixel, directions per tile, the reference patch
// divided by its fall-off), from the maps held in memory when they fit under the bound, else
// from the files (the same model, bit for bit).
Result<MapFitResult> FitNearLampMaps(const MapFitRequest& req, const FitInput& input,
                                     const std::vector<std::string>& paths, bool in_memory) {
  const Config& config = req.config;
  StreamFitInput sin = StreamInputOf(input, paths);
  if (auto c = ParseExrCompression(config.process.model_compression, /*lossy=*/true); c.ok()) sin.compression = *c;
  std::unique_ptr<MapStore> store;
  std::unique_ptr<MapBands> bands;
  if (in_memory) {
    store = std::make_unique<MapStore>(ExrPixelType::kFloat, paths.size(),
                                       std::numeric_limits<size_t>::max());
    std::vector<std::string> keys;
    ProgressTask reading("reading radiance maps", static_cast<int64_t>(paths.size()));
    for (size_t i = 0; i < paths.size(); ++i) {
      reading.Advance(1);
      keys.push_back(std::to_string(i));
      RIG_TRY(store->AddFile(keys.back(), paths[i]));
    }
    RIG_ASSIGN_OR_RETURN(bands, store->Bands(keys));
  } else {
    RIG_ASSIGN_OR_RETURN(bands, OpenMapFiles(paths));
  }
  sin.near_lamp = NearLamp::FromLightFrame(config.light_frame, bands->height());
  const auto& patch = config.process.reference_patch_px;
  if (patch[2] > 0 && patch[3] > 0) {
    RIG_ASSIGN_OR_RETURN(sin.lamp_radiance_rgb,
                         LampRadianceFromPatch(*bands, patch, config.process.reference_reflectance,
                                               sin.near_lamp, sin.directions));
  }
  RIG_ASSIGN_OR_RETURN(StreamFitOutput r,
                       FitModelFromBands(*bands, sin, req.options, req.out, req.pixel_type));
  MapFitResult result;
  result.streamed = !in_memory;
  const std::string near = fmt::format(
      "near lamp {:.6g} mm, surface at z = {:.6g} mm: samples divided by their fall-off, {}",
      sin.near_lamp.distance_mm, sin.near_lamp.plane_z_mm,
      r.near_tile_px > 0 ? fmt::format("{} px tiles ({} projectors)", r.near_tile_px, r.projectors)
                         : std::string("one direction per lamp"));
  result.summary = fmt::format(
      "wrote {}{}: basis {} order {} ({} terms), LOO RMSE {:.5g}{}; {}; {:.2f} s", req.out,
      in_memory ? "" : " (streamed)", BasisKindName(req.options.basis), r.selection.order,
      r.selection.projector.basis.size(), r.loo_rmse, LooScale(r.loo_rmse, r.selection.data_rms),
      near, r.time_s);
  result.report = fmt::format(
      "# Model fitted from {}\n\n{} maps {}x{}; basis {}, chosen order {} ({} terms), "
      "leave-one-out RMS error {:.5g} (the selection's own estimate), {} of the samples' "
      "RMS; {}.\n\n",
      req.list, paths.size(), r.width, r.height, BasisKindName(req.options.basis),
      r.selection.order, r.selection.projector.basis.size(), r.loo_rmse,
      LooRelativeCell(r.loo_rmse, r.selection.data_rms), near);
  result.report += SelectionTable(r.selection, "fit space");
  return result;
}

}  // namespace

Result<MapFitResult> FitMaps(const MapFitRequest& req) {
  const Config& config = req.config;
  MapFitResult result;
  FitInput input;
  input.light_frame = config.light_frame;
  input.lamp_radiance_rgb = config.lamp.radiance_rgb;
  RIG_ASSIGN_OR_RETURN(auto entries, ReadMapList(req.list));
  std::vector<double> h_phys, v_phys;
  for (const auto& e : entries) {
    input.directions.push_back(LightDirection(e.h_deg, e.v_deg, config.light_frame));
    double h = 0, v = 0;
    DirectionToAngles(input.directions.back(), &h, &v);
    h_phys.push_back(h);
    v_phys.push_back(v);
  }
  input.weights = GridQuadratureWeights(h_phys, v_phys);
  std::vector<std::string> paths;
  for (const auto& e : entries) paths.push_back(e.path);
  RIG_ASSIGN_OR_RETURN(auto est, EstimateSampleBytes(paths));
  const ProcessConfig& pc = config.process;
  if (config.light_frame.lamp_distance_mm > 0 && config.light_frame.field_height_mm > 0)
    return FitNearLampMaps(req, input, paths, est <= req.stream_above_bytes);
  if (est > req.stream_above_bytes && pc.reference_patch_px[2] == 0) {
    StreamFitInput sin = StreamInputOf(input, paths);
    RIG_ASSIGN_OR_RETURN(auto r, FitModelStreaming(sin, req.options, req.out, req.pixel_type));
    result.streamed = true;
    result.summary = fmt::format("wrote {} (streamed): basis {} order {} ({} terms), LOO RMSE {:.5g}{}",
                                 req.out, BasisKindName(req.options.basis), r.selection.order,
                                 r.selection.projector.basis.size(), r.loo_rmse,
                                 LooScale(r.loo_rmse, r.selection.data_rms));
    return result;
  }
  {
    ProgressTask reading("reading radiance maps", static_cast<int64_t>(entries.size()));
    for (const auto& e : entries) {
      reading.Advance(1);
      cv::Mat bgr, valid;
      RIG_TRY(LoadRadiance(e.path, &bgr, &valid));
      input.radiance.push_back(bgr);
      input.valid.push_back(valid);
    }
  }

  bool any_mask = false;
  for (const auto& v : input.valid) any_mask |= !v.empty();
  if (!any_mask) {
    input.valid.clear();
  } else {
    for (size_t i = 0; i < input.valid.size(); ++i) {
      if (input.valid[i].empty())
        input.valid[i] = cv::Mat(input.radiance[i].size(), CV_8U, cv::Scalar(1));
    }
  }
  if (pc.reference_patch_px[2] > 0) {
    RIG_ASSIGN_OR_RETURN(input.lamp_radiance_rgb,
                         CalibrateLampRadiance(input.radiance, pc.reference_patch_px,
                                               pc.reference_reflectance));
  }
  RIG_ASSIGN_OR_RETURN(FitOutput fitted, FitModel(input, req.options));
  result.report = FitReportMarkdown(fitted, req.options);
  if (!req.out.empty()) RIG_TRY(SaveModel(req.out, fitted.model, req.pixel_type));
  const auto& m = fitted.model;
  result.summary = fmt::format(
      "wrote {}: basis {} order {} ({} terms/channel), method {}, space {}, LOO RMSE {:.5g}{}, "
      "condition {}, flagged pixels {}, {:.2f} s",
      req.out, m.basis().name(), m.basis().order(), m.basis().size(),
      FitMethodName(req.options.method), FitSpaceName(req.options.transform.space),
      m.info().loo_rmse, LooScale(m.info().loo_rmse, fitted.selection.data_rms),
      std::isfinite(m.info().condition) ? fmt::format("{:.3g}", m.info().condition) : "ill-conditioned", m.info().flagged_pixels, fitted.fit_time_s);
  return result;
}

}  // namespace rig
