// Relighting a reflectance model (the paper's eq. 8): any number of lamps — rig angles, colour,
// intensity — summed in linear radiance, a lamp sweeping along a path, the lamp-region check,
// and the pictures and video of a render. What `rig render` does, callable without the CLI.
#pragma once

#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/reflectance_model.h"
#include "process/render/envmap.h"
#include "process/render/tonemap.h"

namespace rig {

// One lamp in rig angles (degrees, commanded: the model's light frame maps them) or as a unit
// direction in the object frame (x right, y up as seen from the camera, z towards the camera:
// the .lp convention), its colour relative to the capture lamp (R, G, B) and an intensity
// factor.
struct RelightLamp {
  double h_deg = 0, v_deg = 0;
  std::optional<Vec3> direction;  // set: used as it is, h_deg / v_deg ignored
  std::array<double, 3> rgb = {1, 1, 1};
  double intensity = 1;
};

// A unit direction in the object frame from azimuth (in the image plane, from +x towards +y,
// counter-clockwise as seen from the camera) and elevation (above the object plane, 90: from
// the camera), degrees: (cos el cos az, cos el sin az, sin el).
Vec3 AzimuthElevationDirection(double azimuth_deg, double elevation_deg);

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
  // A fixed display (kToneMap, kEncoded), so that lamp intensity shows and pictures compare:
  // display_ev: linear, pixel = radiance · 2^EV before the encoding (no tone mapping);
  // display_reference: a radiance map (CV_32FC3) whose Ward curve (or linear scale, with
  // tonemap.method kLinear) is applied to every frame. Neither set: a single frame is mapped
  // with the curve of the same lamps at intensity 1 (so intensity 1 renders as before and
  // intensity 4 is brighter through the same curve); a sweep with one linear scale (below).
  std::optional<double> display_ev;
  cv::Mat display_reference;
  // An environment map (lat-long CV_32FC3, checked) lighting every frame besides the lamps;
  // `harmonic` is the model's coefficients when it is a harmonic model (projection), else null.
  cv::Mat envmap;
  EnvmapOptions envmap_options;
  const Model* harmonic = nullptr;
};

struct RenderOutput {
  std::vector<cv::Mat> radiance;  // CV_32FC3 BGR linear, one per frame
  // The mapping of every frame's picture (kToneMap): the request's; for a ward or linear sweep
  // the linear scale its brightest frame settles on, so that a video shows the light change,
  // not the operator adapting.
  ToneMapOptions tonemap;
  std::vector<RelightLamp> sweep;  // the request's sweep positions (empty: one frame)
  // The model's valid mask (CV_8U, 0 = flagged by the fit; empty: all valid). Pictures fill
  // flagged pixels from their neighbours; radiance (EXR) keeps them 0.
  cv::Mat valid;
  std::string display_note;  // how the pictures are mapped, for the log line
  std::optional<EnvmapRender> envmap;  // the environment's part (its radiance and figures)
};

// Flagged pixels (valid == 0) filled from their valid neighbours: repeated 3x3 averages of
// the valid (and already filled) neighbours until none is left. *filled: how many.
cv::Mat FillFlaggedPixels(const cv::Mat& radiance, const cv::Mat& valid, size_t* filled);

// Checks every lamp against the model's sampled region first, then renders every frame.
// Errors: a lamp outside the region without `extrapolate` (kInvalidInput), a tone mapping
// that fails on the sweep's brightest frame. Thread-compatible; the model is only read.
Result<RenderOutput> Relight(const ReflectanceModel& model, const RelightRequest& request);

// The 8-bit BGR picture of one frame (kToneMap, kEncoded or kExposure) with the output's
// mapping (radiance as it is: flagged pixels are filled by WriteRender before this).
Result<cv::Mat> RenderPicture(const cv::Mat& radiance, const RelightRequest& request,
                              const ToneMapOptions& tonemap);

// "H,V" of a rig-angle lamp, "dir=x,y,z" of a direction lamp (messages).
std::string LampName(const RelightLamp& lamp);

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
  size_t filled_pixels = 0;  // flagged pixels filled from neighbours in each picture
};

// Writes a render to `out`: one frame as .exr (radiance) or a picture; a sweep's frames into
// SweepFrameDir(out) (refused if it exists, kInvalidInput; created), and for .avi also the
// video at `fps`. Pictures go through RenderPicture. Errors name the file (kIo).
Result<RenderFiles> WriteRender(const RenderOutput& output, const RelightRequest& request,
                                const std::string& out, double fps);

}  // namespace rig
