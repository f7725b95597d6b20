// Relighting a reflectance model (the paper's eq. 8): any number of lamps — rig angles, colour,
// intensity — summed in linear radiance, a lamp sweeping along a path, the lamp-region check,
// and the pictures and video of a render. What `rig render` does, callable without the CLI.
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/reflectance_model.h"
#include "process/render/tonemap.h"

namespace rig {

// One lamp in rig angles (degrees, commanded: the model's light frame maps them), its colour
// relative to the capture lamp (R, G, B) and an intensity factor.
struct RelightLamp {
  double h_deg = 0, v_deg = 0;
  std::array<double, 3> rgb = {1, 1, 1};
  double intensity = 1;
};

// `frames` lamp positions evenly spaced along a polyline of rig angles (by angle travelled),
// first and last on the path's ends. Colour and intensity are white/1. path: at least 2 points.
std::vector<RelightLamp> SampleLampPath(const std::vector<RelightLamp>& path, int frames);

// What each rendered frame becomes.
enum class RenderDisplay {
  kRadiance,  // linear radiance (EXR)
  kToneMap,   // an 8-bit picture for a screen, through `tonemap`
  kExposure,  // the 8-bit picture the camera would record at `exposure_s`, through the response
  kEncoded,   // the photographs' own encoding (sRGB, clipped as they clip): models fitted to
              // 8-bit photographs render by default as the photographs were
};

struct RelightRequest {
  std::vector<RelightLamp> lamps;  // lit in every frame
  // Empty: one frame lit by `lamps`. Else one frame per position (SampleLampPath), each lit
  // by `lamps` plus a lamp there.
  std::vector<RelightLamp> sweep;
  // A lamp outside the sampled region is refused (kInvalidInput, context "--light"; a sweep's
  // within "--sweep"); with `extrapolate` it is rendered and reported through on_warning
  // (a sweep's first such position only).
  bool extrapolate = false;
  std::function<void(const std::string& message)> on_warning;  // null: logged ("render")
  RenderDisplay display = RenderDisplay::kRadiance;
  ToneMapOptions tonemap;  // kToneMap
  double exposure_s = 0;   // kExposure: seconds, > 0
  // kExposure: the response, g(z) = ln exposure per channel B, G, R (ResponseCurve::log_exposure).
  std::array<std::vector<double>, 3> log_exposure;
};

struct RenderOutput {
  std::vector<cv::Mat> radiance;  // CV_32FC3 BGR linear, one per frame
  // The mapping of every frame's picture (kToneMap): the request's; for a ward or linear sweep
  // the linear scale its brightest frame settles on, so that a video shows the light change,
  // not the operator adapting.
  ToneMapOptions tonemap;
  std::vector<RelightLamp> sweep;  // the request's sweep positions (empty: one frame)
};

// Checks every lamp against the model's sampled region first, then renders every frame.
// Errors: a lamp outside the region without `extrapolate` (kInvalidInput), a tone mapping
// that fails on the sweep's brightest frame. Thread-compatible; the model is only read.
Result<RenderOutput> Relight(const ReflectanceModel& model, const RelightRequest& request);

// The 8-bit BGR picture of one frame (kToneMap or kExposure) with the output's mapping.
Result<cv::Mat> RenderPicture(const cv::Mat& radiance, const RelightRequest& request,
                              const ToneMapOptions& tonemap);

// Output files by extension (case-insensitive): .exr radiance; .png/.jpg/.jpeg/.tif a
// picture; .avi a sweep's video (Motion JPEG).
enum class RenderFileKind { kUnknown, kExr, kPicture, kVideo };
RenderFileKind RenderFileKindOf(const std::string& path);

// Where a sweep's frames go: <out without extension>/ for a video, else
// <out's folder>/<out's stem>/.
std::string SweepFrameDir(const std::string& out);

struct RenderFiles {
  std::string out;        // the file written (single frame or video)
  std::string frame_dir;  // a sweep's frame folder (frame_0000.png|exr, ...); else empty
  size_t frames = 0;
  bool video = false;
};

// Writes a render to `out`: one frame as .exr (radiance) or a picture; a sweep's frames into
// SweepFrameDir(out) (refused if it exists, kInvalidInput; created), and for .avi also the
// video at `fps`. Pictures go through RenderPicture. Errors name the file (kIo).
Result<RenderFiles> WriteRender(const RenderOutput& output, const RelightRequest& request,
                                const std::string& out, double fps);

}  // namespace rig
