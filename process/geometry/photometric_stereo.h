// Normals and albedo by photometric stereo (Woodham's Lambertian model, I = albedo N.L E),
// with the samples that break it left out: clipped samples (masks), shadowed ones (too dark,
// or N.L <= 0 once the normal is known), and — with the robust estimator — specular and
// cast-shadow outliers by iteratively reweighted least squares (Tukey's biweight on the
// residual, starting from a fit to the middle of each pixel's sorted samples).
//
// Near lamps: a lamp at a finite distance lights every pixel from its own direction with
// its own 1/d^2 fall-off (NearLamp, process/model/light_direction.h, places every pixel); the
// solve is then one 3x3 system per pixel instead of one pseudo-inverse shared by all pixels.
//
// Axis convention of the output: x right, y up, z towards the camera (relight's and
// RTIViewer's); the 8-bit encoding is RGB = round(255 * (n * 0.5 + 0.5)).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/geometry/light_stack.h"
#include "process/model/light_direction.h"

namespace rig {

struct PsOptions {
  bool robust = true;
  int iterations = 6;           // IRLS passes
  double dark_fraction = 0.02;  // a sample below this fraction of the pixel's brightest is shadow
  double trim_low = 0.25, trim_high = 0.25;  // robust start: the middle of the sorted samples
  NearLamp lamp;
  int threads = 2;
};

struct PsResult {
  cv::Mat normals;  // CV_32FC3: x, y, z (not BGR); (0, 0, 0) where no normal could be solved
  cv::Mat albedo;   // CV_32FC3 B, G, R: I / (N.L E), in the stack's units
  cv::Mat valid;    // CV_8UC1: 1 where solved
  cv::Mat inliers;  // CV_16UC1: samples used per pixel
  double time_s = 0;
};

Result<PsResult> PhotometricStereo(const LightStack& stack, const std::vector<Vec3>& directions,
                                   const PsOptions& options = {});

// Re-estimates the light directions from the images themselves (no sphere): alternates
// photometric stereo (robust) with a least-squares fit of every light to the normals and
// albedo of the pixels it lights well. `rounds` alternations, from `start`.
std::vector<Vec3> RefineLightsFromImages(const LightStack& stack, const std::vector<Vec3>& start,
                                         int rounds = 3, const PsOptions& options = {});
// One light from one image given normals and albedo (the held-out image's light in a fold).
Vec3 EstimateLight(const cv::Mat& linear_bgr, const cv::Mat& clipped, const PsResult& ps,
                   const Vec3& start);

// Height by integrating the normals (Frankot-Chellappa, through OpenCV's DFT), in pixels,
// mean zero: CV_32FC1.
cv::Mat IntegrateNormals(const cv::Mat& normals);

// Writes `normals` to an EXR (channels R, G, B = x, y, z, float) and the 8-bit PNG beside it
// (same name, .png), and the albedo to <stem>-albedo.exr / .png (PNG: sRGB, scaled so the
// 99.5th percentile is 1). Returns the paths written.
Result<std::vector<std::string>> WriteNormalsAndAlbedo(const PsResult& ps,
                                                       const std::string& normals_exr);
// The 8-bit pictures alone: normals.png and albedo.png into `folder` (a model's).
Status WriteNormalPictures(const PsResult& ps, const std::string& normals_png,
                           const std::string& albedo_png);

// Writes the height integrated from `normals` (IntegrateNormals) as a one-channel EXR.
Status WriteHeightMap(const cv::Mat& normals, const std::string& exr);

// Where the lamp stands for photometric stereo, from the command line's choices and a
// session's [light_frame] (null: none): `lamp_distance_mm` < 0 takes the session's (with its
// field height and surface depth where those are not given), 0 or `far` a far lamp. A near
// lamp needs the field's height, and |surface depth| + field height below the lamp's distance.
struct LampPlacement {
  double lamp_distance_mm = -1;
  double field_height_mm = 0;
  double surface_depth_mm = std::numeric_limits<double>::quiet_NaN();
  bool far = false;
};
Result<NearLamp> PlaceLamp(const LampPlacement& placement, const LightFrameConfig* session,
                           int image_height);

// Mean and largest angle (degrees) between two normal maps over a mask (CV_8UC1 != 0).
struct AngularError {
  double mean_deg = 0, median_deg = 0, p95_deg = 0;
  size_t pixels = 0;
};
AngularError NormalError(const cv::Mat& normals, const cv::Mat& truth, const cv::Mat& mask);

}  // namespace rig
