// The simulator's ground truth in a session's truth/ folder, and reading it back so that
// evaluation can compare against the exact radiance and BRDF at any light direction.
//
//   truth/scene.json          what re-creates the scene and the response: the [sim] keys
//                             that define them, the scene's full description, the response,
//                             the light frame, the lamp radiance and the poses
//   truth/response.csv        "level,g_B,g_G,g_R": g(z) = ln(radiance * seconds) per level
//                             (SimResponse::LogExposure), 256 rows
//   truth/radiance/<pose>.exr the exact scene radiance of every pose (float R, G, B; header:
//                             pose, h_deg, v_deg, light_dir, lamp_radiance_rgb, units)
#pragma once

#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/config.h"
#include "config/result.h"
#include "capture/plan/pose.h"
#include "sim/scene.h"
#include "sim/sim_camera.h"

namespace rig {

// Writes every truth file (atomically; existing files are replaced, so a resumed session
// may write it again). `sim` supplies the keys stored to re-create scene and response.
Status WriteTruth(const std::string& truth_dir, const SimConfig& sim, const SimScene& scene,
                  const SimResponse& response, const std::vector<Pose>& poses,
                  const LightFrameConfig& light_frame,
                  const std::array<double, 3>& lamp_radiance_rgb);

// The same from a configuration: scene and response from config.sim, the poses of
// config.grid, config.light_frame, config.lamp.radiance_rgb.
Status WriteTruth(const std::string& truth_dir, const Config& config);

// Truth read back from truth/scene.json.
struct SimTruth {
  SimScene scene;
  SimResponse response;
  std::vector<Pose> poses;
  LightFrameConfig light_frame;
  std::array<double, 3> lamp_radiance_rgb{};
  nlohmann::json json;  // the whole scene.json

  // Exact apparent BRDF (CV_32FC3 BGR) for commanded rig angles, through light_frame.
  cv::Mat BrdfAtAngles(double h_deg, double v_deg) const;
};

// Reads truth/scene.json, re-creates scene and response, and checks the re-created scene
// describes itself exactly as stored (kCorrupt otherwise: written by another version).
Result<SimTruth> LoadTruth(const std::string& truth_dir);
Result<SimScene> LoadTruthScene(const std::string& truth_dir);

}  // namespace rig
