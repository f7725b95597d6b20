// Rig angles to the unit light direction in the object frame, in one place (design.md).
//
// Object frame: x to the right and y up as seen from the camera, z towards the camera.
//   direction(h, v) = ( sin h cos v,  sin v,  cos h cos v )
// where h and v are the physical angles: sign * commanded + offset (config [light_frame]).
//
// Near lamps (docs/lights.md): NearLamp places every pixel and gives its own direction to the
// lamp and its own fall-off; photometric stereo and the harmonic fit both use it.
#pragma once

#include <vector>

#include <array>

#include <opencv2/core.hpp>

#include "config/config.h"

namespace rig {

using Vec3 = std::array<double, 3>;

// Commanded rig angles (degrees) to the unit light direction.
Vec3 LightDirection(double h_deg, double v_deg, const LightFrameConfig& frame = {});

// The inverse: a unit direction to physical angles (degrees), h in (-180, 180].
void DirectionToAngles(const Vec3& dir, double* h_deg, double* v_deg);

// A lamp at a finite distance. Pixel (i, j) of a W x H image lies at
// ((i + 0.5 - W/2), (H/2 - j - 0.5)) * mm_per_px on the plane z = plane_z_mm (0: through the
// arm's centre of rotation), or at a given depth per pixel, the lamp commanded to `dir` at
// distance_mm * dir.
struct NearLamp {
  double distance_mm = 0;  // 0: a far lamp (one direction for every pixel)
  double mm_per_px = 0;
  // The surface's plane when there is no depth map: z (mm, along the camera axis, positive
  // towards the camera) relative to the arm's centre of rotation ([light_frame]
  // surface_depth_mm); 0: the plane through the centre.
  double plane_z_mm = 0;
  // CV_32FC1: every pixel's surface depth z (mm, towards the camera) relative to the arm's
  // centre of rotation; empty: the plane z = plane_z_mm.
  cv::Mat depth_mm;
  // Pixel (i, j)'s surface depth: the depth map's, else the plane's.
  double DepthAt(int i, int j) const {
    return depth_mm.empty() ? plane_z_mm : depth_mm.at<float>(j, i);
  }
  bool near() const { return distance_mm > 0 && mm_per_px > 0; }
  // Direction from pixel (i, j) of a W x H image to the lamp commanded to `dir`, and the
  // fall-off (distance / d)^2.
  Vec3 At(int i, int j, int width, int height, const Vec3& dir, double* falloff) const;
  // The same from any image position (u, v) (pixels from the top-left corner: pixel (i, j)'s
  // centre is (i + 0.5, j + 0.5)) at depth z_mm, e.g. a tile's centre.
  Vec3 AtPosition(double u, double v, double z_mm, int width, int height, const Vec3& dir,
                  double* falloff) const;
  // 1 / fall-off of pixel (i, j), d^2 / distance^2: what divides its sample (no square root).
  double InverseFalloff(int i, int j, int width, int height, const Vec3& dir) const;
  // The largest square tile (pixels, at least 1) inside which every pixel's direction stays
  // within max_deg of the direction at the tile's centre, for every lamp of a W x H image on
  // the plane z = plane_z_mm (its |z| is added to the field's radius; with a depth map, the
  // map's largest |z|):
  // moving the surface point by s changes the direction by at most s / |lamp - point|, and
  // |lamp - point| >= distance - the farthest point's distance from the centre of rotation.
  int TilePx(int width, int height, double max_deg) const;
  // From a configuration's [light_frame] (lamp_distance_mm, field_height_mm,
  // surface_depth_mm) for images of `height` rows; far when either of the first two is 0.
  static NearLamp FromLightFrame(const LightFrameConfig& frame, int height);
  // Whether samples divided by this lamp's fall-off equal those divided by `o`'s, bit for bit
  // (two far lamps always; a lamp with a depth map is never taken as equal to another).
  bool SameSamplingAs(const NearLamp& o) const;
};

// The angle between two directions (need not be unit), degrees.
double AngleBetweenDeg(const Vec3& a, const Vec3& b);
// Largest nearest-neighbour angle among directions (degrees): the sampling's own spacing.
double SampleSpacingDeg(const std::vector<Vec3>& directions);

}  // namespace rig
