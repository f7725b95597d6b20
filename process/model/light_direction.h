// Rig angles to the unit light direction in the object frame, in one place (design.md).
//
// Object frame: x to the right and y up as seen from the camera, z towards the camera.
//   direction(h, v) = ( sin h cos v,  sin v,  cos h cos v )
// where h and v are the physical angles: sign * commanded + offset (config [light_frame]).
#pragma once

#include <array>

#include "config/config.h"

namespace rig {

using Vec3 = std::array<double, 3>;

// Commanded rig angles (degrees) to the unit light direction.
Vec3 LightDirection(double h_deg, double v_deg, const LightFrameConfig& frame = {});

// The inverse: a unit direction to physical angles (degrees), h in (-180, 180].
void DirectionToAngles(const Vec3& dir, double* h_deg, double* v_deg);

}  // namespace rig
