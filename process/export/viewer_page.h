// The relighting page beside a web-format folder: index.html, viewer.js, viewer.css (compiled
// into the binary from process/export/viewer/) and data.js, which holds info.json's content,
// the display settings and — for an untiled model — the plane files in base64, so the page
// opens from file:// as well as served. Tiled models load their tiles with fetch(): serve the
// folder (docs/viewer.md).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/result.h"
#include "process/export/deepzoom.h"
#include "process/model/light_direction.h"

namespace rig {

// (file name, content) of the page's static files.
const std::vector<std::pair<std::string, std::string>>& ViewerAssets();

struct ViewerPage {
  std::string source;                   // what the model is, shown on the page
  Vec3 default_light = {0, 0, 1};       // the lamp when the URL gives none
  nlohmann::json display = {{"encoding", "srgb"}};  // see docs/viewer.md
  bool tiles = false;                   // plane_N.dzi + plane_N_files/ are there
  DeepZoomOptions tile_options;
  std::vector<std::string> images;      // "normals.png", "albedo.png" when in the folder
};

// Writes the page's files into `folder` (which holds info.json and plane_N.jpg); none of them
// may exist yet.
Status WriteViewerPage(const std::string& folder, const ViewerPage& page);

}  // namespace rig
