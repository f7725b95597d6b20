// Light directions from chrome spheres for a session, an .lp capture or a folder of images:
// the workflow of `rig calibrate-lights` (docs/lights.md) — the camera model, the spheres, the
// lamp's position, the .lp written, and for a session the [light_frame] fitted to the arm's
// angles with its residual per pose. Or, with no sphere, an .lp's directions re-estimated from
// its images (with a leave-one-out comparison).
#pragma once

#include <cstdio>
#include <string>
#include <vector>

#include "capture/session/light_source.h"
#include "config/result.h"
#include "process/geometry/sphere_lights.h"

namespace rig {

struct LightCalibrationRequest {
  std::string source;  // the session folder (a session), as given
  std::string lp;      // the .lp (--lp)
  std::string images;  // the image folder (--images)
  std::string out;     // the .lp written; empty: SESSION/calib/lights.lp
  bool force = false;  // replace existing outputs
  std::vector<SphereCircle> spheres;  // empty: found automatically
  bool as_given = false;              // the circles exactly as given (else refined to the edge)
  // The lens: focal_mm with sensor_width_mm, or orthographic; neither: the first photo's EXIF.
  double focal_mm = 0, sensor_width_mm = 0;
  bool orthographic = false;
  double max_disagreement_deg = 3.0;
  double field_height_mm = 0;          // 0: a session's [light_frame] field_height_mm
  std::vector<double> sphere_depth_mm; // one for all or one per sphere
  bool fit_depths = false;
  HighlightOptions highlight;
  // No sphere: the .lp's directions re-estimated from its images.
  bool from_images = false;
  int rounds = 3;
  std::string loo_report;  // with from_images: a Markdown leave-one-out comparison
  int loo_every = 6;
  int threads = 2;
};

// Runs the calibration on `source` (LoadLightSource's), printing what it finds to `out` and
// writing the .lp (and a session's calib/light_frame.toml, lights.csv, lamp.csv). Bad requests
// and existing outputs without `force` are kInvalidInput naming the file or option.
Status CalibrateLights(const LightCalibrationRequest& request, const LightSource& source,
                       std::FILE* out);

}  // namespace rig
