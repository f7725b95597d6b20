// The simulator's analytic scene: a sphere in front of a tilted plane carrying a relief,
// with textured Lambertian and glossy materials, whose exact radiance and apparent BRDF are
// known for any lamp direction.
//
// Geometry. A fixed orthographic camera looks down -z: pixel (i, j) (column, row; row 0 at
// the top) sees the point x = (i + 0.5 - W/2) / (H/2), y = (H/2 - j - 0.5) / (H/2), so y runs
// over [-1, 1] and x over [-W/H, W/H]. The object frame is the one of
// process/model/light_direction.h: x right, y up, z towards the camera; the view direction is +z.
//
// Reflectance. Every pixel has a normal N, a diffuse albedo a (per channel, a procedural
// texture), and a normalised Blinn-Phong lobe (ks, shininess n). For a point lamp in the unit
// direction L, with H = normalize(L + V), V = +z:
//
//   rho(L) = radiance_scale * (a / pi + ks * (n + 8) / (8 pi) * max(0, N.H)^n)
//            * max(0, N.L) * visible(L)
//
// rho is the *apparent* BRDF of the paper: pixel radiance / lamp radiance, per channel.
// visible() is 0 where the sphere casts a shadow on the plane ("full" scene only); attached
// shadows (N.L <= 0) are 0 everywhere. radiance_scale carries the lamp's irradiance at the
// object per unit lamp radiance; it is chosen so that, with the default sim camera (gain 1
// electron per radiance unit per second, 20000 e full well) and the default bracket (1/400
// .. 1/6 s), the sharpest gloss saturates the long exposures while the darkest lit texture
// is still recorded by the longest (about 3.5 decades of scene radiance).
//
// Scenes (config sim.scene): "matte" (Lambertian only), "gloss" (broad lobes), "sharp"
// (a sharp lobe on the sphere), "full" (gloss, the relief, and the sphere's cast shadow).
// Everything is deterministic from (scene, width, height, seed).
//
// Calibration targets (sim.chrome_spheres, sim.matte_sphere; off by default): up to two
// chrome spheres (a mirror-like sharp lobe, ks 0.8, n 1000, over a 0.5% grey diffuse; top left,
// top right) and a matte grey sphere (bottom right), in front of the plane; in "full" they
// cast and receive shadows like the main sphere.
//
// Near lamp (sim.lamp_distance_mm > 0): the lamp is a point at that distance from the origin
// (the arm's centre of rotation) in the commanded direction; every pixel sees it from its own
// surface point, in its own direction, with the 1/d^2 fall-off normalised to 1 at the origin.
// Radiance() applies it; Brdf() stays the far-lamp apparent BRDF (the relighting truth).
// sim.field_height_mm gives the scene's 2 units of height in mm.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/model/light_direction.h"

namespace rig {

// Material ids of MaterialIds().
enum class SimMaterialId : uint8_t { kPlane = 0, kSphere = 1, kRelief = 2, kChrome = 3, kMatte = 4 };

// A calibration sphere as the camera sees it: centre and radius in pixels (column, row; the
// pixel grid's continuous coordinates, pixel (i, j) covering [i, i + 1) x [j, j + 1)).
struct SimSphereView {
  SimMaterialId material = SimMaterialId::kChrome;
  double cx_px = 0, cy_px = 0, r_px = 0;
  Vec3 center{};  // object frame, scene units
  double radius = 0;
};

class SimScene {
 public:
  // Builds the scene for sim.scene, sim.width x sim.height, sim.seed. Fails (kInvalidInput,
  // naming the key) on an unknown scene name or a size the config schema would refuse.
  static Result<SimScene> Create(const SimConfig& sim);

  int width() const { return width_; }
  int height() const { return height_; }
  const std::string& kind() const { return kind_; }
  int seed() const { return seed_; }
  double radiance_scale() const { return radiance_scale_; }
  bool cast_shadows() const { return cast_shadows_; }

  // Exact scene radiance for a point lamp in the unit direction `light_dir` (object frame)
  // with radiance `lamp_rgb` (R, G, B): CV_32FC3, BGR, = Brdf(light_dir) * lamp per channel.
  cv::Mat Radiance(const Vec3& light_dir, const std::array<double, 3>& lamp_rgb) const;

  // The exact apparent BRDF rho of every pixel for any unit direction: CV_32FC3, BGR.
  cv::Mat Brdf(const Vec3& light_dir) const;

  // rho of one pixel (column i, row j), in double precision, (B, G, R).
  std::array<double, 3> BrdfAt(int i, int j, const Vec3& light_dir) const;

  // Per-pixel truth for evaluation: unit normals (CV_32FC3 holding x, y, z — not BGR),
  // diffuse albedo (CV_32FC3 BGR, without radiance_scale), material ids (CV_8UC1).
  cv::Mat Normals() const;
  cv::Mat Albedo() const;
  cv::Mat MaterialIds() const;

  // Every parameter of the scene, enough to re-create and check it (see LoadTruthScene).
  nlohmann::json Describe() const;

  // The chrome and matte spheres present (sim.chrome_spheres, sim.matte_sphere).
  std::vector<SimSphereView> CalibrationSpheres() const;
  // The near lamp's distance in scene units (0: a far lamp) and mm per scene unit.
  double lamp_distance() const { return lamp_distance_; }
  double mm_per_unit() const { return mm_per_unit_; }
  // The plane's z (mm, towards the camera from the origin, the arm's centre of rotation) at
  // the image centre: what [light_frame] surface_depth_mm states of this scene (-0.5 x
  // sim.field_height_mm; the plane is tilted and the spheres stand in front of it).
  double plane_depth_mm() const { return plane_z0_ * mm_per_unit_; }
  // The surface point pixel (i, j) sees (object frame, scene units).
  Vec3 SurfacePoint(int i, int j) const;
  // The direction pixel (i, j) sees a lamp commanded to `light_dir` in, and the fall-off
  // factor (1 for a far lamp).
  Vec3 LightAt(int i, int j, const Vec3& light_dir, double* falloff) const;

 private:
  struct Material {
    std::string name;
    double ks = 0;          // specular albedo of the normalised Blinn-Phong lobe
    double shininess = 1;   // its exponent n
  };

  struct ExtraSphere {
    Vec3 center{};
    double radius = 0;
    SimMaterialId id = SimMaterialId::kChrome;
  };

  SimScene() = default;
  void Build();
  // Build's steps: the layout (geometry, colours jittered by the seed, materials, the extra
  // spheres), then every pixel's surface.
  void ChooseLayout(uint64_t seed);
  struct Surface;
  Surface SurfaceAt(double x, double y, uint64_t seed) const;
  // rho of pixel p = (i, j) for the unit direction l (shadows included), B, G, R.
  void Shade(int i, int j, const Vec3& l, float* out) const;
  bool ShadowedByExtras(int i, int j, const Vec3& l) const;
  bool Shadowed(int i, int j, const Vec3& l) const;
  double PixelX(int i) const { return (i + 0.5 - width_ / 2.0) / (height_ / 2.0); }
  double PixelY(int j) const { return (height_ / 2.0 - j - 0.5) / (height_ / 2.0); }
  double PlaneZ(double x, double y) const;

  std::string kind_;
  int width_ = 0, height_ = 0, seed_ = 0;
  double radiance_scale_ = 0;
  bool cast_shadows_ = false;
  bool relief_ = false;

  // Geometry parameters (object frame units: half the image height).
  Vec3 plane_normal_{};      // unit
  double plane_z0_ = 0;      // plane: z = plane_z0_ + plane_dzdx_ * x + plane_dzdy_ * y
  double plane_dzdx_ = 0, plane_dzdy_ = 0;
  Vec3 sphere_center_{};
  double sphere_radius_ = 0;
  std::array<double, 4> relief_box_{};  // x_min, x_max, y_min, y_max
  double relief_amplitude_ = 0, relief_wavelength_ = 0;
  std::array<double, 3> plane_rgb_light_{}, plane_rgb_dark_{}, sphere_rgb_a_{}, sphere_rgb_b_{},
      relief_rgb_{};  // R, G, B
  double checker_size_ = 0, noise_cell_ = 0;
  std::array<Material, 5> materials_;
  int chrome_spheres_ = 0;
  bool matte_sphere_ = false;
  std::vector<ExtraSphere> extras_;
  double lamp_distance_ = 0, mm_per_unit_ = 50;

  // Per pixel, row-major.
  std::vector<float> normal_;  // 3 per pixel: x, y, z
  std::vector<float> albedo_;  // 3 per pixel: B, G, R
  std::vector<uint8_t> material_;
  std::vector<float> depth_;   // z of the surface point, per pixel
};

}  // namespace rig
