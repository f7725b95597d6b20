// rig render: relights a reflectance model (a model EXR, or a session's) with any number of
// lamps — direction, colour, intensity — summed in linear radiance (the paper's eq. 8); or
// renders a lamp sweeping along a path. Output: radiance (EXR), a tone-mapped picture, or the
// picture the camera would have recorded at a chosen exposure time (the paper's Fig. 12).
// The work is process/render/relight.h; the session's files come from capture/session.
#include <cmath>
#include <cstdio>
#include <optional>
#include <filesystem>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "capture/session/render_source.h"
#include "process/export/load_any.h"
#include "process/hdr/hdr.h"
#include "process/model/harmonic/model.h"
#include "process/render/envmap.h"
#include "process/render/radiance_file.h"
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

// The colour and intensity after a lamp's position: [R,G,B[,I]].
Status ParseColour(const std::string& text, const std::vector<double>& v, size_t first,
                   RelightLamp* l) {
  const size_t rest = v.size() - first;
  if (rest != 0 && rest != 3 && rest != 4) {
    return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                     "after the position: nothing, R,G,B or R,G,B,I ({} numbers given)", rest);
  }
  if (rest >= 3) l->rgb = {v[first], v[first + 1], v[first + 2]};
  if (rest == 4) l->intensity = v[first + 3];
  for (double c : l->rgb)
    if (c < 0) return MakeError(ErrorCode::kInvalidInput, "--light " + text, "negative colour");
  if (l->intensity < 0) return MakeError(ErrorCode::kInvalidInput, "--light " + text, "negative intensity");
  return Ok();
}

// Three forms, told apart by their start:
//   H,V[,R,G,B[,I]]                rig angles (degrees), through the model's light frame
//   dir=X,Y,Z[,R,G,B[,I]]          a unit direction in the object frame (the .lp convention)
//   az=A,el=E[,R,G,B[,I]]          azimuth in the image plane from +x towards +y, elevation
//                                  above the object plane (90: from the camera), degrees
Result<RelightLamp> ParseLamp(const std::string& text) {
  RelightLamp l;
  if (text.rfind("dir=", 0) == 0) {
    RIG_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers("--light", text.substr(4)));
    if (v.size() < 3) {
      return MakeError(ErrorCode::kInvalidInput, "--light " + text, "dir= takes X,Y,Z");
    }
    const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!std::isfinite(n) || std::abs(n - 1) > 0.01) {
      return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                       "dir= takes a unit vector, this one has length {:.4g}", n);
    }
    l.direction = Vec3{v[0] / n, v[1] / n, v[2] / n};
    RIG_TRY(ParseColour(text, v, 3, &l));
    return l;
  }
  if (text.rfind("az=", 0) == 0) {
    const size_t comma = text.find(',');
    if (comma == std::string::npos || text.compare(comma + 1, 3, "el=") != 0) {
      return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                       "expected az=A,el=E[,R,G,B[,I]] (degrees)");
    }
    const std::string numbers = text.substr(3, comma - 3) + "," + text.substr(comma + 4);
    RIG_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers("--light", numbers));
    if (v.size() < 2 || v[1] < -90 || v[1] > 90) {
      return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                       "elevation must be in [-90, 90] degrees");
    }
    l.direction = AzimuthElevationDirection(v[0], v[1]);
    RIG_TRY(ParseColour(text, v, 2, &l));
    return l;
  }
  RIG_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers("--light", text));
  if (v.size() != 2 && v.size() != 5 && v.size() != 6) {
    return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                     "expected H,V or H,V,R,G,B or H,V,R,G,B,I (rig angles), "
                     "dir=X,Y,Z[,...] or az=A,el=E[,...]");
  }
  l.h_deg = v[0];
  l.v_deg = v[1];
  RIG_TRY(ParseColour(text, v, 2, &l));
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
  std::string source, out, log_level, tonemap_name, sweep_text, response_option,
      ward_variant = "pcond", display_from, envmap, gamut = "desaturate";
  double rotate_deg = 0, env_intensity = 1;
  bool envmap_stretch = false;
  int env_samples = 256;
  std::optional<double> display_ev;
  std::vector<std::string> lights;
  double exposure_s = 0, fps = 12;
  int frames = 24;
  bool extrapolate = false;
};

void AddRenderOptions(CLI::App& app, RenderArgs* a) {
  app.add_option("MODEL", a->source,
                 "what is relit: a session folder (its model: model/pca/ or model/model.exr); a "
                 "model EXR of rig fit (SH, HSH, PTM); a model folder in relight's web format "
                 "(ptm, hsh, bilinear/PCA: rig fit --lp or relight-cli); a .ptm or .rti file "
                 "(RTIViewer's); a neural model folder (neural.json)")
      ->required();
  app.add_option("--light", a->lights,
                 "lamp H,V[,R,G,B[,I]] in rig angles (deg), or dir=X,Y,Z[,R,G,B[,I]] (unit "
                 "vector, object frame: x right, y up, z to the camera, as .lp files), or "
                 "az=A,el=E[,R,G,B[,I]] (deg: azimuth from +x towards +y, elevation above the "
                 "object plane); colour relative to the capture lamp, intensity; repeat for "
                 "several lamps");
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
  auto* envmap = app.add_option("--envmap", a->envmap,
                 "light the scene by a latitude-longitude HDR environment (.hdr/.exr, 2:1; its "
                 "centre faces the camera), restricted to the directions the model answers");
  app.add_flag("--envmap-stretch", a->envmap_stretch,
               "--envmap: resample an image that is not 2:1 onto the lat-long grid (a stand-in "
               "environment such as a photograph; not a real panorama)")
      ->needs(envmap);
  app.add_option("--rotate", a->rotate_deg, "--envmap: turn the map about the vertical axis (deg, as a lamp's H)")
      ->needs(envmap);
  app.add_option("--intensity", a->env_intensity, "--envmap: scale its radiance (default 1)")
      ->check(CLI::NonNegativeNumber)
      ->needs(envmap);
  app.add_option("--samples", a->env_samples,
                 "--envmap on a PCA/neural model (or sRGB/log-space harmonic): lamps drawn by "
                 "importance sampling (default 256, seeded)")
      ->check(CLI::Range(1, 1000000))
      ->needs(envmap);
  app.add_option("--ward-variant", a->ward_variant,
                 "ward: pcond (default, as Radiance's pcond) or paper (1-degree samples only)");
  app.add_option("--gamut", a->gamut,
                 "--tonemap: colours the display cannot show: desaturate (default, as Radiance's "
                 "pcond: towards the grey of the same luminance) or clip (each channel)");
  app.add_option("--display-ev", a->display_ev,
                 "fixed display: pixel = radiance x 2^EV before the encoding, no tone mapping "
                 "(pictures compare, lamp intensity shows)");
  app.add_option("--display-from", a->display_from,
                 "fixed display: the --tonemap mapping (ward or linear) of this radiance EXR "
                 "(e.g. an earlier rig render --out ref.exr), applied as it is");
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
  if (a.lights.empty() && a.sweep_text.empty() && a.envmap.empty()) {
    return Bad("--light", "give at least one --light, a --sweep or an --envmap");
  }
  if (!a.envmap.empty() && !a.sweep_text.empty()) return Bad("--envmap", "an environment map renders one frame, not a --sweep");
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
    return Bad(a.out, !sweep ? "output must end in .exr, .png, .jpg, .tif or .tiff"
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
  if ((a.display_ev || !a.display_from.empty()) &&
      (kind == RenderFileKind::kExr || a.exposure_s > 0)) {
    return Bad(a.display_ev ? "--display-ev" : "--display-from",
               "a fixed display is for pictures (not .exr, not with --exposure)");
  }
  if (a.display_ev && !a.display_from.empty()) {
    return Bad("--display-ev", "--display-ev and --display-from exclude each other");
  }
  if (a.display_ev && !std::isfinite(*a.display_ev)) return Bad("--display-ev", "must be finite");
  request.display_ev = a.display_ev;
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
  RIG_ASSIGN_OR_RETURN(request->tonemap.ward_variant, ParseWardVariant(a.ward_variant));
  auto gamut = ParseGamutMapping(a.gamut);
  if (!gamut.ok()) return gamut.error().Within("--gamut");
  request->tonemap.gamut = *gamut;
  if (!a.envmap.empty()) {
    if (a.envmap_stretch) {
      RIG_ASSIGN_OR_RETURN(cv::Mat photo, ReadRadianceFile(a.envmap));
      if (!photo.empty() && photo.cols != 2 * photo.rows) {
        cv::resize(photo, photo, cv::Size(2 * photo.rows, photo.rows), 0, 0, cv::INTER_AREA);
        std::printf("rig render: %s stretched to %dx%d for --envmap (a stand-in, not a panorama)\n",
                    a.envmap.c_str(), photo.cols, photo.rows);
      }
      RIG_TRY(CheckEnvironmentMap(photo, a.envmap));
      request->envmap = photo;
    } else {
      RIG_ASSIGN_OR_RETURN(request->envmap, LoadEnvironmentMap(a.envmap));
    }
    request->envmap_options.rotate_deg = a.rotate_deg;
    request->envmap_options.intensity = a.env_intensity;
    request->envmap_options.samples = a.env_samples;
    request->envmap_options.extrapolate = a.extrapolate;
  }
  if (!a.display_from.empty()) {
    auto reference = ReadRadianceFile(a.display_from);
    if (!reference.ok()) return reference.error().Within("--display-from");
    request->display_reference = *reference;
  }
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
  // A harmonic model's coefficients are kept for --envmap's projection.
  std::optional<Model> harmonic;
  Result<std::unique_ptr<ReflectanceModel>> model =
      MakeError(ErrorCode::kInternal, source->model_path, "not loaded");
  if (!a.envmap.empty() && fs::path(source->model_path).extension() == ".exr") {
    auto m = LoadModel(source->model_path);
    if (!m.ok()) return ReportError("render", m.error());
    harmonic = *m;
    model = WrapHarmonic(*m);
  } else {
    model = LoadAnyModel(source->model_path);
  }
  if (!model.ok()) return ReportError("render", model.error());
  if (Status st = ApplySource(a, *source, &*request); !st.ok()) return ReportError("render", st.error());

  // A model of 8-bit photographs renders, unless asked otherwise, as the photographs were.
  if ((*model)->encoding() == ValueEncoding::kSrgb && request->display == RenderDisplay::kToneMap &&
      a.tonemap_name.empty() && a.display_from.empty()) {
    request->display = RenderDisplay::kEncoded;
  }
  if (harmonic) request->harmonic = &*harmonic;
  auto output = Relight(**model, *request);
  if (!output.ok()) return ReportError("render", output.error());
  if (output->envmap) {
    const EnvmapRender& e = *output->envmap;
    std::printf("rig render: environment %s (%dx%d working map): %s; %.1f%% of its energy lies "
                "outside the directions the model answers%s\n",
                a.envmap.c_str(), e.map_width, e.map_height,
                e.projected ? fmt::format("projected onto the {} basis terms", e.terms).c_str()
                            : fmt::format("{} importance samples ({} distinct lamps, seed 1)",
                                          e.samples, e.distinct_lamps).c_str(),
                100 * e.outside_energy_fraction,
                a.extrapolate ? " (extrapolated)" : " (left out; --extrapolate uses it)");
  }
  auto files = WriteRender(*output, *request, a.out, a.fps);
  if (!files.ok()) return ReportError("render", files.error());
  if (files->filled_pixels > 0) {
    std::printf("rig render: %zu pixel%s the fit flagged filled from their neighbours in the "
                "picture%s (an .exr keeps them 0)\n",
                files->filled_pixels, files->filled_pixels == 1 ? "" : "s",
                files->frames > 1 ? "s" : "");
  }
  if (!output->display_note.empty()) std::printf("rig render: %s\n", output->display_note.c_str());

  if (request->sweep.empty()) {
    const size_t n = request->lamps.size();
    std::printf("rig render: wrote %s (%zu lamp%s%s%s)\n", a.out.c_str(), n, n == 1 ? "" : "s",
                request->envmap.empty() ? "" : " and the environment",
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
