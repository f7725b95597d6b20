// rig normals SESSION|MODEL|--lp FILE.lp --out NORMALS.exr: photometric-stereo normals and albedo.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "process/geometry/photometric_stereo.h"
#include "rig/commands/command.h"
#include "capture/session/light_source.h"

namespace rig {

namespace fs = std::filesystem;

int RunNormals(int argc, char** argv) {
  CLI::App app{"Surface normals and albedo by photometric stereo (robust by default: clipped and "
               "dark samples masked, specular and shadowed ones down-weighted by IRLS). Writes "
               "NORMALS.exr (float R, G, B = x right, y up, z towards the camera), NORMALS.png "
               "(RGB = n * 0.5 + 0.5), NORMALS-albedo.exr and NORMALS-albedo.png "
               "(docs/lights.md).",
               "rig normals"};
  std::string source, lp, lights, out, model_folder, height, log_level;
  bool plain = false, far = false;
  double lamp_mm = -1, field_mm = 0, surface_mm = std::nan("");
  int threads = 2;
  app.add_option("MODEL", source, "a model or a session folder (rendered at 37 directions)");
  app.add_option("--lp", lp, "an .lp capture");
  app.add_option("--lights", lights, "an .lp whose directions replace the capture's (e.g. from "
                 "rig calibrate-lights), same image count and order");
  app.add_option("--out", out, "the normals EXR (PNG and albedo beside it)")->required();
  app.add_flag("--plain", plain, "plain least squares over the unmasked samples (no IRLS)");
  app.add_option("--lamp-distance-mm", lamp_mm, "a near lamp at this distance (default: a "
                 "session's [light_frame] lamp_distance_mm; 0: far)")->check(CLI::NonNegativeNumber);
  app.add_option("--field-height-mm", field_mm, "the field's height at the object (mm), with "
                 "--lamp-distance-mm")->check(CLI::NonNegativeNumber);
  app.add_option("--surface-depth-mm", surface_mm, "the surface's z (mm, towards the camera from "
                 "the arm's centre of rotation), with a near lamp (default: a session's "
                 "[light_frame] surface_depth_mm, else 0)");
  app.add_flag("--far", far, "ignore a session's lamp distance (the far-lamp assumption)");
  app.add_option("--model-folder", model_folder, "also write normals.png and albedo.png into this "
                 "folder (a model's, for its relighting page)");
  app.add_option("--height", height, "also integrate the normals into a height map (EXR, "
                 "pixels; Frankot-Chellappa)");
  app.add_option("--threads", threads, "threads")->check(CLI::Range(1, 64));
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;
  std::error_code ec;
  for (const std::string& p : {out, height})
    if (!p.empty() && fs::exists(p, ec)) {
      std::fprintf(stderr, "rig normals: %s exists; choose another --out\n", p.c_str());
      return 2;
    }
  auto src = LoadLightSource(source, lp, "", 1);
  if (!src.ok()) return ReportError("normals", src.error());
  if (!lights.empty()) {
    if (Status st = OverrideDirections(lights, &*src); !st.ok()) return ReportError("normals", st.error());
  }
  const LightStack& stack = src->stack;
  PsOptions o;
  o.robust = !plain;
  o.threads = threads;
  const LampPlacement placement{lamp_mm, field_mm, surface_mm, far};
  auto lamp = PlaceLamp(placement, src->session_config ? &src->session_config->light_frame : nullptr,
                        stack.height);
  if (!lamp.ok()) return ReportError("normals", lamp.error());
  o.lamp = *lamp;
  auto ps = PhotometricStereo(stack, stack.directions, o);
  if (!ps.ok()) return ReportError("normals", ps.error());
  const double solved = cv::countNonZero(ps->valid) / static_cast<double>(stack.width * stack.height);
  std::printf("photometric stereo: %s, %s lamp%s, %zu images, %dx%d, %.1f%% of pixels solved, "
              "%.2f s\n", o.robust ? "robust (IRLS, Tukey)" : "plain least squares",
              o.lamp.near() ? "near" : "far",
              o.lamp.near() ? fmt::format(" at {:.0f} mm", o.lamp.distance_mm).c_str() : "",
              stack.size(), stack.width, stack.height, 100 * solved, ps->time_s);
  fs::create_directories(fs::absolute(out, ec).parent_path(), ec);
  auto paths = WriteNormalsAndAlbedo(*ps, out);
  if (!paths.ok()) return ReportError("normals", paths.error());
  for (const auto& p : *paths) std::printf("wrote %s\n", p.c_str());
  if (!model_folder.empty()) {
    const std::string n = (fs::path(model_folder) / "normals.png").string();
    const std::string a = (fs::path(model_folder) / "albedo.png").string();
    if (auto st = WriteNormalPictures(*ps, n, a); !st.ok()) return ReportError("normals", st.error());
    std::printf("wrote %s\nwrote %s\n", n.c_str(), a.c_str());
  }
  if (!height.empty()) {
    if (auto st = WriteHeightMap(ps->normals, height); !st.ok()) return ReportError("normals", st.error());
    std::printf("wrote %s\n", height.c_str());
  }
  return 0;
}

}  // namespace rig
