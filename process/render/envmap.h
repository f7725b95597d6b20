// Relighting by an environment: the scene lit by a whole latitude-longitude HDR map, restricted
// to the directions the model answers. Harmonic models fitted in linear space (SH, HSH, PTM):
// the map is projected onto the model's basis once, then every pixel is one dot product of
// its coefficients with that projection (exact for the map's texels, as fast as one lamp).
// Other models (PCA, neural, harmonic in sRGB/log space, whose ρ is not linear in the basis):
// N lamps drawn by importance sampling over the map's luminance × solid angle (seeded), summed.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/harmonic/model.h"
#include "process/model/reflectance_model.h"

namespace rig {

// Lat-long convention (object frame: x right, y up as seen from the camera, z towards it):
// texel (column c, row r) of a W×H map has u = (c + 0.5) / W, v = (r + 0.5) / H, azimuth
// φ = 360°·(u − 0.5) + rotate_deg, elevation θ = 180°·(0.5 − v), direction
// (cos θ sin φ, sin θ, cos θ cos φ): the centre of the map is +z (the camera's side, where
// the lamps are), the top row is +y, and φ, θ are the rig's own h, v angles (light_direction.h),
// so rotating the map by δ moves its light as adding δ to a lamp's h does.
Vec3 EnvmapDirection(double u, double v, double rotate_deg);

struct EnvmapOptions {
  double rotate_deg = 0;   // about the vertical (y) axis
  double intensity = 1;    // the map's radiance is multiplied by this
  int samples = 256;       // sampling: lamps drawn (with replacement; equal texels merge)
  uint64_t seed = 1;       // sampling: std::mt19937_64
  bool extrapolate = false;  // use the whole map, also where the model was never lit
  bool force_sampling = false;  // sample even a harmonic model (tests, comparisons)
  int max_width = 512;     // the map is area-averaged to at most this width first (energy kept)
};

struct EnvmapRender {
  cv::Mat radiance;        // CV_32FC3 BGR linear; flagged pixels 0
  bool projected = false;  // true: basis projection; false: importance sampling
  int samples = 0;         // sampling: lamps drawn
  int distinct_lamps = 0;  // sampling: distinct texels rendered
  int terms = 0;           // projection: basis terms
  int map_width = 0, map_height = 0;  // the working resolution
  // Of the map's luminance × solid angle: the part outside the directions the model answers
  // (left out unless extrapolate).
  double outside_energy_fraction = 0;
  // Wall time: the map's preparation (resampling, directions, region, projection or the
  // sampling's distribution) and the per-pixel part (dot products, or the lamps summed).
  double prepare_s = 0, pixels_s = 0;
};

// Reads and checks a map: .hdr/.pic/.exr, 2:1 (width == 2 · height), every value finite and
// ≥ 0. Errors name the file (kNotFound, kInvalidInput).
Result<cv::Mat> LoadEnvironmentMap(const std::string& path);
// The checks alone, for a map in memory; `name` is the error's context.
Status CheckEnvironmentMap(const cv::Mat& map, const std::string& name);

// `harmonic`: the model's coefficients when it is a harmonic model (nullptr otherwise); with
// linear fit space it is projected, else sampled. Errors: a bad map (kInvalidInput).
Result<EnvmapRender> RenderEnvironment(const ReflectanceModel& model, const Model* harmonic,
                                       const cv::Mat& map, const EnvmapOptions& options);

}  // namespace rig
