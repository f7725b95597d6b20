// Real spherical harmonics exactly as in docs/paper-notes.md (the paper's eq. 2-5, corrected).
//
// Angle convention (object frame: x right, y up, z towards the camera): θ is the polar angle
// from +z (the camera axis), φ = atan2(y, x) the azimuth in the image plane. With the
// paper's Legendre recurrence (which carries the Condon-Shortley phase (-1)^m):
//   Y_00 = 1/(2√π),  Y_1,-1 = -√(3/4π)·y,  Y_10 = √(3/4π)·z,  Y_11 = -√(3/4π)·x.
// Coefficients are indexed k = l² + l + m (l = 0..L, m = -l..l): (L+1)² terms for order L.
#pragma once

#include "process/model/light_direction.h"

namespace rig {

// Associated Legendre P_lm(x), 0 <= m <= l, |x| <= 1, by the paper's recurrences (eq. 4).
double AssocLegendre(int l, int m, double x);

// N_lm = sqrt((2l+1)/(2π) · (l-|m|)!/(l+|m|)!)  (eq. 3 with 2π).
double ShNormalization(int l, int m);

// Y_lm(θ, φ) (eq. 2), θ and φ in radians.
double ShY(int l, int m, double theta_rad, double phi_rad);

// Index of (l, m) in a coefficient vector: l² + l + m.
inline int ShIndex(int l, int m) { return l * l + l + m; }

// All (order+1)² values at a unit direction (any non-zero vector; it is normalised), written
// to out[0 .. (order+1)²). Uses the recurrences once for every m (O(L²)).
void ShEvalAll(int order, const Vec3& direction, double* out);

// The unit direction's polar angle from +z and azimuth atan2(y, x), radians.
void DirectionToSpherical(const Vec3& direction, double* theta_rad, double* phi_rad);

}  // namespace rig
