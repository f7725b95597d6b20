// rig calibrate-lights' workflow in named steps: the camera model, the directions re-estimated
// from the images (no sphere), the spheres, the lamp's position, the .lp, a session's frame.
#include "capture/session/light_calibration.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <utility>

#include <fmt/format.h>

#include "capture/session/session_store.h"
#include "process/export/relight_files.h"
#include "process/geometry/light_refit_loo.h"
#include "process/geometry/photometric_stereo.h"
#include "process/io/exif.h"
#include "process/model/any/rti_fit.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

std::string RelativeTo(const std::string& file, const fs::path& dir) {
  std::error_code ec;
  fs::path rel = fs::relative(fs::absolute(file, ec), fs::absolute(dir, ec), ec);
  return ec || rel.empty() ? file : rel.string();
}

Status RefuseExisting(const fs::path& p, bool force) {
  std::error_code ec;
  if (fs::exists(p, ec) && !force)
    return MakeError(ErrorCode::kInvalidInput, p.string(), "exists (give --force to replace it)");
  return Ok();
}

// The camera: the lens given, orthographic, or the first photograph's EXIF.
Result<CameraModel> CameraFor(const LightCalibrationRequest& rq, const LightSource& src) {
  CameraModel camera;
  const LightStack& stack = src.stack;
  if (rq.focal_mm > 0) {
    camera.focal_px = rq.focal_mm / rq.sensor_width_mm * stack.width;
    camera.source = fmt::format("from --focal-mm {} and --sensor-width-mm {}", rq.focal_mm,
                                rq.sensor_width_mm);
    return camera;
  }
  if (rq.orthographic) {
    camera.source = "--orthographic (no EXIF read)";
    return camera;
  }
  if (rq.from_images) return camera;
  // No lens given: the photographs' EXIF, if they carry a focal length and a sensor width.
  if (src.first_photo.empty()) {
    camera.source = "no --focal-mm, and no photograph to read EXIF from";
    return camera;
  }
  RIG_ASSIGN_OR_RETURN(ExifLens lens, ReadExifLens(src.first_photo));
  const ExifFocal f = FocalFromExif(lens, stack.width, stack.height);
  if (f.focal_mm > 0) {
    camera.focal_px = f.focal_mm / f.sensor_width_mm * stack.width;
    camera.source = fmt::format("from the EXIF of {}: {}", src.first_photo, f.how);
  } else {
    camera.source = fmt::format(
        "no --focal-mm, and {} {}", src.first_photo,
        !lens.has_exif ? "has no EXIF"
        : !f.how.empty() ? f.how
        : lens.focal_mm > 0 ? "has an EXIF FocalLength but neither FocalPlaneXResolution "
                              "nor FocalLengthIn35mmFilm to give the sensor's width"
                            : "has no EXIF focal length");
  }
  return camera;
}

// No sphere: the .lp's directions re-estimated from its images, written, and optionally
// compared by leave-one-out with the given ones.
Status RefineFromImages(const LightCalibrationRequest& rq, const LightSource& src,
                        const std::string& lp_out, std::FILE* out) {
  const LightStack& stack = src.stack;
  if (src.kind != "lp")
    return MakeError(ErrorCode::kInvalidInput, "",
                     "--from-images refines the directions of an .lp (give --lp)");
  PsOptions po;
  po.threads = rq.threads;
  const auto dirs = RefineLightsFromImages(stack, stack.directions, rq.rounds, po);
  double sum = 0, worst = 0;
  for (size_t k = 0; k < dirs.size(); ++k) {
    const double e = AngleDeg(dirs[k], stack.directions[k]);
    sum += e;
    worst = std::max(worst, e);
  }
  std::fprintf(out, "no sphere: directions re-estimated from the images (%d rounds of robust "
               "photometric stereo and per-light least squares)\nchange from the .lp: mean %.3f "
               "deg, max %.3f deg\n", rq.rounds, sum / dirs.size(), worst);
  std::error_code ec;
  const fs::path out_dir = fs::absolute(lp_out, ec).parent_path();
  fs::create_directories(out_dir, ec);
  std::vector<std::string> names;
  for (const auto& n : stack.names) names.push_back(RelativeTo(n, out_dir));
  RIG_TRY(WriteLp(lp_out, names, dirs));
  std::fprintf(out, "wrote %s\n", lp_out.c_str());
  if (rq.loo_report.empty()) return Ok();
  RIG_ASSIGN_OR_RETURN(RtiCapture cap, LoadRtiCapture(rq.lp));
  RIG_ASSIGN_OR_RETURN(auto rows, CompareLightsLoo(cap, stack, rq.loo_every, rq.rounds, {}, rq.threads));
  std::string md = fmt::format(
      "# Leave-one-out: the default model with the .lp's directions and with directions "
      "re-estimated from the images\n\n{}: {} images, {}x{}; every {}th image held out ({} folds); "
      "the re-estimation ({} rounds) redone inside every fold from the fold's images, the held-out "
      "light estimated from its image against the fold's normals.\n\n"
      "| lights | PSNR of mean MSE (dB) | median PSNR (dB) | B/px | mean change from the .lp (deg) |\n"
      "|---|---|---|---|---|\n",
      rq.lp, stack.size(), stack.width, stack.height, rq.loo_every, rows[0].folds, rq.rounds);
  for (const auto& r : rows) {
    md += fmt::format("| {} | {:.2f} | {:.2f} | {:.2f} | {} |\n", r.lights, r.psnr_mean_mse_db,
                      r.psnr_median_db, r.bytes_per_pixel,
                      r.mean_change_deg > 0 ? fmt::format("{:.2f}", r.mean_change_deg) : "0");
    std::fprintf(out, "%-32s PSNR %.2f dB (median %.2f dB), %.2f B/px\n", r.lights.c_str(),
                 r.psnr_mean_mse_db, r.psnr_median_db, r.bytes_per_pixel);
  }
  RIG_TRY(WriteFileAtomic(rq.loo_report, md));
  std::fprintf(out, "wrote %s\n", rq.loo_report.c_str());
  return Ok();
}

// The spheres: found, or the given circles refined to the sphere's edge (or as given).
Result<std::vector<SphereCircle>> LocateSpheres(const LightCalibrationRequest& rq,
                                                const LightStack& stack) {
  if (rq.spheres.empty()) return DetectChromeSpheres(stack, rq.highlight);
  std::vector<SphereCircle> spheres = rq.spheres;
  if (!rq.as_given) {
    const cv::Mat median = MedianGrey(stack);
    for (auto& s : spheres) s = RefineCircle(median, s);
  }
  return spheres;
}

// The lamp's position: asked for with a field height or sphere depths (its errors are the
// user's), or tried when a session's config knows the field and the capture allows.
SphereField FieldFor(const LightCalibrationRequest& rq, size_t spheres, const CameraModel& camera,
                     double session_field_mm, std::FILE* out) {
  SphereField field;
  field.depth_mm = rq.sphere_depth_mm;
  field.fit_depths = rq.fit_depths;
  if (rq.field_height_mm > 0 || !rq.sphere_depth_mm.empty() || rq.fit_depths) {
    field.field_height_mm = rq.field_height_mm > 0 ? rq.field_height_mm : session_field_mm;
  } else if (session_field_mm > 0) {
    if (spheres < 2)
      std::fprintf(out, "lamp position: not estimated (one sphere sees the lamp's direction, not "
                   "its distance; two at different places in the field triangulate it)\n");
    else if (camera.perspective())
      std::fprintf(out, "lamp position: not estimated (the spheres are placed with the "
                   "orthographic model only)\n");
    else
      field.field_height_mm = session_field_mm;
  }
  return field;
}

// The lamp's position per image: the table printed, and lamp.csv's text.
std::string ReportLampFixes(const LampEstimate& lamp, const LightStack& stack, std::FILE* out) {
  std::fprintf(out, "%-12s %8s %8s %8s %11s %8s %8s %9s\n", "image", "x_mm", "y_mm", "z_mm",
               "distance_mm", "sigma_mm", "miss_mm", "parallax");
  std::string csv = "image,determined,x_mm,y_mm,z_mm,distance_mm,sigma_mm,miss_mm,parallax_deg\n";
  for (size_t k = 0; k < stack.size(); ++k) {
    const LampFix& f = lamp.fixes[k];
    const std::string name = fs::path(stack.names[k]).filename().string();
    if (f.determined)
      std::fprintf(out, "%-12s %8.1f %8.1f %8.1f %11.1f %8.1f %8.3f %8.2f\n", name.c_str(),
                   f.position_mm[0], f.position_mm[1], f.position_mm[2], f.distance_mm,
                   f.sigma_mm, f.miss_mm, f.parallax_deg);
    else
      std::fprintf(out, "%-12s no distance: %s\n", name.c_str(), f.note.c_str());
    csv += fmt::format("{},{},{:.3f},{:.3f},{:.3f},{:.3f},{:.3f},{:.4f},{:.4f}\n", name,
                       f.determined ? 1 : 0, f.position_mm[0], f.position_mm[1], f.position_mm[2],
                       f.distance_mm, f.sigma_mm, f.miss_mm, f.parallax_deg);
  }
  return csv;
}

// The surface under the spheres, if they rest on it: printed, and a commented TOML line.
std::string ReportSurface(const LampEstimate& lamp, const std::vector<SphereCircle>& spheres,
                          const SphereField& field, int image_height, std::FILE* out) {
  if (lamp.depth_assumed) {
    std::fprintf(out, "surface: the spheres assumed resting on the plane z = 0 place it there "
                 "(surface_depth_mm unset); give --sphere-depth-mm or --fit-sphere-depths "
                 "for a suggestion\n");
    return "";
  }
  const std::vector<double> under =
      SurfaceUnderSpheres(lamp, spheres, field.field_height_mm, image_height);
  double mean = 0;
  std::string each;
  for (double z : under) {
    mean += z / under.size();
    each += fmt::format("{}{:.1f}", each.empty() ? "" : ", ", z);
  }
  const bool fits = lamp.distance_mm > field.field_height_mm + std::abs(mean);
  std::fprintf(out, "surface: if the spheres rest on the object's surface (facing the camera), "
               "it lies at z = %s mm under them (their centres' z minus their radii): "
               "suggested surface_depth_mm = %.1f, their mean%s; spheres on posts, or "
               "away from the object, say nothing of its depth\n",
               each.c_str(), mean,
               fits ? "" : " (but no farther from the lamp than the field is tall: it "
                           "would be refused)");
  return fmt::format("# surface_depth_mm = {:.1f}  # only if the spheres rest on the "
                     "object's surface: their centres' z minus radii, {} mm\n",
                     mean, each);
}

// A near lamp: its distance, the directions' spread, the surface; the [light_frame] lines.
std::string ReportNearLamp(const SphereCalibration& cal, const std::vector<SphereCircle>& spheres,
                           const SphereField& field, const LightStack& stack, std::FILE* out) {
  const LampEstimate& lamp = *cal.lamp;
  double parallax = 0, residual = 0;
  for (size_t k = 0; k < stack.size(); ++k) {
    parallax = std::max(parallax, cal.sphere_disagreement_deg[k]);
    residual = std::max(residual, lamp.residual_deg[k]);
  }
  std::fprintf(out, "lamp: near, %.1f mm from the arm's centre (median of the %d of %zu images "
               "that give a distance), median ray miss %.3f mm\n", lamp.distance_mm,
               lamp.determined, stack.size(), lamp.median_miss_mm);
  std::fprintf(out, "directions: from the arm's centre to the lamp at that distance (the spheres "
               "see it up to %.2f deg apart; their rays miss it by at most %.2f deg)\n",
               parallax, residual);
  if (lamp.depth_assumed)
    std::fprintf(out, "(the spheres' depths are assumed: where they do not rest on the plane "
                 "through the arm's centre, give --sphere-depth-mm, or --fit-sphere-depths for "
                 "a lamp on the arm; docs/lights.md measures what a wrong depth costs)\n");
  std::string toml = fmt::format("lamp_distance_mm = {:.1f}  # median of {} of {} images, {} "
                                 "spheres, ray miss {:.3f} mm\nfield_height_mm = {:.3f}\n",
                                 lamp.distance_mm, lamp.determined, stack.size(), spheres.size(),
                                 lamp.median_miss_mm, field.field_height_mm);
  return toml + ReportSurface(lamp, spheres, field, stack.height, out);
}

// The lamp's position from the spheres, printed; *lamp_toml and *lamp_csv receive the
// [light_frame] lines and lamp.csv's text.
void ReportLamp(const SphereCalibration& cal, const std::vector<SphereCircle>& spheres,
                const SphereField& field, const LightStack& stack, std::FILE* out,
                std::string* lamp_toml, std::string* lamp_csv) {
  const LampEstimate& lamp = *cal.lamp;
  std::string depths;
  for (double z : lamp.depth_mm) depths += fmt::format("{}{:.1f}", depths.empty() ? "" : ", ", z);
  std::fprintf(out, "\nlamp position from %zu spheres (orthographic, field %.1f mm high, origin at "
               "the arm's centre = the image centre; sphere centres at z = %s mm, %s):\n",
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
    std::fprintf(out, "sphere depths fitted with the lamp's one distance over all images: z = %s "
                 "mm (1-sigma at %.2f px of highlight; from %s mm); the fit's distance %.1f +- "
                 "%.1f mm, rms %.2f of that sigma\n", fitted.c_str(), field.edge_px, start.c_str(),
                 lamp.fit_distance_mm, lamp.fit_distance_sigma_mm, lamp.fit_rms);
  }
  *lamp_csv = ReportLampFixes(lamp, stack, out);
  if (lamp.near) {
    *lamp_toml = ReportNearLamp(cal, spheres, field, stack, out);
  } else {
    std::fprintf(out, "lamp: far (%d of %zu images give a distance; these spheres resolve one up "
                 "to ~%.0f mm): directions as for a far lamp, the spheres' mean\n",
                 lamp.determined, stack.size(), lamp.resolvable_mm);
    *lamp_toml = fmt::format("lamp_distance_mm = 0  # far: beyond the ~{:.0f} mm {} spheres "
                             "resolve\n", lamp.resolvable_mm, spheres.size());
  }
  std::fprintf(out, "suggested: [light_frame] %s", lamp_toml->c_str());
}

// The .lp with image paths relative to its folder; an .lp source is compared with it.
Status WriteCalibratedLp(const LightCalibrationRequest& rq, const LightSource& src,
                         const std::string& lp_out, const std::vector<Vec3>& directions,
                         std::FILE* out) {
  const LightStack& stack = src.stack;
  std::error_code ec;
  const fs::path out_dir = fs::absolute(lp_out, ec).parent_path();
  fs::create_directories(out_dir, ec);
  std::vector<std::string> names;
  for (size_t k = 0; k < stack.size(); ++k) {
    if (src.kind == "session")
      names.push_back(RelativeTo((fs::path(rq.source) / "hdr" / (stack.names[k] + ".exr")).string(), out_dir));
    else if (src.kind == "images")
      names.push_back(RelativeTo((fs::path(rq.images) / stack.names[k]).string(), out_dir));
    else
      names.push_back(RelativeTo(stack.names[k], out_dir));
  }
  RIG_TRY(WriteLp(lp_out, names, directions));
  std::fprintf(out, "wrote %s (%zu lights)\n", lp_out.c_str(), stack.size());
  if (src.kind == "lp") {
    double sum = 0, worst = 0;
    for (size_t k = 0; k < stack.size(); ++k) {
      const double e = AngleDeg(stack.directions[k], directions[k]);
      sum += e;
      worst = std::max(worst, e);
    }
    std::fprintf(out, "against the .lp's directions: mean %.3f deg, max %.3f deg\n",
                 sum / stack.size(), worst);
  }
  return Ok();
}

// A session: the [light_frame] fitted to the arm's angles, its residual per pose, and
// calib/light_frame.toml, lights.csv (and lamp.csv) beside the .lp.
Status WriteSessionFrame(const LightCalibrationRequest& rq, const LightSource& src,
                         const std::string& lp_out, const std::vector<Vec3>& directions,
                         size_t spheres, const std::string& lamp_toml, const std::string& lamp_csv,
                         std::FILE* out) {
  const LightStack& stack = src.stack;
  RIG_ASSIGN_OR_RETURN(LightFrameFit fit, FitLightFrame(stack.h_deg, stack.v_deg, directions));
  const auto& f = fit.frame;
  const auto& was = src.session_config->light_frame;
  std::fprintf(out, "\npose        h_deg  v_deg  residual_deg (sphere -> [light_frame] fitted)\n");
  std::string csv = "pose,h_deg,v_deg,x,y,z,residual_deg\n";
  for (size_t k = 0; k < stack.size(); ++k) {
    std::fprintf(out, "%-10s %6.1f %6.1f  %8.3f\n", stack.names[k].c_str(), stack.h_deg[k],
                 stack.v_deg[k], fit.residual_deg[k]);
    csv += fmt::format("{},{},{},{:.6f},{:.6f},{:.6f},{:.4f}\n", stack.names[k], stack.h_deg[k],
                       stack.v_deg[k], directions[k][0], directions[k][1], directions[k][2],
                       fit.residual_deg[k]);
  }
  std::fprintf(out, "residual: rms %.3f deg, max %.3f deg\n", fit.rms_deg, fit.max_deg);
  std::fprintf(out, "a tilt of the arm about the camera axis, if allowed: %.3f deg (rms %.3f "
               "deg); [light_frame] cannot hold a tilt\n", fit.tilt_deg, fit.rms_with_tilt_deg);
  const std::string toml = fmt::format(
      "# fitted by rig calibrate-lights from {} chrome sphere(s), {} poses; rms {:.3f} deg\n"
      "[light_frame]\nh_offset_deg = {:.4f}\nv_offset_deg = {:.4f}\nh_sign = {}\nv_sign = {}\n{}",
      spheres, stack.size(), fit.rms_deg, f.h_offset_deg, f.v_offset_deg, f.h_sign, f.v_sign,
      lamp_toml);
  std::fprintf(out, "\n%s", toml.c_str());
  std::fprintf(out, "(the session ran with h_offset_deg = %.4f, v_offset_deg = %.4f, h_sign = %d, "
               "v_sign = %d, lamp_distance_mm = %.1f)\n", was.h_offset_deg, was.v_offset_deg,
               was.h_sign, was.v_sign, was.lamp_distance_mm);
  std::error_code ec;
  const fs::path out_dir = fs::absolute(lp_out, ec).parent_path();
  std::vector<std::pair<std::string, std::string>> files = {{"light_frame.toml", toml},
                                                            {"lights.csv", csv}};
  if (!lamp_csv.empty()) files.emplace_back("lamp.csv", lamp_csv);
  for (const auto& [name, text] : files) {
    const fs::path p = out_dir / name;
    RIG_TRY(RefuseExisting(p, rq.force));
    RIG_TRY(WriteFileAtomic(p, text));
    std::fprintf(out, "wrote %s\n", p.string().c_str());
  }
  return Ok();
}

}  // namespace

Status CalibrateLights(const LightCalibrationRequest& rq, const LightSource& src, std::FILE* out) {
  if (src.kind == "model")
    return MakeError(ErrorCode::kInvalidInput, rq.source,
                     "a model has no photographs to find a sphere in; give a session, --lp or "
                     "--images");
  const LightStack& stack = src.stack;
  RIG_ASSIGN_OR_RETURN(CameraModel camera, CameraFor(rq, src));
  const double session_field_mm =
      src.session_config ? src.session_config->light_frame.field_height_mm : 0.0;
  if ((!rq.sphere_depth_mm.empty() || rq.fit_depths) && rq.field_height_mm <= 0 &&
      session_field_mm <= 0)
    return MakeError(ErrorCode::kInvalidInput, "",
                     "--sphere-depth-mm and --fit-sphere-depths place the spheres for the lamp's "
                     "position, which needs --field-height-mm (or a session's [light_frame] "
                     "field_height_mm)");
  std::string lp_out = rq.out;
  if (lp_out.empty()) {
    if (src.kind != "session")
      return MakeError(ErrorCode::kInvalidInput, "",
                       "--out FILE.lp is required for --lp and --images");
    lp_out = (fs::path(rq.source) / "calib" / "lights.lp").string();
  }
  RIG_TRY(RefuseExisting(lp_out, rq.force));
  if (rq.from_images) return RefineFromImages(rq, src, lp_out, out);

  RIG_ASSIGN_OR_RETURN(std::vector<SphereCircle> spheres, LocateSpheres(rq, stack));
  std::fprintf(out, "camera model: %s\n", camera.Describe().c_str());
  for (size_t i = 0; i < spheres.size(); ++i)
    std::fprintf(out, "sphere %zu: centre (%.2f, %.2f) px, radius %.2f px\n", i + 1, spheres[i].cx,
                 spheres[i].cy, spheres[i].r);
  const SphereField field = FieldFor(rq, spheres.size(), camera, session_field_mm, out);
  RIG_ASSIGN_OR_RETURN(SphereCalibration cal,
                       CalibrateFromSpheres(stack, spheres, camera, rq.highlight,
                                            rq.max_disagreement_deg, field));
  std::string lamp_toml, lamp_csv;
  if (cal.lamp) ReportLamp(cal, spheres, field, stack, out, &lamp_toml, &lamp_csv);
  RIG_TRY(WriteCalibratedLp(rq, src, lp_out, cal.directions, out));
  if (src.kind != "session") return Ok();
  return WriteSessionFrame(rq, src, lp_out, cal.directions, spheres.size(), lamp_toml, lamp_csv,
                           out);
}

}  // namespace rig
