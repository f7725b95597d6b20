// rig calibrate-lights SESSION|--lp FILE.lp|--images DIR: light directions from chrome spheres.
#include <cstdio>
#include <string>
#include <vector>

#include "capture/session/light_calibration.h"
#include "capture/session/light_source.h"
#include "rig/commands/command.h"

namespace rig {

int RunCalibrateLights(int argc, char** argv) {
  CLI::App app{"Light directions from the highlights on chrome spheres in every image: an .lp for "
               "any multi-light capture and, for a rig session, the [light_frame] that maps the "
               "arm's angles to them, with its residual per pose (docs/lights.md).",
               "rig calibrate-lights"};
  LightCalibrationRequest rq;
  std::string log_level;
  std::vector<std::string> sphere_args;
  app.add_option("SESSION", rq.source, "a session folder");
  app.add_option("--lp", rq.lp, "an .lp capture (its directions are compared, then replaced)");
  app.add_option("--images", rq.images, "a folder of images (JPEG, PNG, TIFF), one lamp each");
  app.add_option("--sphere", sphere_args, "a chrome sphere's circle CX,CY,R in pixels (repeat for "
                 "several; default: found automatically)");
  app.add_option("--focal-mm", rq.focal_mm, "perspective camera: the lens's focal length (mm); "
                 "default: the first photograph's EXIF (FocalLength with FocalPlaneXResolution "
                 "or FocalLengthIn35mmFilm), else orthographic")->check(CLI::PositiveNumber);
  app.add_option("--sensor-width-mm", rq.sensor_width_mm, "the sensor's width (mm), with --focal-mm")
      ->check(CLI::PositiveNumber);
  app.add_flag("--orthographic", rq.orthographic, "the orthographic model whatever the EXIF says");
  app.add_option("--max-disagreement", rq.max_disagreement_deg,
                 "largest angle (deg) two spheres may disagree on an image's light (a near lamp "
                 "whose position is estimated: a sphere's ray may miss the lamp)")
      ->check(CLI::PositiveNumber);
  app.add_option("--field-height-mm", rq.field_height_mm, "the image's height at the object (mm): "
                 "with two or more spheres, the lamp's position and distance are estimated "
                 "(default: a session's [light_frame] field_height_mm)")
      ->check(CLI::PositiveNumber);
  app.add_option("--sphere-depth-mm", rq.sphere_depth_mm, "a sphere centre's z (mm, towards the "
                 "camera from the plane through the arm's centre), one for all or one per sphere "
                 "in order; default: every sphere resting on that plane (z = its radius)");
  app.add_flag("--fit-sphere-depths", rq.fit_depths, "a near lamp on the arm: fit the spheres' depths "
               "(from --sphere-depth-mm or the default) with the lamp's one distance from the "
               "arm's centre over all images");
  app.add_option("--min-contrast", rq.highlight.min_contrast, "a highlight's peak over the sphere's median")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-blob", rq.highlight.max_blob_fraction, "largest highlight blob, as a fraction of the sphere")
      ->check(CLI::Range(1e-4, 1.0));
  app.add_option("--out", rq.out, "the .lp written (a session: default SESSION/calib/lights.lp)");
  app.add_flag("--force", rq.force, "replace an existing output file");
  app.add_flag("--as-given", rq.as_given, "use the --sphere circles exactly as given (default: refined "
               "to the sphere's edge)");
  app.add_flag("--from-images", rq.from_images, "no sphere: re-estimate the .lp's directions from the "
               "images themselves (alternating robust photometric stereo and per-light least "
               "squares, from the given directions)");
  app.add_option("--rounds", rq.rounds, "alternations of --from-images")->check(CLI::Range(1, 50));
  app.add_option("--loo-report", rq.loo_report, "with --from-images: leave-one-out PSNR of the default "
                 "model with the given against the re-estimated directions (Markdown)");
  app.add_option("--loo-every", rq.loo_every, "hold out every n-th image in --loo-report")
      ->check(CLI::Range(1, 1000));
  app.add_option("--threads", rq.threads, "threads")->check(CLI::Range(1, 64));
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;

  if (rq.focal_mm > 0 || rq.sensor_width_mm > 0) {
    if (rq.focal_mm <= 0 || rq.sensor_width_mm <= 0) {
      std::fprintf(stderr, "rig calibrate-lights: --focal-mm and --sensor-width-mm go together\n");
      return 2;
    }
    if (rq.orthographic) {
      std::fprintf(stderr, "rig calibrate-lights: --orthographic or --focal-mm, not both\n");
      return 2;
    }
  }
  for (const auto& s : sphere_args) {
    SphereCircle c;
    char extra = 0;
    if (std::sscanf(s.c_str(), "%lf,%lf,%lf%c", &c.cx, &c.cy, &c.r, &extra) != 3 || c.r <= 0) {
      std::fprintf(stderr, "rig calibrate-lights: --sphere '%s' is not CX,CY,R (pixels, R > 0)\n",
                   s.c_str());
      return 2;
    }
    rq.spheres.push_back(c);
  }
  auto src = LoadLightSource(rq.source, rq.lp, rq.images, 1);
  if (!src.ok()) return ReportError("calibrate-lights", src.error());
  if (Status st = CalibrateLights(rq, *src, stdout); !st.ok())
    return ReportError("calibrate-lights", st.error());
  return 0;
}

}  // namespace rig
