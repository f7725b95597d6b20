// `rig view`'s folder: the model in relight's web format (only the files its info.json
// declares copied when it is one already, converted as `rig export --format relight` converts
// otherwise), deep-zoom tiles for large images, normals.png/albedo.png found beside the model,
// and the self-contained WebGL2 relighting page (viewer_page.h).
#pragma once

#include <optional>
#include <string>

#include "config/config.h"
#include "config/result.h"
#include "process/model/light_direction.h"

namespace rig {

struct ViewRequest {
  std::string model_path;  // a model: EXR, relight folder, PCA folder, .ptm, .rti
  std::string out;         // the folder written (the caller refuses an existing one)
  std::string tiles = "auto";  // deep-zoom tiles: auto (longer side > 4096), on, off
  std::optional<Vec3> light;   // the page's default lamp; none: the mean of the model's lights
  int quality = 98;            // of converted planes and of tiles
  std::optional<ProcessConfig> process;  // a session's [process]: its display for Ward's curve
};

struct ViewReport {
  int width = 0, height = 0;
  std::string describe;    // the model, as its family describes itself
  std::string how;         // copied as it is, or converted (and how close the conversion is)
  std::string tiles_line;  // the deep-zoom figures; empty: no tiles
  bool tiled = false;
  bool srgb = true;        // the page shows the photographs' encoding; else Ward's curve
};

// Writes the folder into request.out (created). What a failed call leaves there is the
// caller's to remove.
Result<ViewReport> WriteViewFolder(const ViewRequest& request);

}  // namespace rig
