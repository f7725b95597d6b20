// rig calibrate-lights SESSION|--lp FILE.lp|--images DIR: light directions from chrome spheres.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "process/geometry/light_refit_loo.h"
#include "process/geometry/photometric_stereo.h"
#include "process/export/relight_files.h"
#include "process/io/exif.h"
#include "process/geometry/sphere_lights.h"
#include "process/model/rti_fit.h"
#include "rig/commands/command.h"
#include "rig/commands/light_source.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

std::string RelativeTo(const std::string& file, const fs::path& dir) {
  std::error_code ec;
  fs::path rel = fs::relative(fs::absolute(file, ec), fs::absolute(dir, ec), ec);
  return ec || rel.empty() ? file : rel.string();
}

}  // namespace

int RunCalibrateLights(int argc, char** argv) {
  CLI::App app{"Light directions from the highlights on chrome spheres in every image: an .lp for "
               "any multi-light capture and, for a rig session, the [light_frame] that maps the "
               "arm's angles to them, with its residual per pose (docs/lights.md).",
               "rig calibrate-lights"};
  std::string source, lp, images, out, log_level;
  std::vector<std::string> sphere_args;
  std::vector<double> sphere_depth_mm;
  double field_height_mm = 0;
  double focal_mm = 0, sensor_width_mm = 0, max_disagreement = 3.0, min_contrast = 8,
         max_blob = 0.03;
  bool force = false, from_images = false, as_given = false, fit_depths = false,
       orthographic = false;
  std::string loo_report;
  int loo_every = 6, rounds = 3, threads = 2;
  app.add_option("source", source, "a session folder");
  app.add_option("--lp", lp, "an .lp capture (its directions are compared, then replaced)");
  app.add_option("--images", images, "a folder of images (JPEG, PNG, TIFF), one lamp each");
  app.add_option("--sphere", sphere_args, "a chrome sphere's circle CX,CY,R in pixels (repeat for "
                 "several; default: found automatically)");
  app.add_option("--focal-mm", focal_mm, "perspective camera: the lens's focal length (mm); "
                 "default: the first photograph's EXIF (FocalLength with FocalPlaneXResolution "
                 "or FocalLengthIn35mmFilm), else orthographic")->check(CLI::PositiveNumber);
  app.add_option("--sensor-width-mm", sensor_width_mm, "the sensor's width (mm), with --focal-mm")
      ->check(CLI::PositiveNumber);
  app.add_flag("--orthographic", orthographic, "the orthographic model whatever the EXIF says");
  app.add_option("--max-disagreement", max_disagreement,
                 "largest angle (deg) two spheres may disagree on an image's light (a near lamp "
                 "whose position is estimated: a sphere's ray may miss the lamp)")
      ->check(CLI::PositiveNumber);
  app.add_option("--field-height-mm", field_height_mm, "the image's height at the object (mm): "
                 "with two or more spheres, the lamp's position and distance are estimated "
                 "(default: a session's [light_frame] field_height_mm)")
      ->check(CLI::PositiveNumber);
  app.add_option("--sphere-depth-mm", sphere_depth_mm, "a sphere centre's z (mm, towards the "
                 "camera from the plane through the arm's centre), one for all or one per sphere "
                 "in order; default: every sphere resting on that plane (z = its radius)");
  app.add_flag("--fit-sphere-depths", fit_depths, "a near lamp on the arm: fit the spheres' depths "
               "(from --sphere-depth-mm or the default) with the lamp's one distance from the "
               "arm's centre over all images");
  app.add_option("--min-contrast", min_contrast, "a highlight's peak over the sphere's median")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-blob", max_blob, "largest highlight blob, as a fraction of the sphere")
      ->check(CLI::Range(1e-4, 1.0));
  app.add_option("--out", out, "the .lp written (a session: default SESSION/calib/lights.lp)");
  app.add_flag("--force", force, "replace an existing output file");
  app.add_flag("--as-given", as_given, "use the --sphere circles exactly as given (default: refined "
               "to the sphere's edge)");
  app.add_flag("--from-images", from_images, "no sphere: re-estimate the .lp's directions from the "
               "images themselves (alternating robust photometric stereo and per-light least "
               "squares, from the given directions)");
  app.add_option("--rounds", rounds, "alternations of --from-images")->check(CLI::Range(1, 50));
  app.add_option("--loo-report", loo_report, "with --from-images: leave-one-out PSNR of the default "
                 "model with the given against the re-estimated directions (Markdown)");
  app.add_option("--loo-every", loo_every, "hold out every n-th image in --loo-report")
      ->check(CLI::Range(1, 1000));
  app.add_option("--threads", threads, "threads")->check(CLI::Range(1, 64));
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;

  CameraModel camera;
  if (focal_mm > 0 || sensor_width_mm > 0) {
    if (focal_mm <= 0 || sensor_width_mm <= 0) {
      std::fprintf(stderr, "rig calibrate-lights: --focal-mm and --sensor-width-mm go together\n");
      return 2;
    }
    if (orthographic) {
      std::fprintf(stderr, "rig calibrate-lights: --orthographic or --focal-mm, not both\n");
      return 2;
    }
  }
  std::vector<SphereCircle> spheres;
  for (const auto& s : sphere_args) {
    SphereCircle c;
    char extra = 0;
    if (std::sscanf(s.c_str(), "%lf,%lf,%lf%c", &c.cx, &c.cy, &c.r, &extra) != 3 || c.r <= 0) {
      std::fprintf(stderr, "rig calibrate-lights: --sphere '%s' is not CX,CY,R (pixels, R > 0)\n",
                   s.c_str());
      return 2;
    }
    spheres.push_back(c);
  }
  auto src = LoadLightSource(source, lp, images, 1);
  if (!src.ok()) return ReportError("calibrate-lights", src.error());
  if (src->kind == "model") {
    std::fprintf(stderr, "rig calibrate-lights: %s: a model has no photographs to find a sphere "
                         "in; give a session, --lp or --images\n", source.c_str());
    return 2;
  }
  const LightStack& stack = src->stack;
  if (focal_mm > 0) {
    camera.focal_px = focal_mm / sensor_width_mm * stack.width;
    camera.source = fmt::format("from --focal-mm {} and --sensor-width-mm {}", focal_mm,
                                sensor_width_mm);
  } else if (orthographic) {
    camera.source = "--orthographic (no EXIF read)";
  } else if (!from_images) {
    // No lens given: the photographs' EXIF, if they carry a focal length and a sensor width.
    if (src->first_photo.empty()) {
      camera.source = "no --focal-mm, and no photograph to read EXIF from";
    } else {
      auto lens = ReadExifLens(src->first_photo);
      if (!lens.ok()) return ReportError("calibrate-lights", lens.error());
      const ExifFocal f = FocalFromExif(*lens, stack.width, stack.height);
      if (f.focal_mm > 0) {
        camera.focal_px = f.focal_mm / f.sensor_width_mm * stack.width;
        camera.source = fmt::format("from the EXIF of {}: {}", src->first_photo, f.how);
      } else {
        camera.source = fmt::format(
            "no --focal-mm, and {} {}", src->first_photo,
            !lens->has_exif ? "has no EXIF"
            : !f.how.empty() ? f.how
            : lens->focal_mm > 0 ? "has an EXIF FocalLength but neither FocalPlaneXResolution "
                                   "nor FocalLengthIn35mmFilm to give the sensor's width"
                                 : "has no EXIF focal length");
      }
    }
  }
  const double session_field_mm =
      src->session_config ? src->session_config->light_frame.field_height_mm : 0.0;
  if ((!sphere_depth_mm.empty() || fit_depths) && field_height_mm <= 0 && session_field_mm <= 0) {
    std::fprintf(stderr, "rig calibrate-lights: --sphere-depth-mm and --fit-sphere-depths place "
                         "the spheres for the lamp's position, which needs --field-height-mm (or "
                         "a session's [light_frame] field_height_mm)\n");
    return 2;
  }
  if (out.empty()) {
    if (src->kind != "session") {
      std::fprintf(stderr, "rig calibrate-lights: --out FILE.lp is required for --lp and --images\n");
      return 2;
    }
    out = (fs::path(source) / "calib" / "lights.lp").string();
  }
  std::error_code ec;
  if (fs::exists(out, ec) && !force) {
    std::fprintf(stderr, "rig calibrate-lights: %s exists (give --force to replace it)\n", out.c_str());
    return 2;
  }
  if (from_images) {
    if (src->kind != "lp") {
      std::fprintf(stderr, "rig calibrate-lights: --from-images refines the directions of an .lp "
                           "(give --lp)\n");
      return 2;
    }
    PsOptions po;
    po.threads = threads;
    const auto dirs = RefineLightsFromImages(stack, stack.directions, rounds, po);
    double sum = 0, worst = 0;
    for (size_t k = 0; k < dirs.size(); ++k) {
      const double e = AngleDeg(dirs[k], stack.directions[k]);
      sum += e;
      worst = std::max(worst, e);
    }
    std::printf("no sphere: directions re-estimated from the images (%d rounds of robust "
                "photometric stereo and per-light least squares)\nchange from the .lp: mean %.3f "
                "deg, max %.3f deg\n", rounds, sum / dirs.size(), worst);
    const fs::path out_dir = fs::absolute(out, ec).parent_path();
    fs::create_directories(out_dir, ec);
    std::vector<std::string> names;
    for (const auto& n : stack.names) names.push_back(RelativeTo(n, out_dir));
    if (auto st = WriteLp(out, names, dirs); !st.ok()) return ReportError("calibrate-lights", st.error());
    std::printf("wrote %s\n", out.c_str());
    if (loo_report.empty()) return 0;
    auto cap = LoadRtiCapture(lp);
    if (!cap.ok()) return ReportError("calibrate-lights", cap.error());
    auto rows = CompareLightsLoo(*cap, stack, loo_every, rounds, {}, threads);
    if (!rows.ok()) return ReportError("calibrate-lights", rows.error());
    std::string md = fmt::format(
        "# Leave-one-out: the default model with the .lp's directions and with directions "
        "re-estimated from the images\n\n{}: {} images, {}x{}; every {}th image held out ({} folds); "
        "the re-estimation ({} rounds) redone inside every fold from the fold's images, the held-out "
        "light estimated from its image against the fold's normals.\n\n"
        "| lights | PSNR of mean MSE (dB) | median PSNR (dB) | B/px | mean change from the .lp (deg) |\n"
        "|---|---|---|---|---|\n",
        lp, stack.size(), stack.width, stack.height, loo_every, (*rows)[0].folds, rounds);
    for (const auto& r : *rows) {
      md += fmt::format("| {} | {:.2f} | {:.2f} | {:.2f} | {} |\n", r.lights, r.psnr_mean_mse_db,
                        r.psnr_median_db, r.bytes_per_pixel,
                        r.mean_change_deg > 0 ? fmt::format("{:.2f}", r.mean_change_deg) : "0");
      std::printf("%-32s PSNR %.2f dB (median %.2f dB), %.2f B/px\n", r.lights.c_str(),
                  r.psnr_mean_mse_db, r.psnr_median_db, r.bytes_per_pixel);
    }
    std::ofstream o(loo_report, std::ios::binary | std::ios::trunc);
    o << md;
    if (!o.flush()) {
      std::fprintf(stderr, "rig calibrate-lights: %s: cannot write\n", loo_report.c_str());
      return 1;
    }
    std::printf("wrote %s\n", loo_report.c_str());
    return 0;
  }
  HighlightOptions ho;
  ho.min_contrast = min_contrast;
  ho.max_blob_fraction = max_blob;
  const cv::Mat median = MedianGrey(stack);
  if (spheres.empty()) {
    auto found = DetectChromeSpheres(stack, ho);
    if (!found.ok()) return ReportError("calibrate-lights", found.error());
    spheres = *found;
  } else {
    if (!as_given)
      for (auto& s : spheres) s = RefineCircle(median, s);
  }
  std::printf("camera model: %s\n", camera.Describe().c_str());
  for (size_t i = 0; i < spheres.size(); ++i)
    std::printf("sphere %zu: centre (%.2f, %.2f) px, radius %.2f px\n", i + 1, spheres[i].cx,
                spheres[i].cy, spheres[i].r);
  // The lamp's position: asked for with --field-height-mm or --sphere-depth-mm (its errors
  // are the user's), or tried when a session's config knows the field and the capture allows.
  SphereField field;
  field.depth_mm = sphere_depth_mm;
  field.fit_depths = fit_depths;
  if (field_height_mm > 0 || !sphere_depth_mm.empty() || fit_depths) {
    field.field_height_mm = field_height_mm > 0 ? field_height_mm : session_field_mm;
  } else if (session_field_mm > 0) {
    if (spheres.size() < 2)
      std::printf("lamp position: not estimated (one sphere sees the lamp's direction, not its "
                  "distance; two at different places in the field triangulate it)\n");
    else if (camera.perspective())
      std::printf("lamp position: not estimated (the spheres are placed with the orthographic "
                  "model only)\n");
    else
      field.field_height_mm = session_field_mm;
  }
  auto cal = CalibrateFromSpheres(stack, spheres, camera, ho, max_disagreement, field);
  if (!cal.ok()) return ReportError("calibrate-lights", cal.error());
  std::string lamp_toml, lamp_csv;
  if (cal->lamp) {
    const LampEstimate& lamp = *cal->lamp;
    std::string depths;
    for (double z : lamp.depth_mm) depths += fmt::format("{}{:.1f}", depths.empty() ? "" : ", ", z);
    std::printf("\nlamp position from %zu spheres (orthographic, field %.1f mm high, origin at the "
                "arm's centre = the image centre; sphere centres at z = %s mm, %s):\n",
                spheres.size(), field.field_height_mm, depths.c_str(),
                lamp.depth_fitted    ? "fitted"
                : lamp.depth_assumed ? "assumed resting on the plane z = 0"
                                     : "as given");
    if (lamp.depth_fitted) {
      std::string fitted, start;
      for (size_t j = 0; j < lamp.depth_mm.size(); ++j) {
        fitted += fmt::format("{}{:.1f} +- {:.1f}", j ? ", " : "", lamp.depth_mm[j],
                              lamp.depth_sigma_mm[j]);
        start += fmt::format("{}{:.1f}", j ? ", " : "", lamp.depth_start_mm[j]);
      }
      std::printf("sphere depths fitted with the lamp's one distance over all images: z = %s mm "
                  "(1-sigma at %.2f px of highlight; from %s mm); the fit's distance %.1f +- %.1f "
                  "mm, rms %.2f of that sigma\n", fitted.c_str(), field.edge_px, start.c_str(),
                  lamp.fit_distance_mm, lamp.fit_distance_sigma_mm, lamp.fit_rms);
    }
    std::printf("%-12s %8s %8s %8s %11s %8s %8s %9s\n", "image", "x_mm", "y_mm", "z_mm",
                "distance_mm", "sigma_mm", "miss_mm", "parallax");
    lamp_csv = "image,determined,x_mm,y_mm,z_mm,distance_mm,sigma_mm,miss_mm,parallax_deg\n";
    for (size_t k = 0; k < stack.size(); ++k) {
      const LampFix& f = lamp.fixes[k];
      const std::string name = fs::path(stack.names[k]).filename().string();
      if (f.determined)
        std::printf("%-12s %8.1f %8.1f %8.1f %11.1f %8.1f %8.3f %8.2f\n", name.c_str(),
                    f.position_mm[0], f.position_mm[1], f.position_mm[2], f.distance_mm,
                    f.sigma_mm, f.miss_mm, f.parallax_deg);
      else
        std::printf("%-12s no distance: %s\n", name.c_str(), f.note.c_str());
      lamp_csv += fmt::format("{},{},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{:.4f},{:.4f}\n", name,
                              f.determined ? 1 : 0, f.position_mm[0], f.position_mm[1],
                              f.position_mm[2], f.distance_mm, f.sigma_mm, f.miss_mm,
                              f.parallax_deg);
    }
    if (lamp.near) {
      double parallax = 0, residual = 0;
      for (size_t k = 0; k < stack.size(); ++k) {
        parallax = std::max(parallax, cal->sphere_disagreement_deg[k]);
        residual = std::max(residual, lamp.residual_deg[k]);
      }
      std::printf("lamp: near, %.1f mm from the arm's centre (median of the %d of %zu images that "
                  "give a distance), median ray miss %.3f mm\n", lamp.distance_mm,
                  lamp.determined, stack.size(), lamp.median_miss_mm);
      std::printf("directions: from the arm's centre to the lamp at that distance (the spheres "
                  "see it up to %.2f deg apart; their rays miss it by at most %.2f deg)\n",
                  parallax, residual);
      if (lamp.depth_assumed)
        std::printf("(the spheres' depths are assumed: where they do not rest on the plane "
                    "through the arm's centre, give --sphere-depth-mm, or --fit-sphere-depths for "
                    "a lamp on the arm; docs/lights.md measures what a wrong depth costs)\n");
      lamp_toml = fmt::format("lamp_distance_mm = {:.1f}  # median of {} of {} images, {} "
                              "spheres, ray miss {:.3f} mm\nfield_height_mm = {:.3f}\n",
                              lamp.distance_mm, lamp.determined, stack.size(), spheres.size(),
                              lamp.median_miss_mm, field.field_height_mm);
      // The surface: the spheres' depths place it only if they rest on it.
      if (lamp.depth_assumed) {
        std::printf("surface: the spheres assumed resting on the plane z = 0 place it there "
                    "(surface_depth_mm unset); give --sphere-depth-mm or --fit-sphere-depths "
                    "for a suggestion\n");
      } else {
        const std::vector<double> under =
            SurfaceUnderSpheres(lamp, spheres, field.field_height_mm, stack.height);
        double mean = 0;
        std::string each;
        for (double z : under) {
          mean += z / under.size();
          each += fmt::format("{}{:.1f}", each.empty() ? "" : ", ", z);
        }
        const bool fits = lamp.distance_mm > field.field_height_mm + std::abs(mean);
        std::printf("surface: if the spheres rest on the object's surface (facing the camera), "
                    "it lies at z = %s mm under them (their centres' z minus their radii): "
                    "suggested surface_depth_mm = %.1f, their mean%s; spheres on posts, or "
                    "away from the object, say nothing of its depth\n",
                    each.c_str(), mean,
                    fits ? "" : " (but no farther from the lamp than the field is tall: it "
                                "would be refused)");
        lamp_toml += fmt::format("# surface_depth_mm = {:.1f}  # only if the spheres rest on the "
                                 "object's surface: their centres' z minus radii, {} mm\n",
                                 mean, each);
      }
    } else {
      std::printf("lamp: far (%d of %zu images give a distance; these spheres resolve one up to "
                  "~%.0f mm): directions as for a far lamp, the spheres' mean\n",
                  lamp.determined, stack.size(), lamp.resolvable_mm);
      lamp_toml = fmt::format("lamp_distance_mm = 0  # far: beyond the ~{:.0f} mm {} spheres "
                              "resolve\n", lamp.resolvable_mm, spheres.size());
    }
    std::printf("suggested: [light_frame] %s", lamp_toml.c_str());
  }

  // The .lp: image paths relative to its folder.
  const fs::path out_dir = fs::absolute(out, ec).parent_path();
  fs::create_directories(out_dir, ec);
  std::vector<std::string> names;
  for (size_t k = 0; k < stack.size(); ++k) {
    if (src->kind == "session")
      names.push_back(RelativeTo((fs::path(source) / "hdr" / (stack.names[k] + ".exr")).string(), out_dir));
    else if (src->kind == "images")
      names.push_back(RelativeTo((fs::path(images) / stack.names[k]).string(), out_dir));
    else
      names.push_back(RelativeTo(stack.names[k], out_dir));
  }
  if (auto st = WriteLp(out, names, cal->directions); !st.ok())
    return ReportError("calibrate-lights", st.error());
  std::printf("wrote %s (%zu lights)\n", out.c_str(), stack.size());
  if (src->kind == "lp") {
    double sum = 0, worst = 0;
    for (size_t k = 0; k < stack.size(); ++k) {
      const double e = AngleDeg(stack.directions[k], cal->directions[k]);
      sum += e;
      worst = std::max(worst, e);
    }
    std::printf("against the .lp's directions: mean %.3f deg, max %.3f deg\n", sum / stack.size(),
                worst);
  }
  if (src->kind != "session") return 0;

  // A session: the [light_frame] from the arm's angles.
  auto fit = FitLightFrame(stack.h_deg, stack.v_deg, cal->directions);
  if (!fit.ok()) return ReportError("calibrate-lights", fit.error());
  const auto& f = fit->frame;
  const auto& was = src->session_config->light_frame;
  std::printf("\npose        h_deg  v_deg  residual_deg (sphere -> [light_frame] fitted)\n");
  std::string csv = "pose,h_deg,v_deg,x,y,z,residual_deg\n";
  for (size_t k = 0; k < stack.size(); ++k) {
    std::printf("%-10s %6.1f %6.1f  %8.3f\n", stack.names[k].c_str(), stack.h_deg[k], stack.v_deg[k],
                fit->residual_deg[k]);
    csv += fmt::format("{},{},{},{:.6f},{:.6f},{:.6f},{:.4f}\n", stack.names[k], stack.h_deg[k],
                       stack.v_deg[k], cal->directions[k][0], cal->directions[k][1],
                       cal->directions[k][2], fit->residual_deg[k]);
  }
  std::printf("residual: rms %.3f deg, max %.3f deg\n", fit->rms_deg, fit->max_deg);
  std::printf("a tilt of the arm about the camera axis, if allowed: %.3f deg (rms %.3f deg); "
              "[light_frame] cannot hold a tilt\n", fit->tilt_deg, fit->rms_with_tilt_deg);
  const std::string toml = fmt::format(
      "# fitted by rig calibrate-lights from {} chrome sphere(s), {} poses; rms {:.3f} deg\n"
      "[light_frame]\nh_offset_deg = {:.4f}\nv_offset_deg = {:.4f}\nh_sign = {}\nv_sign = {}\n{}",
      spheres.size(), stack.size(), fit->rms_deg, f.h_offset_deg, f.v_offset_deg, f.h_sign,
      f.v_sign, lamp_toml);
  std::printf("\n%s", toml.c_str());
  std::printf("(the session ran with h_offset_deg = %.4f, v_offset_deg = %.4f, h_sign = %d, "
              "v_sign = %d, lamp_distance_mm = %.1f)\n", was.h_offset_deg, was.v_offset_deg,
              was.h_sign, was.v_sign, was.lamp_distance_mm);
  std::vector<std::pair<std::string, std::string>> files = {{"light_frame.toml", toml},
                                                            {"lights.csv", csv}};
  if (!lamp_csv.empty()) files.emplace_back("lamp.csv", lamp_csv);
  for (const auto& [name, text] : files) {
    const fs::path p = out_dir / name;
    if (fs::exists(p, ec) && !force) {
      std::fprintf(stderr, "rig calibrate-lights: %s exists (give --force to replace it)\n",
                   p.string().c_str());
      return 2;
    }
    std::ofstream o(p, std::ios::binary | std::ios::trunc);
    o << text;
    if (!o.flush()) {
      std::fprintf(stderr, "rig calibrate-lights: %s: cannot write\n", p.string().c_str());
      return 1;
    }
    std::printf("wrote %s\n", p.string().c_str());
  }
  return 0;
}

}  // namespace rig
