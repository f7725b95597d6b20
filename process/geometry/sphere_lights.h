// Light directions from reflective (chrome) spheres: the sphere found in the capture (or given),
// the specular highlight of every image located to sub-pixel precision, reflected into the
// lamp's direction; and the [light_frame] (offsets, signs, and a tilt it cannot hold) fitted
// to a rig session's arm angles.
//
// Camera models. Orthographic (the default, and the field's usual assumption): the view
// direction is +z at every pixel, a sphere pixel at (dx, dy) from the centre has the normal
// (dx / r, -dy / r, sqrt(1 - ...)). Perspective (focal length in pixels, principal point at
// the image centre): every pixel has its own view ray; the sphere's centre lies on the ray
// through the circle's centre at the distance its angular radius gives.
// Either way: L = 2 (N.V) N - V at the highlight, x right, y up, z towards the camera.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "config/config.h"
#include "config/result.h"
#include "process/geometry/lamp_position.h"
#include "process/geometry/light_stack.h"

namespace rig {

struct SphereCircle {
  double cx = 0, cy = 0, r = 0;  // pixels, continuous (pixel (i, j) covers [i, i+1) x [j, j+1))
};

struct CameraModel {
  double focal_px = 0;  // 0: orthographic
  std::string source;   // where the model came from (said in Describe), e.g. "--focal-mm"
  bool perspective() const { return focal_px > 0; }
  std::string Describe() const;
};

struct HighlightOptions {
  // A highlight is a peak this many times above the sphere's median (after subtracting it).
  double min_contrast = 8;
  // Its half-maximum blob may cover at most this fraction of the disc (a saturated blob
  // larger than that is no point lamp's highlight: refused, naming the image).
  double max_blob_fraction = 0.03;
  // Finding a sphere automatically asks more of a candidate circle, in 60% of the images: a
  // peak this many times above the disc's 90th percentile (a glossy object's lobe stands ~30x
  // above its diffuse, a mirror's far more), with a blob at most this fraction of the disc.
  double detect_contrast = 50;
  double detect_blob_fraction = 0.006;
};

struct Highlight {
  double x = 0, y = 0;   // sub-pixel image position
  Vec3 normal{};         // the sphere's normal there
  Vec3 direction{};      // the lamp direction it reflects
  int blob_px = 0;       // pixels of the half-maximum blob
  double blob_fraction = 0;  // of the disc
  double contrast90 = 0;     // (peak - median) / the disc's 90th percentile
  bool saturated = false;
};

// Finds chrome spheres automatically: circles (Hough on the log median image, refined to
// sub-pixel from radial edge points) that show a sharp highlight in most images. Errors when
// none is found (naming the capture).
Result<std::vector<SphereCircle>> DetectChromeSpheres(const LightStack& stack,
                                                      const HighlightOptions& options = {});

// Refines a circle given roughly (e.g. by the user) to the sphere's edge; returns it unchanged
// if no clear edge is found.
SphereCircle RefineCircle(const cv::Mat& median_grey, const SphereCircle& rough);

// The per-pixel median of the stack's grey images (CV_32FC1).
cv::Mat MedianGrey(const LightStack& stack);

// The highlight of image `k` on the sphere; errors (kInvalidInput) name the image: no
// highlight, or a saturated blob too large to be one.
Result<Highlight> LocateHighlight(const LightStack& stack, size_t k, const SphereCircle& sphere,
                                  const CameraModel& camera, const HighlightOptions& options = {});

// Where the spheres are in the object frame of lamp_position.h (mm, origin at the arm's centre
// of rotation, at the image centre), for the lamp's position; orthographic camera only.
struct SphereField {
  double field_height_mm = 0;  // the image's height at the object; 0: no lamp position
  // Per sphere (in the order given), its centre's z: mm towards the camera from the plane
  // z = 0 through the arm's centre. Empty: every sphere rests on that plane (its centre one
  // radius in front of it, z = r); one value: every sphere's.
  std::vector<double> depth_mm;
  // The highlight's position accuracy in pixels: a sphere of radius r px then gives the
  // direction to 2 * edge_px / r rad (its normal to edge_px / r). 0.1 px: the circle-finding
  // accuracy process_lights_test asserts, and it matches the sessions' largest direction error
  // (0.35 deg on a 33.6 px sphere, docs/lights.md).
  double edge_px = 0.1;
  // Fit every sphere's depth (from `depth_mm` or the resting default) together with the lamp's
  // one distance from the arm's centre over all images: a near lamp on an arm keeps its
  // distance, and grazing lamps see a depth error as a shift across their rays. Assumes the
  // arm's centre at the image centre.
  bool fit_depths = false;
  LampOptions lamp;
};

struct LampEstimate {
  std::vector<LampFix> fixes;  // per image
  std::vector<double> depth_mm;  // every sphere centre's z used
  bool depth_assumed = true;     // resting on the plane (no depth given, none fitted)
  // With SphereField::fit_depths: the depths' 1-sigma, where the fit started, and the fit's
  // own distance (1-sigma) and rms residual (in units of the directions' assumed sigma).
  bool depth_fitted = false;
  std::vector<double> depth_sigma_mm, depth_start_mm;
  double fit_distance_mm = 0, fit_distance_sigma_mm = 0, fit_rms = 0;
  int determined = 0;            // images whose fix is determined
  // Near: the lamp's distance is determined in at least half of the images; distance_mm is
  // the median over those, median_miss_mm their median ray miss.
  bool near = false;
  double distance_mm = 0, median_miss_mm = 0;
  double resolvable_mm = 0;  // the median of the fixes' resolvable_mm
  // Near only, per image: the direction from the arm's centre to the lamp at distance_mm, and
  // the largest angle between a sphere's ray and the direction from its highlight to that lamp.
  std::vector<Vec3> directions;
  std::vector<double> residual_deg;
};

struct SphereCalibration;

// The lamp's position in every image from the highlights of two or more spheres (`cal`, as
// CalibrateFromSpheres found them, its directions not needed). Errors (kInvalidInput): fewer
// than two spheres, overlapping spheres, no field height, a perspective camera, a depth list
// whose length is neither 1 nor the spheres'; depths to fit from a far lamp.
Result<LampEstimate> EstimateLamp(const SphereCalibration& cal, int width, int height,
                                  const CameraModel& camera, const SphereField& field);

// Where the object's surface would lie under spheres resting on it (the plane facing the
// camera): per sphere, its centre's z (`lamp.depth_mm`) minus its radius in mm (field height
// over image height per px). The sphere geometry says no more: spheres on posts or floating
// (the simulator's) give no surface depth; spheres assumed resting (no depth given or fitted)
// give z = 0 by construction.
std::vector<double> SurfaceUnderSpheres(const LampEstimate& lamp,
                                        const std::vector<SphereCircle>& spheres,
                                        double field_height_mm, int height);

struct SphereCalibration {
  std::vector<SphereCircle> spheres;
  // per image: the direction (the spheres' mean; a near lamp: from the arm's centre), and every
  // sphere's highlight
  std::vector<Vec3> directions;
  std::vector<std::vector<Highlight>> highlights;  // [image][sphere]
  std::vector<double> sphere_disagreement_deg;     // per image: largest angle between spheres
  std::optional<LampEstimate> lamp;                // with a field height and two or more spheres
};

// Every image's direction from every sphere. With two or more spheres, images whose spheres
// disagree by more than `max_disagreement_deg` are an error naming the image. With
// `field.field_height_mm` > 0 the lamp's position is estimated too (EstimateLamp, its errors
// returned); when it is near, every direction is the one from the arm's centre and the check
// is on what remains after the parallax: each sphere's ray against the lamp triangulated.
Result<SphereCalibration> CalibrateFromSpheres(const LightStack& stack,
                                               const std::vector<SphereCircle>& spheres,
                                               const CameraModel& camera,
                                               const HighlightOptions& options = {},
                                               double max_disagreement_deg = 3.0,
                                               const SphereField& field = {});

double AngleDeg(const Vec3& a, const Vec3& b);

// The [light_frame] fitted to commanded angles and measured directions: the signs tried both
// ways, the offsets by Gauss-Newton; a tilt (rotation of the arm's frame about the camera
// axis, which [light_frame] cannot hold) fitted beside it to say whether one is there.
struct LightFrameFit {
  LightFrameConfig frame;                 // the best offsets and signs (tilt 0)
  std::vector<double> residual_deg;       // per pose, with `frame`
  double rms_deg = 0, max_deg = 0;
  double tilt_deg = 0;                    // with a tilt allowed
  double rms_with_tilt_deg = 0;
};
Result<LightFrameFit> FitLightFrame(const std::vector<double>& h_deg,
                                    const std::vector<double>& v_deg,
                                    const std::vector<Vec3>& measured,
                                    const LightFrameConfig& start = {});

}  // namespace rig
