// rig render: relights a reflectance model (a model EXR, or a session's) with any number of
// lamps — direction, colour, intensity — summed in linear radiance (the paper's eq. 8); or
// renders a lamp sweeping along a path. Output: radiance (EXR), a tone-mapped picture, or the
// picture the camera would have recorded at a chosen exposure time (the paper's Fig. 12).
#include <cstdio>
#include <filesystem>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "config/config.h"
#include "process/render/exposure_render.h"
#include "process/io/exr_io.h"
#include "process/hdr/hdr.h"
#include "process/model/light_direction.h"
#include "process/model/model.h"
#include "process/render/tonemap.h"
#include "rig/commands/command.h"

namespace rig {
namespace fs = std::filesystem;

namespace {

struct LampSpec {
  double h_deg = 0, v_deg = 0;
  std::array<double, 3> rgb = {1, 1, 1};
  double intensity = 1;
};

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
Result<LampSpec> ParseLamp(const std::string& text) {
  RIG_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers("--light", text));
  if (v.size() != 2 && v.size() != 5 && v.size() != 6) {
    return MakeError(ErrorCode::kInvalidInput, "--light " + text,
                     "expected H,V or H,V,R,G,B or H,V,R,G,B,I");
  }
  LampSpec l;
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
Result<std::vector<LampSpec>> ParseSweep(const std::string& text) {
  std::vector<LampSpec> points;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ':')) {
    RIG_ASSIGN_OR_RETURN(std::vector<double> v, ParseNumbers("--sweep", item));
    if (v.size() != 2) {
      return MakeError(ErrorCode::kInvalidInput, "--sweep " + text, "'{}': expected H,V", item);
    }
    points.push_back({v[0], v[1]});
  }
  if (points.size() < 2) {
    return MakeError(ErrorCode::kInvalidInput, "--sweep " + text,
                     "a path needs at least two points H,V:H,V");
  }
  return points;
}

// `frames` lamp positions evenly spaced along the polyline (by angle travelled).
std::vector<LampSpec> SamplePath(const std::vector<LampSpec>& path, int frames) {
  std::vector<double> cum = {0};
  for (size_t i = 1; i < path.size(); ++i)
    cum.push_back(cum.back() + std::hypot(path[i].h_deg - path[i - 1].h_deg,
                                          path[i].v_deg - path[i - 1].v_deg));
  std::vector<LampSpec> out;
  for (int f = 0; f < frames; ++f) {
    const double s = frames == 1 ? 0 : cum.back() * f / (frames - 1);
    size_t k = 1;
    while (k + 1 < path.size() && cum[k] < s) ++k;
    const double seg = cum[k] - cum[k - 1];
    const double t = seg > 0 ? (s - cum[k - 1]) / seg : 0;
    LampSpec l;
    l.h_deg = path[k - 1].h_deg + t * (path[k].h_deg - path[k - 1].h_deg);
    l.v_deg = path[k - 1].v_deg + t * (path[k].v_deg - path[k - 1].v_deg);
    out.push_back(l);
  }
  return out;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

Status WritePicture(const std::string& path, const cv::Mat& bgr8) {
  try {
    if (!cv::imwrite(path, bgr8)) return MakeError(ErrorCode::kIo, path, "cannot write the picture");
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kIo, path, "cannot write the picture: {}", e.what());
  }
  return Ok();
}

// What a render needs besides the model: where it came from, the response and the display.
struct Inputs {
  std::string model_path;
  std::string response_path;  // empty: none known
  ToneMapOptions tonemap;
};

Result<Inputs> ResolveInputs(const std::string& source, const std::string& response_option) {
  Inputs in;
  const fs::path p(source);
  if (fs::is_directory(p)) {
    // A session folder: its model, its response curve, its display settings.
    in.model_path = (p / "model" / "model.exr").string();
    if (!fs::exists(in.model_path)) {
      return MakeError(ErrorCode::kNotFound, in.model_path,
                       "the session has no model yet (run 'rig process {}')", source);
    }
    if (fs::exists(p / "calib" / "response.csv")) in.response_path = (p / "calib" / "response.csv").string();
    if (fs::exists(p / "session.toml")) {
      auto config = LoadConfigOrError((p / "session.toml").string());
      if (!config.ok()) return config.error();
      in.tonemap.field_of_view_deg = config->process.field_of_view_deg;
      in.tonemap.display_min_cd_m2 = config->process.display_min_cd_m2;
      in.tonemap.display_max_cd_m2 = config->process.display_max_cd_m2;
    }
  } else {
    if (!fs::exists(p)) return MakeError(ErrorCode::kNotFound, source, "no such model file or session");
    in.model_path = source;
    // A model inside a session (SESSION/model/x.exr): the session's response.
    const fs::path r = p.parent_path().parent_path() / "calib" / "response.csv";
    if (fs::exists(r)) in.response_path = r.string();
  }
  if (!response_option.empty()) in.response_path = response_option;
  return in;
}

}  // namespace

int RunRender(int argc, char** argv) {
  CLI::App app{"Relight a reflectance model: the sum over lamps of rho(direction) x lamp radiance "
               "x colour x intensity, in linear radiance (the paper's eq. 8). Writes the radiance "
               "(.exr), a picture for a screen (--tonemap), or the picture the camera would have "
               "recorded at an exposure time (--exposure, through the session's response curve).",
               "rig render"};
  std::string source, out, log_level, tonemap_name, sweep_text, response_option;
  std::vector<std::string> lights;
  double exposure_s = 0, fps = 12;
  int frames = 24;
  bool extrapolate = false;
  app.add_option("MODEL", source, "a model EXR (rig fit) or a session folder (its model/model.exr)")
      ->required();
  app.add_option("--light", lights,
                 "lamp H,V[,R,G,B[,I]]: rig angles (deg), colour relative to the capture lamp, "
                 "intensity; repeat for several lamps");
  app.add_option("--sweep", sweep_text,
                 "a lamp moving along H,V:H,V[:H,V...] (rig angles); writes --frames frames "
                 "(plus any --light lamps, held still)");
  app.add_option("--frames", frames, "frames of a --sweep (default 24)")->check(CLI::Range(2, 10000));
  app.add_option("--fps", fps, "frame rate of a --sweep video (default 12)")->check(CLI::Range(0.1, 240.0));
  app.add_option("--exposure", exposure_s,
                 "the 8-bit picture the camera would record at this exposure time (s), "
                 "through the response curve (saturation included)")
      ->check(CLI::PositiveNumber);
  app.add_option("--response", response_option,
                 "response curve (calib/response.csv) for --exposure; default: the session's");
  app.add_option("--tonemap", tonemap_name,
                 "tone mapping for a picture: ward (histogram adjustment), linear, reinhard, "
                 "drago, mantiuk (default for pictures: ward)");
  app.add_flag("--extrapolate", extrapolate,
               "render lamps outside the sampled lamp region (with a warning) instead of refusing");
  app.add_option("--out", out,
                 "output: .exr (linear radiance), .png/.jpg (picture); with --sweep a video "
                 "(.avi, Motion JPEG) whose frames also go to <out without extension>/")
      ->required();
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;
  auto bad = [](const std::string& what, const std::string& msg) {
    return ReportError("render", MakeError(ErrorCode::kInvalidInput, what, "{}", msg));
  };

  if (lights.empty() && sweep_text.empty()) return bad("--light", "give at least one --light or a --sweep");
  std::vector<LampSpec> lamps;
  for (const auto& text : lights) {
    auto l = ParseLamp(text);
    if (!l.ok()) return ReportError("render", l.error());
    lamps.push_back(*l);
  }
  std::vector<LampSpec> sweep;
  if (!sweep_text.empty()) {
    auto path = ParseSweep(sweep_text);
    if (!path.ok()) return ReportError("render", path.error());
    sweep = SamplePath(*path, frames);
  }
  const std::string ext = Lower(fs::path(out).extension().string());
  const bool to_exr = ext == ".exr";
  const bool to_picture = ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif";
  const bool to_video = ext == ".avi";
  if (!sweep.empty() ? !(to_video || to_picture || to_exr) : !(to_exr || to_picture)) {
    return bad(out, sweep.empty() ? "output must end in .exr, .png, .jpg or .tif"
                                  : "a sweep's output must end in .avi (video), or .png/.exr "
                                    "(frames only)");
  }
  if (exposure_s > 0 && !tonemap_name.empty()) return bad("--exposure", "--exposure and --tonemap exclude each other");
  if (to_exr && (exposure_s > 0 || !tonemap_name.empty())) {
    return bad(out, "an .exr holds linear radiance: --exposure and --tonemap need a picture output");
  }
  if (fs::exists(out)) return bad(out, "exists; choose another name (nothing is overwritten)");

  auto inputs = ResolveInputs(source, response_option);
  if (!inputs.ok()) return ReportError("render", inputs.error());
  auto model = LoadModel(inputs->model_path);
  if (!model.ok()) return ReportError("render", model.error());

  ToneMapOptions tonemap = inputs->tonemap;
  if (!tonemap_name.empty()) {
    auto m = ParseToneMapMethod(tonemap_name);
    if (!m.ok()) return ReportError("render", m.error());
    tonemap.method = *m;
  }
  tonemap.srgb = true;
  ResponseCurve response;
  if (exposure_s > 0) {
    if (inputs->response_path.empty()) {
      return bad("--exposure", fmt::format("no response curve known for {}: give --response FILE", source));
    }
    auto r = LoadResponse(inputs->response_path);
    if (!r.ok()) return ReportError("render", r.error());
    response = *r;
  }

  // Refuse (or warn about) lamps outside the sampled region before rendering anything.
  auto check = [&](const LampSpec& l) -> Status {
    const RegionCheck region = model->CheckRegion(LightDirection(l.h_deg, l.v_deg, model->info().light_frame));
    if (region.inside) return Ok();
    const std::string what = fmt::format(
        "lamp {},{} is {:.1f} deg from the nearest sampled lamp (sampling spacing {:.1f} deg): "
        "outside the sampled region",
        l.h_deg, l.v_deg, region.nearest_deg, model->info().sample_spacing_deg);
    if (!extrapolate) return MakeError(ErrorCode::kInvalidInput, "--light", "{}; --extrapolate renders it anyway", what);
    std::fprintf(stderr, "rig render: warning: %s: extrapolated\n", what.c_str());
    return Ok();
  };
  for (const auto& l : lamps) {
    if (Status st = check(l); !st.ok()) return ReportError("render", st.error());
  }
  bool sweep_warned = false;
  for (const auto& l : sweep) {
    const RegionCheck region = model->CheckRegion(LightDirection(l.h_deg, l.v_deg, model->info().light_frame));
    if (region.inside || sweep_warned) continue;
    if (Status st = check(l); !st.ok()) return ReportError("render", st.error().Within("--sweep"));
    sweep_warned = true;
  }

  auto relight = [&](const std::vector<LampSpec>& set) {
    cv::Mat sum;
    for (const auto& l : set) {
      const Vec3 dir = LightDirection(l.h_deg, l.v_deg, model->info().light_frame);
      model->AddLamp(dir, {l.rgb[0] * l.intensity, l.rgb[1] * l.intensity, l.rgb[2] * l.intensity}, &sum);
    }
    return sum;
  };
  // A sweep is tone-mapped with one mapping for all frames (from its brightest frame), so
  // the video shows the light change, not the operator adapting.
  auto picture = [&](const cv::Mat& radiance) -> Result<cv::Mat> {
    if (exposure_s > 0) return RenderExposure(radiance, exposure_s, response.log_exposure);
    return ToneMap(radiance, tonemap);
  };

  if (sweep.empty()) {
    cv::Mat radiance = relight(lamps);
    Status st;
    if (to_exr) {
      st = WriteRgbExr(out, radiance, {{"rig.render", "relit radiance (linear)"}});
    } else {
      auto pic = picture(radiance);
      if (!pic.ok()) return ReportError("render", pic.error());
      st = WritePicture(out, *pic);
    }
    if (!st.ok()) return ReportError("render", st.error());
    std::printf("rig render: wrote %s (%zu lamp%s%s)\n", out.c_str(), lamps.size(),
                lamps.size() == 1 ? "" : "s",
                exposure_s > 0 ? fmt::format(", exposure {} s", exposure_s).c_str()
                : to_exr      ? ", linear radiance"
                              : fmt::format(", tone mapping {}", ToneMapMethodName(tonemap.method)).c_str());
    return 0;
  }

  // ---- Sweep ------------------------------------------------------------------------------
  const fs::path frame_dir = to_video ? fs::path(out).replace_extension("") : fs::path(out).parent_path() / fs::path(out).stem();
  std::error_code ec;
  if (fs::exists(frame_dir)) return bad(frame_dir.string(), "exists; choose another --out (nothing is overwritten)");
  fs::create_directories(frame_dir, ec);
  if (ec) return ReportError("render", MakeError(ErrorCode::kIo, frame_dir.string(), "{}", ec.message()));
  std::vector<cv::Mat> radiance_frames;
  for (const auto& l : sweep) {
    std::vector<LampSpec> set = lamps;
    set.push_back(l);
    radiance_frames.push_back(relight(set));
  }
  if (exposure_s <= 0 && !to_exr && (tonemap.method == ToneMapMethod::kWard || tonemap.method == ToneMapMethod::kLinear)) {
    // One mapping for the whole sweep: the linear scale Ward/linear settle on for the
    // brightest frame, applied to every frame.
    size_t brightest = 0;
    double best = -1;
    for (size_t i = 0; i < radiance_frames.size(); ++i) {
      const double m = cv::mean(Luminance(radiance_frames[i]))[0];
      if (m > best) best = m, brightest = i;
    }
    ToneMapReport report;
    ToneMapOptions linear = tonemap;
    linear.method = ToneMapMethod::kLinear;
    auto probe = ToneMap(radiance_frames[brightest], linear, &report);
    if (!probe.ok()) return ReportError("render", probe.error());
    tonemap = linear;
    tonemap.linear_scale = report.linear_scale;
  }
  cv::VideoWriter video;
  for (size_t i = 0; i < radiance_frames.size(); ++i) {
    const fs::path frame = frame_dir / fmt::format("frame_{:04d}{}", i, to_exr ? ".exr" : ".png");
    Status st;
    if (to_exr) {
      st = WriteRgbExr(frame.string(), radiance_frames[i], {{"rig.render", "relit radiance (linear)"}});
    } else {
      auto pic = picture(radiance_frames[i]);
      if (!pic.ok()) return ReportError("render", pic.error().Within(frame.string()));
      st = WritePicture(frame.string(), *pic);
      if (st.ok() && to_video) {
        try {
          if (!video.isOpened()) {
            video.open(out, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps, pic->size());
            if (!video.isOpened()) st = MakeError(ErrorCode::kIo, out, "cannot open a Motion JPEG video writer");
          }
          if (st.ok()) video.write(*pic);
        } catch (const cv::Exception& e) {
          st = MakeError(ErrorCode::kIo, out, "video: {}", e.what());
        }
      }
    }
    if (!st.ok()) return ReportError("render", st.error());
  }
  video.release();
  std::printf("rig render: wrote %zu frames to %s%s (lamp from %g,%g to %g,%g)\n", sweep.size(),
              frame_dir.string().c_str(), to_video ? (" and " + out).c_str() : "", sweep.front().h_deg,
              sweep.front().v_deg, sweep.back().h_deg, sweep.back().v_deg);
  return 0;
}

}  // namespace rig
