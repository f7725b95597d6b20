// The capture a light command reads (rig calibrate-lights, rig normals): a session's radiance
// maps with their arm angles, an .lp capture, a folder of images, or a fitted model rendered
// at a set of directions.
#pragma once

#include <optional>
#include <string>

#include "config/config.h"
#include "config/result.h"
#include "process/geometry/light_stack.h"

namespace rig {

struct LightSource {
  std::string kind;        // "session", "lp", "images", "model"
  std::string path;        // the session folder, the .lp, the image folder or the model
  LightStack stack;
  std::optional<Config> session_config;  // a session's session.toml
  // A photograph of the capture, for its EXIF: the first image; a session's first JPEG frame;
  // empty for a model or a session without one.
  std::string first_photo;
};

// `positional`: a session folder or a model; `lp`: an .lp file; `images`: a folder of images
// (no directions known). Exactly one must be given.
Result<LightSource> LoadLightSource(const std::string& positional, const std::string& lp,
                                    const std::string& images, int downsample);

// The directions of an .lp (e.g. from rig calibrate-lights) in place of the source's: the same
// image count and order.
Status OverrideDirections(const std::string& lp, LightSource* source);

}  // namespace rig
