// rig view MODEL --out DIR: the model in relight's web format (copied when it is one already,
// converted as `rig export --format relight` converts otherwise), deep-zoom tiles for large
// images, and a self-contained WebGL2 relighting page (process/export/viewer_page.h).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include <fmt/format.h>

#include "capture/session/render_source.h"
#include "process/export/view_folder.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

struct ViewArgs {
  std::string source, out, tiles = "auto", light, log_level;
  int quality = 98;
};

Result<Vec3> ParseDirection(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      v.push_back(std::stod(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      return MakeError(ErrorCode::kInvalidInput, "--light " + text, "'{}' is not a number", item);
    }
  }
  const double n = v.size() == 3 ? std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) : 0;
  if (v.size() != 3 || !(n > 0)) {
    return MakeError(ErrorCode::kInvalidInput, "--light " + text, "a direction x,y,z (not zero) expected");
  }
  return Vec3{v[0] / n, v[1] / n, v[2] / n};
}

}  // namespace

int RunView(int argc, char** argv) {
  CLI::App app{"Write a self-contained relighting page for a model: the model in relight's web "
               "format (copied if it is one, converted otherwise, as rig export does), deep-zoom "
               "tiles for large images, index.html with a WebGL2 viewer. Open DIR/index.html "
               "(untiled models open from file://; serve a tiled folder, e.g. "
               "python3 -m http.server -d DIR --bind 127.0.0.1).",
               "rig view"};
  ViewArgs a;
  app.add_option("MODEL", a.source, "a model (EXR, relight folder, PCA folder, .ptm, .rti) or a session")
      ->required();
  app.add_option("--out", a.out, "the folder to write; must not exist")->required();
  app.add_option("--tiles", a.tiles, "deep-zoom tiles: auto (longer side > 4096), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  app.add_option("--light", a.light, "the page's default lamp, a direction x,y,z (object frame); "
                                     "default: the mean of the model's lights");
  app.add_option("--jpeg-quality", a.quality, "quality of converted planes and of tiles (default 98, as rig export)")
      ->check(CLI::Range(1, 100));
  AddLogLevelOption(app, &a.log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(a.log_level)) return *rc;

  std::error_code ec;
  if (fs::exists(a.out, ec)) {
    return ReportError("view", MakeError(ErrorCode::kInvalidInput, a.out,
                                         "exists; choose another --out (nothing is overwritten)"));
  }
  // --out did not exist: whatever a failed run leaves in it is removed.
  struct RemoveOnFailure {
    std::string dir;
    bool done = false;
    ~RemoveOnFailure() {
      std::error_code e;
      if (!done) fs::remove_all(dir, e);
    }
  } guard{a.out};
  auto source = ResolveRenderSource(a.source);
  if (!source.ok()) return ReportError("view", source.error());
  ViewRequest request;
  request.model_path = source->model_path;
  request.out = a.out;
  request.tiles = a.tiles;
  request.quality = a.quality;
  request.process = source->process;
  if (!a.light.empty()) {
    auto d = ParseDirection(a.light);
    if (!d.ok()) return ReportError("view", d.error());
    request.light = *d;
  }
  auto view = WriteViewFolder(request);
  if (!view.ok()) return ReportError("view", view.error());
  guard.done = true;
  const ViewReport& r = *view;
  std::printf("rig view: wrote %s/index.html (%dx%d, %s)\n  %s%s\n  display: %s\n  open it %s\n", a.out.c_str(),
              r.width, r.height, r.describe.c_str(), r.how.c_str(), r.tiles_line.c_str(),
              r.srgb
                  ? "the photographs' sRGB encoding, as rig render"
                  : "Ward's curve of the default light as a table (rig render recomputes it per light)",
              r.tiled ? fmt::format("served: python3 -m http.server -d {} --bind 127.0.0.1", a.out).c_str()
                         : "from file:// or served");
  return 0;
}

}  // namespace rig
