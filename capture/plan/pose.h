// Lamp poses and the grid the session visits.
#pragma once

#include <string>
#include <vector>

#include "config/config.h"
#include "config/result.h"

namespace rig {

// A lamp position in the rig's own angles.
struct Pose {
  double h_deg = 0;
  double v_deg = 0;
  // Stable, sortable name: "h030_v10"; fractional "h032.5_v10"; negative "hm010_v05".
  std::string Name() const;
  bool operator==(const Pose&) const = default;
};

// Parses a name made by Pose::Name().
Result<Pose> ParsePoseName(const std::string& name);

// The poses of the grid in visiting order: serpentine (every other row reversed, so each
// move is one step) or raster.
std::vector<Pose> PlanGrid(const GridConfig& grid);

// Why `pose` is outside the motor's soft limits ("h 120 v 10 deg is outside the soft limits
// h -5..95 v -5..60"), or empty when it is inside. Every motor backend refuses such a move.
std::string SoftLimitViolation(const MotorConfig& motor, const Pose& pose);

// The seconds a move from `from` to `to` takes by the motor's configuration: each axis a
// trapezoid (accelerate at accel_deg_per_s2 to speed_deg_per_s, cruise, decelerate), both
// axes at once, the longer one counting. An estimate for planning: no settle, no protocol.
double MoveSeconds(const MotorConfig& motor, const Pose& from, const Pose& to);

}  // namespace rig
