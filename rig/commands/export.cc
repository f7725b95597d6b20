// rig export MODEL --format relight|ptm|rti --out PATH: a model in relight's web format or
// RTIViewer's .ptm/.rti, exactly where the format holds it, refitted (and the PSNR lost
// printed) where it does not; every file written is read back and its PSNR measured.
// rig export SESSION --format lp --out DIR: the session's radiance maps as an RTI capture.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include <opencv2/imgcodecs.hpp>

#include "capture/plan/pose.h"
#include "config/atomic_file.h"
#include "process/io/image_io.h"
#include "capture/session/render_source.h"
#include "capture/session/session_lp.h"
#include "process/export/export_model.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/export/convert.h"
#include "process/export/deepzoom.h"
#include "process/export/load_any.h"
#include "process/export/relight_files.h"
#include "process/model/harmonic/model.h"
#include "process/model/lp.h"
#include "rig/commands/command.h"
#include "config/console.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

struct ExportArgs {
  std::string source, format, out, variant = "rgb", basis, log_level, tiles = "auto",
      lp_images = "jpg";
  int hsh_terms = 0, quality = 98;  // q98: 48.2 dB for the icon's web PTM (q95: 44.1)
  bool jpeg_rgb = false;
};

std::string Db(double db) { return std::isinf(db) ? "identical (inf dB)" : fmt::format("{:.2f} dB", db); }

// Deep-zoom tiles of a written web-format folder, by --tiles.
int WriteTilesIfWanted(const ExportArgs& a, int width, int height) {
  if (a.tiles == "off" || (a.tiles == "auto" && !WantsDeepZoom(width, height))) return 0;
  DeepZoomOptions o;
  o.quality = a.quality;
  auto report = WriteDeepZoom(a.out, o);
  if (!report.ok()) return ReportError("export", report.error());
  std::printf("  deep zoom: %d plane files x %d levels, %ld tiles of %d px (overlap %d) in %.2f s\n",
              report->files, report->levels, report->tiles, o.tile_size, o.overlap, report->seconds);
  return 0;
}

}  // namespace

int RunExport(int argc, char** argv) {
  CLI::App app{"Write a reflectance model in relight's web format (info.json + plane_N.jpg, types "
               "ptm and hsh) or as RTIViewer's .ptm (PTM 1.2, RGB or LRGB) or .rti (HSH). Where "
               "the format cannot hold the model exactly (SH, a linear or log fit space, another "
               "order), it is refitted at the model's sampled lights and the PSNR lost is printed.",
               "rig export"};
  ExportArgs a;
  app.add_option("MODEL", a.source,
                 "a model (EXR, relight folder, PCA folder, .ptm, .rti) or a session folder (its model)")
      ->required();
  app.add_option("--format", a.format,
                 "relight, ptm or rti; lp: a SESSION's radiance maps as 8-bit sRGB images + dirs.lp")
      ->required();
  app.add_option("--lp-images", a.lp_images,
                 "--format lp: jpg (default, JPEG q95: what relight-cli reads) or png (lossless)")
      ->check(CLI::IsMember({"jpg", "png"}));
  app.add_option("--out", a.out, "the folder (relight) or file (.ptm, .rti) to write; must not exist")
      ->required();
  app.add_option("--ptm-variant", a.variant,
                 "PTM targets: rgb (default) or lrgb (luminance PTM x RGB albedo; relight's lptm)");
  app.add_option("--basis", a.basis, "--format relight: ptm or hsh (default: the model's, else hsh)");
  app.add_option("--hsh-terms", a.hsh_terms, "HSH targets: 9 (default), 4, or 16 (--format rti only)")
      ->check(CLI::IsMember({4, 9, 16}));
  app.add_option("--jpeg-quality", a.quality, "--format relight: JPEG quality (default 98; relight writes 95, which loses ~4 dB on "
                 "PTM planes: docs/viewer.md)")
      ->check(CLI::Range(1, 100));
  app.add_flag("--jpeg-rgb", a.jpeg_rgb,
               "--format relight: planes in the JPEG RGB colour space (Adobe marker; ~2 dB more, "
               "~2x the bytes). Not for relight's C++ reader, which decodes every plane as YCbCr "
               "(Rti::load); browsers and libjpeg's default honour the marker. Default: YCbCr 4:4:4, "
               "as relight writes rgb planes");
  app.add_option("--tiles", a.tiles,
                 "--format relight: deep-zoom tiles (plane_N.dzi + plane_N_files/, 256 px, overlap 1) "
                 "beside the planes: auto (longer side > 4096), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  AddLogLevelOption(app, &a.log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(a.log_level)) return *rc;

  std::error_code ec;
  if (fs::exists(a.out, ec)) {
    return ReportError("export", MakeError(ErrorCode::kInvalidInput, a.out,
                                           "exists; choose another --out (nothing is overwritten)"));
  }
  if (a.format == "lp") {
    auto lp = ExportSessionLp(a.source, a.out, a.lp_images == "png" ? LpImageFormat::kPng : LpImageFormat::kJpeg);
    if (!lp.ok()) return ReportError("export", lp.error());
    std::printf("rig export: wrote %s and %zu images (%dx%d, 8-bit sRGB %s, radiance %.4g = white) to %s\n",
                lp->lp.c_str(), lp->images, lp->width, lp->height, a.lp_images == "png" ? "PNG" : "JPEG q95",
                lp->white, a.out.c_str());
    if (!lp->lifted.empty()) {
      std::string poses;
      for (const auto& p : lp->lifted) poses += (poses.empty() ? "" : ", ") + p;
      std::fprintf(stderr,
                   "rig export: warning: %zu pose(s) at the horizon written at %.2f deg elevation "
                   "(relight's HSH fit writes NaN for a light at z = 0): %s\n",
                   lp->lifted.size(), kLowestElevationDeg, poses.c_str());
    }
    return 0;
  }
  auto source = ResolveRenderSource(a.source);
  if (!source.ok()) return ReportError("export", source.error());
  const std::string& path = source->model_path;
  ExportRequest request{a.format, a.out, a.variant, a.basis, a.hsh_terms, a.quality, a.jpeg_rgb, {}};
  request.announce = [&](const std::string& plan) {
    std::printf("rig export: %s to %s: %s...\n", path.c_str(), a.format.c_str(), plan.c_str());
    std::fflush(stdout);
  };
  const auto started = std::chrono::steady_clock::now();
  // A line at most every 2 s: which stage, how far.
  auto last_told = started;
  request.progress = [&, last_told](const char* stage, size_t done, size_t total) mutable {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_told < std::chrono::seconds(2)) return;
    last_told = now;
    std::printf("  %s: %zu of %zu lights, %.1f s\n", stage, done, total,
                std::chrono::duration<double>(now - started).count());
    std::fflush(stdout);
  };
  auto exported = ConvertForExport(path, request);
  if (!exported.ok()) return ReportError("export", exported.error());
  const double convert_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  const ReflectanceModel* model = exported->model.get();
  if (exported->as_stored) {
    // Its files, byte for byte (saving again would compress the planes a second time).
    if (Status st = CopyDeclaredWebFiles(path, a.out); !st.ok()) return ReportError("export", st.error());
    std::printf("rig export: wrote %s (relight web format, %s, as the model is "
                "stored: nothing refitted, nothing lost)\n  from %s: %s\n",
                a.out.c_str(), model->family().substr(4).c_str(), path.c_str(), model->Describe().c_str());
    return WriteTilesIfWanted(a, model->width(), model->height());
  }
  const Conversion* conversion = &exported->conversion;
  const RelightCoefficients& c = conversion->coefficients;

  std::string what;
  Result<RelightCoefficients> back = WriteExportFormat(request, c, &what);
  if (!back.ok()) return ReportError("export", back.error());
  std::printf("rig export: wrote %s (%s, %dx%d)\n", a.out.c_str(), what.c_str(), c.width, c.height);
  std::printf("  from %s: %s\n", path.c_str(), model->Describe().c_str());
  std::printf("  %s (%.1f s)\n", conversion->how.c_str(), convert_s);
  if (conversion->exact) {
    std::printf("  held exactly before quantisation (%s over %d lights)\n",
                Db(conversion->psnr_db).c_str(), conversion->lights);
  } else {
    std::printf("  refitted: %s PSNR against the source's render over %d lights, before "
                "quantisation (8-bit sRGB)\n",
                Db(conversion->psnr_db).c_str(), conversion->lights);
  }
  // The whole loss: what a reader of the file renders against the source, at the same lights.
  std::vector<Vec3> lights = c.lights.empty() ? HemisphereDirections() : c.lights;
  const auto reread = WrapRelight(std::move(*back), a.out);
  const double back_db = RenderPsnrDb(*model, *reread, lights, conversion->gain, request.progress);
  std::printf("  as written, read back: %s PSNR against the source over %zu lights (8-bit sRGB)\n",
              Db(back_db).c_str(), lights.size());
  for (const std::string& note : ExportNotes(request, *model, *conversion))
    std::printf("  note: %s\n", note.c_str());
  if (a.format == "relight") return WriteTilesIfWanted(a, c.width, c.height);
  return 0;
}

}  // namespace rig
