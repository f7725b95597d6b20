// rig fit: fits a reflectance model to radiance maps with known lamp angles (--list) or to an
// RTI capture (--lp), or reports leave-one-out error per basis and order (--loo-report).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "config/config.h"
#include "config/log.h"
#include "process/io/exr_io.h"
#include "process/model/model.h"
#include "process/model/model_stream.h"
#include "process/model/rti.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

struct ListEntry {
  std::string path;
  double h_deg = 0, v_deg = 0;
};

Result<std::vector<ListEntry>> ReadFitList(const std::string& list) {
  std::ifstream f(list);
  if (!f) return MakeError(ErrorCode::kNotFound, list, "cannot open the list");
  const std::filesystem::path folder = std::filesystem::path(list).parent_path();
  std::vector<ListEntry> out;
  std::string line;
  int lineno = 0;
  while (std::getline(f, line)) {
    ++lineno;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream is(line);
    ListEntry e;
    std::string extra;
    if (!(is >> e.path >> e.h_deg >> e.v_deg) || (is >> extra)) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("{}:{}", list, lineno),
                       "expected '<radiance.exr> <h_deg> <v_deg>', got '{}'", line);
    }
    std::filesystem::path p(e.path);
    if (p.is_relative()) p = folder / p;
    e.path = p.string();
    out.push_back(e);
  }
  if (out.empty()) return MakeError(ErrorCode::kInvalidInput, list, "the list names no maps");
  return out;
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

}  // namespace

int RunFit(int argc, char** argv) {
  CLI::App app{"Fit a per-pixel reflectance model (basis coefficients) to radiance maps with known "
               "lamp directions, or report leave-one-out error per basis and order.",
               "rig fit"};
  std::string list, lp, out, report, loo_report, config_path, basis_name, order_text = "",
                                                                 method_name, space_name,
                                                                 pixel_type, log_level;
  bool linear = false;
  int downsample = 1, max_order = -1;
  size_t stream_mb = 1024;
  auto* list_opt = app.add_option("--list", list,
                                  "LIST: one '<radiance.exr> <h_deg> <v_deg>' per line (paths "
                                  "relative to the LIST's folder)");
  auto* lp_opt = app.add_option("--lp", lp,
                                "RTI light file: a count, then '<image> <x> <y> <z>' per line");
  list_opt->excludes(lp_opt);
  app.add_option("--out", out, "model EXR to write");
  app.add_option("--config", config_path, "configuration (lamp radiance, light frame, [process])");
  app.add_option("--basis", basis_name, "sh, hsh or ptm (default: config, else sh)");
  app.add_option("--order", order_text, "an order, or 'auto' (default: config)");
  app.add_option("--max-order", max_order, "highest order considered by 'auto'");
  app.add_option("--method", method_name, "quadrature, ls or rls (default: config, else rls)");
  app.add_option("--space", space_name, "fit space: linear, srgb or log (default: config)");
  app.add_option("--pixel-type", pixel_type, "model pixels: half or float (default: config)");
  app.add_option("--report", report, "write a Markdown report of the fit (per order)");
  app.add_option("--loo-report", loo_report,
                 "with --lp: write leave-one-out PSNR per basis, order, method and space");
  app.add_flag("--linear", linear, "with --lp: the images are linear, not sRGB");
  app.add_option("--downsample", downsample, "with --lp: shrink images by this factor first")
      ->check(CLI::Range(1, 64));
  app.add_option("--stream-above-mb", stream_mb,
                 "with --list: stream row bands when the samples exceed this many MB");
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;
  if (list.empty() && lp.empty()) {
    std::fprintf(stderr, "rig fit: one of --list or --lp is required\n");
    return 2;
  }
  if (out.empty() && loo_report.empty()) {
    std::fprintf(stderr, "rig fit: --out (or, with --lp, --loo-report) is required\n");
    return 2;
  }
  if (!loo_report.empty() && lp.empty()) {
    std::fprintf(stderr, "rig fit: --loo-report needs --lp\n");
    return 2;
  }

  Config config;
  if (!config_path.empty()) {
    auto c = LoadConfigOrError(config_path);
    if (!c.ok()) return ReportError("fit", c.error());
    config = *c;
  }
  ProcessConfig& pc = config.process;
  if (!basis_name.empty()) pc.basis = basis_name;
  if (!method_name.empty()) pc.fit_method = method_name;
  if (!space_name.empty()) pc.fit_space = space_name;
  if (!pixel_type.empty()) {
    if (pixel_type != "half" && pixel_type != "float") {
      std::fprintf(stderr, "rig fit: --pixel-type must be half or float\n");
      return 2;
    }
    pc.model_pixel_type = pixel_type;
  }
  if (max_order >= 0) pc.max_order = max_order;
  if (!order_text.empty()) {
    if (order_text == "auto") {
      pc.order = -1;
    } else {
      try {
        size_t used = 0;
        pc.order = std::stoi(order_text, &used);
        if (used != order_text.size() || pc.order < 0) throw std::invalid_argument("order");
      } catch (const std::exception&) {
        std::fprintf(stderr, "rig fit: --order must be a non-negative number or 'auto'\n");
        return 2;
      }
    }
  }
  auto options = FitOptionsFromConfig(pc);
  if (!options.ok()) return ReportError("fit", options.error());
  const ExrPixelType type = pc.model_pixel_type == "half" ? ExrPixelType::kHalf
                                                          : ExrPixelType::kFloat;

  FitInput input;
  input.light_frame = config.light_frame;
  input.lamp_radiance_rgb = config.lamp.radiance_rgb;
  if (!lp.empty()) {
    auto entries = ReadLp(lp);
    if (!entries.ok()) return ReportError("fit", entries.error());
    auto images = LoadRtiImages(*entries, linear, downsample);
    if (!images.ok()) return ReportError("fit", images.error());
    for (const auto& e : *entries) input.directions.push_back(e.direction);
    if (!loo_report.empty()) {
      std::vector<LooSpec> specs;
      for (FitSpace space : {FitSpace::kSrgb, FitSpace::kLinear, FitSpace::kLog}) {
        for (BasisKind b : {BasisKind::kPtm, BasisKind::kHsh, BasisKind::kSh}) {
          const int lo = b == BasisKind::kPtm ? 1 : 0;
          const int hi = b == BasisKind::kPtm ? std::min(pc.max_order, 4) : pc.max_order;
          for (int order = lo; order <= hi; ++order) {
            for (FitMethod m : {FitMethod::kLs, FitMethod::kRls}) {
              specs.push_back({b, order, m, space});
            }
          }
          if (space == FitSpace::kSrgb && b != BasisKind::kPtm) {
            specs.push_back({b, 2, FitMethod::kQuadrature, space});
          }
        }
      }
      auto rows = RtiLeaveOneOut(*images, input.directions, specs, linear, options->max_condition);
      std::string md = fmt::format(
          "# Leave-one-out on {}\n\n{} images {}x{} (downsample {}), {}; PSNR in 8-bit sRGB\n\n",
          lp, images->encoded.size(), images->encoded[0].cols, images->encoded[0].rows,
          downsample, linear ? "linear 8-bit" : "sRGB 8-bit");
      md += LooTableMarkdown(rows);
      std::ofstream f(loo_report);
      f << md;
      if (!f) return ReportError("fit", MakeError(ErrorCode::kIo, loo_report, "cannot write"));
      std::printf("%s", md.c_str());
      if (out.empty()) return 0;
    }
    input.radiance = std::move(images->radiance);
    input.weights = UniformHemisphereWeights(input.directions.size());
  } else {
    auto entries = ReadFitList(list);
    if (!entries.ok()) return ReportError("fit", entries.error());
    std::vector<double> h_phys, v_phys;
    for (const auto& e : *entries) {
      input.directions.push_back(LightDirection(e.h_deg, e.v_deg, config.light_frame));
      double h = 0, v = 0;
      DirectionToAngles(input.directions.back(), &h, &v);
      h_phys.push_back(h);
      v_phys.push_back(v);
    }
    input.weights = GridQuadratureWeights(h_phys, v_phys);
    std::vector<std::string> paths;
    for (const auto& e : *entries) paths.push_back(e.path);
    auto est = EstimateSampleBytes(paths);
    if (!est.ok()) return ReportError("fit", est.error());
    if (*est > stream_mb * 1024 * 1024 && pc.reference_patch_px[2] == 0) {
      StreamFitInput sin;
      sin.paths = paths;
      sin.directions = input.directions;
      sin.weights = input.weights;
      sin.lamp_radiance_rgb = input.lamp_radiance_rgb;
      sin.light_frame = input.light_frame;
      auto r = FitModelStreaming(sin, *options, out, type);
      if (!r.ok()) return ReportError("fit", r.error());
      std::printf("rig fit: wrote %s (streamed): basis %s order %d (%d terms), LOO RMSE %.5g\n",
                  out.c_str(), BasisKindName(options->basis), r->selection.order,
                  r->selection.projector.basis.size(), r->loo_rmse);
      return 0;
    }
    for (const auto& e : *entries) {
      cv::Mat bgr, valid;
      Status s = LoadRadiance(e.path, &bgr, &valid);
      if (!s.ok()) return ReportError("fit", s.error());
      input.radiance.push_back(bgr);
      input.valid.push_back(valid);
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
  }
  if (pc.reference_patch_px[2] > 0) {
    auto e = CalibrateLampRadiance(input.radiance, pc.reference_patch_px,
                                   pc.reference_reflectance);
    if (!e.ok()) return ReportError("fit", e.error());
    input.lamp_radiance_rgb = *e;
  }
  auto fitted = FitModel(input, *options);
  if (!fitted.ok()) return ReportError("fit", fitted.error());
  if (!report.empty()) {
    std::ofstream f(report);
    f << FitReportMarkdown(*fitted, *options);
    if (!f) return ReportError("fit", MakeError(ErrorCode::kIo, report, "cannot write"));
  }
  if (!out.empty()) {
    Status s = SaveModel(out, fitted->model, type);
    if (!s.ok()) return ReportError("fit", s.error());
  }
  const auto& m = fitted->model;
  std::printf("rig fit: wrote %s: basis %s order %d (%d terms/channel), method %s, space %s, "
              "LOO RMSE %.5g, condition %.3g, flagged pixels %zu, %.2f s\n",
              out.c_str(), m.basis().name().c_str(), m.basis().order(), m.basis().size(),
              FitMethodName(options->method), FitSpaceName(options->transform.space),
              m.info().loo_rmse, m.info().condition, m.info().flagged_pixels,
              fitted->fit_time_s);
  return 0;
}

}  // namespace rig
