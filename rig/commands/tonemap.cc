// rig tonemap IN.(exr|hdr) --out OUT.png: tone-maps any HDR file for a screen (Ward's
// histogram adjustment by default; linear and OpenCV's operators for comparison).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "config/config.h"
#include "process/io/image_io.h"
#include "process/render/radiance_file.h"
#include "process/io/exr_io.h"
#include "process/render/tonemap.h"
#include "process/render/tonemap_compare.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

struct TonemapArgs {
  std::string in, out, method_name = "ward", config_path, log_level, ward_variant = "pcond",
      gamut = "desaturate";
  double fov_deg = 0, focal_mm = 0, sensor_mm = 0, display_min = 0, display_max = 0;
  double exposure_scale = 0, gamma = 2.2;
  bool srgb = false, compare = false;
  int width = 0;
};

// The tone mapping the arguments ask for: a configuration's field of view and display, the
// picture's header (its primaries; its view over the configuration's field of view), then the
// lens and --fov-deg (over the header's view), then the options themselves.
Result<ToneMapOptions> OptionsFromArgs(const TonemapArgs& a, const PictureHeader& header) {
  ToneMapOptions options;
  if (!a.config_path.empty()) {
    RIG_ASSIGN_OR_RETURN(Config config, LoadConfigOrError(a.config_path));
    options.field_of_view_deg = config.process.field_of_view_deg;
    options.display_min_cd_m2 = config.process.display_min_cd_m2;
    options.display_max_cd_m2 = config.process.display_max_cd_m2;
  }
  if ((a.focal_mm > 0) != (a.sensor_mm > 0)) {
    return MakeError(ErrorCode::kInvalidInput, "", "--focal-length-mm and --sensor-width-mm go together");
  }
  if (Status st = ApplyPictureHeader(header, &options); !st.ok()) return st.error().Within(a.in);
  if (a.focal_mm > 0) options.field_of_view_deg = FieldOfViewDeg(a.focal_mm, a.sensor_mm);
  if (a.fov_deg > 0) options.field_of_view_deg = a.fov_deg;
  if (a.focal_mm > 0 || a.fov_deg > 0) options.view_extent = {0, 0};
  auto gamut = ParseGamutMapping(a.gamut);
  if (!gamut.ok()) return gamut.error().Within("--gamut");
  options.gamut = *gamut;
  if (a.display_min > 0) options.display_min_cd_m2 = a.display_min;
  if (a.display_max > 0) options.display_max_cd_m2 = a.display_max;
  options.gamma = a.gamma;
  options.srgb = a.srgb;
  RIG_ASSIGN_OR_RETURN(options.method, ParseToneMapMethod(a.method_name));
  auto variant = ParseWardVariant(a.ward_variant);
  if (!variant.ok()) return variant.error().Within("--ward-variant");
  options.ward_variant = *variant;
  if (a.exposure_scale > 0) {
    if (options.method != ToneMapMethod::kLinear || a.compare) {
      return MakeError(ErrorCode::kInvalidInput, "", "--exposure-scale applies to --method linear only");
    }
    options.linear_scale = a.exposure_scale;
  }
  return options;
}

}  // namespace

int RunTonemap(int argc, char** argv) {
  CLI::App app{"Tone-map an HDR image (OpenEXR or Radiance .hdr) to an 8-bit picture.",
               "rig tonemap"};
  TonemapArgs a;
  app.add_option("IN", a.in, "HDR image: .exr (R, G, B channels) or Radiance .hdr/.pic")
      ->required();
  app.add_option("--out", a.out, "output picture (.png, .jpg, ...)")->required();
  app.add_option("--method", a.method_name, "ward (default), linear, reinhard, drago or mantiuk");
  app.add_option("--ward-variant", a.ward_variant,
                 "ward: pcond (default: as Radiance's pcond computes it, with single pixels "
                 "added to the foveal samples) or paper (the 1997 paper's 1-degree samples only)");
  app.add_option("--fov-deg", a.fov_deg,
                 "field of view in degrees, for Ward's 1-degree samples: of the larger side "
                 "(pcond), of the width (paper) "
                 "(default: from lens and sensor, else the file's VIEW= line, else from --config, "
                 "else 40)");
  app.add_option("--focal-length-mm", a.focal_mm, "lens focal length (with --sensor-width-mm)");
  app.add_option("--sensor-width-mm", a.sensor_mm, "sensor width (with --focal-length-mm)");
  app.add_option("--config", a.config_path,
                 "configuration file: process.field_of_view_deg and display range from it");
  app.add_option("--display-min", a.display_min, "display's darkest luminance, cd/m² (default 1)");
  app.add_option("--display-max", a.display_max, "display's brightest luminance, cd/m² (default 100)");
  app.add_option("--exposure-scale", a.exposure_scale,
                 "linear method only: pixel = radiance × this (default: 99th percentile → white)");
  app.add_option("--gamma", a.gamma, "display gamma (default 2.2)");
  app.add_flag("--srgb", a.srgb, "encode with the sRGB curve instead of a pure gamma");
  app.add_option("--gamut", a.gamut,
                 "colours the display (sRGB primaries) cannot show once converted from the "
                 "file's primaries: desaturate (default, as Radiance's pcond: towards the grey of "
                 "the same luminance) or clip (each channel)");
  app.add_flag("--compare", a.compare,
               "write every method side by side, labelled (the --method is ignored)");
  app.add_option("--width", a.width, "resize each picture to this width in pixels (0: as is)");
  AddLogLevelOption(app, &a.log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(a.log_level)) return *rc;

  auto picture = ReadRadiancePicture(a.in);
  if (!picture.ok()) return ReportError("tonemap", picture.error());
  auto options = OptionsFromArgs(a, picture->header);
  if (!options.ok()) return ReportError("tonemap", options.error());
  const cv::Mat* radiance = &picture->radiance;
  const std::vector<ToneMapMethod> methods =
      a.compare ? ComparedToneMapMethods() : std::vector<ToneMapMethod>{options->method};
  std::vector<ToneMapPanel> panels;
  auto result = ToneMapSideBySide(*radiance, *options, methods, a.width, a.compare, &panels);
  if (!result.ok()) return ReportError("tonemap", result.error().Within(a.in));
  for (const ToneMapPanel& p : panels) {
    std::printf("%s: %s %dx%d in %.1f ms: %s\n", a.in.c_str(), ToneMapMethodName(p.options.method),
                radiance->cols, radiance->rows, p.ms, DescribeToneMapPanel(p).c_str());
  }
  if (Status st = WriteImageFile(a.out, *result, {cv::IMWRITE_PNG_COMPRESSION, 9}); !st.ok())
    return ReportError("tonemap", st.error());
  return 0;
}

}  // namespace rig
