// A near lamp's position from the rays two or more chrome spheres reflect towards it: the
// point nearest the rays (weighted least squares), its distance from the arm's centre of
// rotation with an uncertainty from the directions' noise, and when the rays are too nearly
// parallel to tell a distance, the distance beyond which these spheres cannot tell the lamp
// from a far one.
//
// Frame: the object frame of process/model/light_direction.h in millimetres, with its origin at
// the arm's centre of rotation (the field's centre: the image centre, on the plane z = 0 the
// near-lamp model of docs/lights.md takes as the object's surface). A lamp commanded to (h, v)
// sits at lamp_distance_mm * LightDirection(h, v) there.
#pragma once

#include <string>
#include <vector>

#include "process/model/light_direction.h"

namespace rig {

struct LampRay {
  Vec3 origin_mm{};        // the highlight's point on the sphere
  Vec3 direction{};        // unit: the direction the sphere reflects the lamp's light from
  double sigma_rad = 0;    // 1-sigma of the direction (> 0)
};

struct LampFix {
  bool determined = false;  // the distance is known to `max_relative_sigma` (LampOptions)
  Vec3 position_mm{};       // the point nearest the rays (when they converge in front of them)
  double distance_mm = 0;   // |position_mm|: from the arm's centre
  double sigma_mm = 0;      // 1-sigma of distance_mm from the rays' direction noise
  double miss_mm = 0;       // rms distance of position_mm from the rays (a quality figure)
  double parallax_deg = 0;  // the largest angle between two of the rays
  // The distance at which the widest pair of spheres would see `max_relative_sigma`: beyond it
  // these spheres cannot tell the lamp from a far one.
  double resolvable_mm = 0;
  std::string note;         // why it is not determined
};

struct LampOptions {
  // A distance is reported when its 1-sigma uncertainty is at most this fraction of it (at 10 %
  // the parallax is 10 sigmas of the directions' noise: a far lamp seen through noisy or
  // slightly biased spheres does not pass for a finite one).
  double max_relative_sigma = 0.1;
};

// The point nearest `rays` (at least two, or a bug). Weights 1 / (sigma * range)^2, so every ray
// counts by its angular error; re-weighted three times with the ranges found.
LampFix TriangulateRays(const std::vector<LampRay>& rays, const LampOptions& options = {});

// The lamp at a known distance from the arm's centre: the unit direction u minimising the rays'
// weighted distances from distance_mm * u (Gauss-Newton on the sphere, from `start`). Returns
// u; `residual_deg` (if given) gets, per ray, the angle between its direction and the direction
// from its origin to the lamp.
Vec3 LampDirectionAtDistance(const std::vector<LampRay>& rays, double distance_mm,
                             const Vec3& start, std::vector<double>* residual_deg = nullptr);

}  // namespace rig
