// The Motor interface: the lamp arm's two axes, in the rig's own angles (degrees).
#pragma once

#include <string>
#include <vector>

#include "config/result.h"
#include "capture/plan/pose.h"

namespace rig {

class Motor {
 public:
  virtual ~Motor() = default;

  // "grbl on /dev/ttyACM0", "sim motor".
  virtual std::string Describe() const = 0;

  // Opens the device (and waits for it to be ready).
  virtual Status Open() = 0;
  virtual void Close() = 0;

  // Runs the homing cycle; afterwards the axes are at their zero.
  virtual Status Home() = 0;

  // Moves to `pose` and returns only once motion has completed (never while the arm is
  // still moving: the camera must not fire then). Fails outside the soft limits.
  virtual Status MoveTo(const Pose& pose) = 0;

  // Refuses, before anything moves, poses the controller cannot reach: outside its travel or
  // its own soft limits (after Open). The error names the pose, the rig's limit and the
  // controller's. Controllers that hold no such limits: nothing to check.
  virtual Status CheckReach(const std::vector<Pose>& poses) {
    (void)poses;
    return Ok();
  }

  // Where the axes are now, as the controller reports it.
  virtual Result<Pose> Position() = 0;

  // Stops motion at once (feed hold / target = current). Safe to call at any time.
  virtual Status Stop() = 0;

  // After a lost connection: reopen and re-home or verify, as configured.
  virtual Status Reconnect() = 0;

  // Clears a controller's alarm lock without homing (GRBL's $X), trusting the position it
  // holds. Controllers without such a lock: nothing to do.
  virtual Status Unlock() { return Ok(); }
};

}  // namespace rig
