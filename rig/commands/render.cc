// rig render: relights a reflectance model (a model EXR, or a session's) with any number of
// lamps — direction, colour, intensity — summed in linear radiance (the paper's eq. 8); or
// renders a lamp sweeping along a path. Output: radiance (EXR), a tone-mapped picture, or the
// picture the camera would have recorded at a chosen exposure time (the paper's Fig. 12).
// The work is process/render/relight.h; the session's files come from capture/session.
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "capture/session/render_source.h"
#include "process/export/load_any.h"
#include "process/hdr/hdr.h"
#include "process/model/model.h"
#include "process/render/relight.h"
#include "process/render/tonemap.h"
#include "rig/commands/command.h"

namespace rig {
namespace fs = std::filesystem;

namespace {

Result<std::vector<double>> ParseNumbers(const std::string& option, const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      return MakeError(ErrorCode::kInvalidInput, option + " " + text, "'{}' is not a number", item);
    }
  }
  return v;
}

// "H,V[,R,G,B[,I]]"
Result<RelightLamp> ParseLamp(const std::string& text) {
  RIG_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers("--light", text));
  if (v.size() != 2 && v.size() != 5 && v.size() != 6) {
    return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                     "expected H,V or H,V,R,G,B or H,V,R,G,B,I");
  }
  RelightLamp l;
  l.h_deg = v[0];
  l.v_deg = v[1];
  if (v.size() >= 5) l.rgb = {v[2], v[3], v[4]};
  if (v.size() == 6) l.intensity = v[5];
  for (double c : l.rgb)
    if (c < 0) return MakeError(ErrorCode::kInvalidInput, "--light " + text, "negative colour");
  if (l.intensity < 0) return MakeError(ErrorCode::kInvalidInput, "--light " + text, "negative intensity");
  return l;
}

// "H0,V0:H1,V1[:H2,V2...]": a polyline in rig angles.
Result<std::vector<RelightLamp>> ParseSweep(const std::string& text) {
  std::vector<RelightLamp> points;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ':')) {
    RIG_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers("--sweep", item));
    if (v.size() != 2) {
      return MakeError(ErrorCode::kInvalidInput, "--sweep " + text, "'{}': expected H,V", item);
    }
    RelightLamp l;
    l.h_deg = v[0];
    l.v_deg = v[1];
    points.push_back(l);
  }
  if (points.size() < 2) {
    return MakeError(ErrorCode::kInvalidInput, "--sweep " + text,
                     "a path needs at least two points H,V:H,V");
  }
  return points;
}

// The command line as given.
struct RenderArgs {
  std::string source, out, log_level, tonemap_name, sweep_text, response_option;
  std::vector<std::string> lights;
  double exposure_s = 0, fps = 12;
  int frames = 24;
  bool extrapolate = false;
};

void AddRenderOptions(CLI::App& app, RenderArgs* a) {
  app.add_option("MODEL", a->source, "a model EXR (rig fit) or a session folder (its model/model.exr)")
      ->required();
  app.add_option("--light", a->lights,
                 "lamp H,V[,R,G,B[,I]]: rig angles (deg), colour relative to the capture lamp, "
                 "intensity; repeat for several lamps");
  app.add_option("--sweep", a->sweep_text,
                 "a lamp moving along H,V:H,V[:H,V...] (rig angles); writes --frames frames "
                 "(plus any --light lamps, held still)");
  app.add_option("--frames", a->frames, "frames of a --sweep (default 24)")->check(CLI::Range(2, 10000));
  app.add_option("--fps", a->fps, "frame rate of a --sweep video (default 12)")->check(CLI::Range(0.1, 240.0));
  app.add_option("--exposure", a->exposure_s,
                 "the 8-bit picture the camera would record at this exposure time (s), "
                 "through the response curve (saturation included)")
      ->check(CLI::PositiveNumber);
  app.add_option("--response", a->response_option,
                 "response curve (calib/response.csv) for --exposure; default: the session's");
  app.add_option("--tonemap", a->tonemap_name,
                 "tone mapping for a picture: ward (histogram adjustment), linear, reinhard, "
                 "drago, mantiuk (default for pictures: ward)");
  app.add_flag("--extrapolate", a->extrapolate,
               "render lamps outside the sampled lamp region (with a warning) instead of refusing");
  app.add_option("--out", a->out,
                 "output: .exr (linear radiance), .png/.jpg (picture); with --sweep a video "
                 "(.avi, Motion JPEG) whose frames also go to <out without extension>/")
      ->required();
  AddLogLevelOption(app, &a->log_level);
}

Error Bad(const std::string& what, const std::string& msg) {
  return MakeError(ErrorCode::kInvalidInput, what, "{}", msg);
}

// The lamps, the sweep and the output, checked before anything is read.
Result<RelightRequest> RequestFromArgs(const RenderArgs& a) {
  if (a.lights.empty() && a.sweep_text.empty()) return Bad("--light", "give at least one --light or a --sweep");
  RelightRequest request;
  for (const auto& text : a.lights) {
    RIG_ASSIGN_OR_RETURN(RelightLamp l, ParseLamp(text));
    request.lamps.push_back(l);
  }
  if (!a.sweep_text.empty()) {
    RIG_ASSIGN_OR_RETURN(std::vector<RelightLamp> path, ParseSweep(a.sweep_text));
    request.sweep = SampleLampPath(path, a.frames);
  }
  const RenderFileKind kind = RenderFileKindOf(a.out);
  const bool sweep = !request.sweep.empty();
  if (kind == RenderFileKind::kUnknown || (!sweep && kind == RenderFileKind::kVideo)) {
    return Bad(a.out, !sweep ? "output must end in .exr, .png, .jpg or .tif"
                             : "a sweep's output must end in .avi (video), or .png/.exr (frames only)");
  }
  {
    // The output's folder must exist (it is not created: a typo would scatter renders).
    const fs::path parent = fs::path(a.out).parent_path();
    std::error_code ec;
    if (!parent.empty() && !fs::is_directory(parent, ec))
      return Bad(a.out, "the output folder '" + parent.string() + "' does not exist");
  }
  if (a.exposure_s > 0 && !a.tonemap_name.empty()) return Bad("--exposure", "--exposure and --tonemap exclude each other");
  if (kind == RenderFileKind::kExr && (a.exposure_s > 0 || !a.tonemap_name.empty())) {
    return Bad(a.out, "an .exr holds linear radiance: --exposure and --tonemap need a picture output");
  }
  if (fs::exists(a.out)) return Bad(a.out, "exists; choose another name (nothing is overwritten)");
  request.extrapolate = a.extrapolate;
  request.exposure_s = a.exposure_s;
  request.display = a.exposure_s > 0 ? RenderDisplay::kExposure
                    : kind == RenderFileKind::kExr ? RenderDisplay::kRadiance
                                                   : RenderDisplay::kToneMap;
  request.on_warning = [](const std::string& message) {
    std::fprintf(stderr, "rig render: warning: %s\n", message.c_str());
  };
  return request;
}

// The session's display and response settings, and the --tonemap choice.
Status ApplySource(const RenderArgs& a, const RenderSource& source, RelightRequest* request) {
  if (source.process) request->tonemap = ToneMapOptionsFor(*source.process);
  if (!a.tonemap_name.empty()) {
    RIG_ASSIGN_OR_RETURN(request->tonemap.method, ParseToneMapMethod(a.tonemap_name));
  }
  request->tonemap.srgb = true;
  if (request->display != RenderDisplay::kExposure) return Ok();
  if (source.response_path.empty()) {
    return Bad("--exposure", fmt::format("no response curve known for {}: give --response FILE", a.source));
  }
  RIG_ASSIGN_OR_RETURN(ResponseCurve response, LoadResponse(source.response_path));
  request->log_exposure = response.log_exposure;
  return Ok();
}

}  // namespace

int RunRender(int argc, char** argv) {
  CLI::App app{"Relight a reflectance model: the sum over lamps of rho(direction) x lamp radiance "
               "x colour x intensity, in linear radiance (the paper's eq. 8). Writes the radiance "
               "(.exr), a picture for a screen (--tonemap), or the picture the camera would have "
               "recorded at an exposure time (--exposure, through the session's response curve).",
               "rig render"};
  RenderArgs a;
  AddRenderOptions(app, &a);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(a.log_level)) return *rc;

  auto request = RequestFromArgs(a);
  if (!request.ok()) return ReportError("render", request.error());
  // Refused before any rendering, as WriteRender would after it: nothing is overwritten.
  if (!request->sweep.empty() && std::filesystem::exists(SweepFrameDir(a.out))) {
    return ReportError("render", MakeError(ErrorCode::kInvalidInput, SweepFrameDir(a.out),
                                           "exists; choose another --out (nothing is overwritten)"));
  }
  auto source = ResolveRenderSource(a.source, a.response_option);
  if (!source.ok()) return ReportError("render", source.error());
  auto model = LoadAnyModel(source->model_path);
  if (!model.ok()) return ReportError("render", model.error());
  if (Status st = ApplySource(a, *source, &*request); !st.ok()) return ReportError("render", st.error());

  // A model of 8-bit photographs renders, unless asked otherwise, as the photographs were.
  if ((*model)->encoding() == ValueEncoding::kSrgb && request->display == RenderDisplay::kToneMap &&
      a.tonemap_name.empty()) {
    request->display = RenderDisplay::kEncoded;
  }
  auto output = Relight(**model, *request);
  if (!output.ok()) return ReportError("render", output.error());
  auto files = WriteRender(*output, *request, a.out, a.fps);
  if (!files.ok()) return ReportError("render", files.error());

  if (request->sweep.empty()) {
    const size_t n = request->lamps.size();
    std::printf("rig render: wrote %s (%zu lamp%s%s)\n", a.out.c_str(), n, n == 1 ? "" : "s",
                request->display == RenderDisplay::kExposure ? fmt::format(", exposure {} s", a.exposure_s).c_str()
                : request->display == RenderDisplay::kRadiance ? ", linear radiance"
                : request->display == RenderDisplay::kEncoded
                    ? ", sRGB as the photographs (no tone mapping)"
                    : fmt::format(", tone mapping {}", ToneMapMethodName(output->tonemap.method)).c_str());
    return 0;
  }
  const auto& sweep = request->sweep;
  std::printf("rig render: wrote %zu frames to %s%s (lamp from %g,%g to %g,%g)\n", sweep.size(),
              files->frame_dir.c_str(), files->video ? (" and " + a.out).c_str() : "",
              sweep.front().h_deg, sweep.front().v_deg, sweep.back().h_deg, sweep.back().v_deg);
  return 0;
}

}  // namespace rig
