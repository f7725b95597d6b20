// rig tonemap IN.(exr|hdr) --out OUT.png: tone-maps any HDR file for a screen (Ward's
// histogram adjustment by default; linear and OpenCV's operators for comparison).
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "config/config.h"
#include "process/io/image_io.h"
#include "process/render/radiance_file.h"
#include "process/io/exr_io.h"
#include "process/render/tonemap.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

// Reads a radiance map: OpenEXR through exr_io, Radiance RGBE (.hdr/.pic) through OpenCV.
// One method's picture, resized to `width` (0: as is), with its name written in a corner.
cv::Mat Panel(const cv::Mat& picture, int width, const std::string& label) {
  cv::Mat panel = picture;
  if (width > 0 && width < picture.cols) {
    const int height = static_cast<int>(std::lround(1.0 * picture.rows * width / picture.cols));
    cv::resize(picture, panel, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  } else {
    panel = picture.clone();
  }
  if (!label.empty()) {
    const double scale = std::max(0.4, panel.cols / 500.0);
    int baseline = 0;
    const cv::Size text = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &baseline);
    cv::rectangle(panel, cv::Rect(0, 0, text.width + 8, text.height + baseline + 8),
                  cv::Scalar::all(0), cv::FILLED);
    cv::putText(panel, label, cv::Point(4, text.height + 4), cv::FONT_HERSHEY_SIMPLEX, scale,
                cv::Scalar::all(255), 1, cv::LINE_AA);
  }
  return panel;
}

}  // namespace

int RunTonemap(int argc, char** argv) {
  CLI::App app{"Tone-map an HDR image (OpenEXR or Radiance .hdr) to an 8-bit picture.",
               "rig tonemap"};
  std::string in, out, method_name = "ward", config_path, log_level, ward_variant = "pcond";
  double fov_deg = 0, focal_mm = 0, sensor_mm = 0, display_min = 0, display_max = 0;
  double exposure_scale = 0, gamma = 2.2;
  bool srgb = false, compare = false;
  int width = 0;
  app.add_option("IN", in, "HDR image: .exr (R, G, B channels) or Radiance .hdr/.pic")
      ->required();
  app.add_option("--out", out, "output picture (.png, .jpg, ...)")->required();
  app.add_option("--method", method_name, "ward (default), linear, reinhard, drago or mantiuk");
  app.add_option("--ward-variant", ward_variant,
                 "ward: pcond (default: as Radiance's pcond computes it, 16 random pixels per "
                 "foveal sample) or paper (the 1997 paper's 1-degree samples only)");
  app.add_option("--fov-deg", fov_deg,
                 "field of view in degrees, for Ward's 1-degree samples: of the larger side "
                 "(pcond), of the width (paper) "
                 "(default: from --config, else from lens and sensor, else 40)");
  app.add_option("--focal-length-mm", focal_mm, "lens focal length (with --sensor-width-mm)");
  app.add_option("--sensor-width-mm", sensor_mm, "sensor width (with --focal-length-mm)");
  app.add_option("--config", config_path,
                 "configuration file: process.field_of_view_deg and display range from it");
  app.add_option("--display-min", display_min, "display's darkest luminance, cd/m² (default 1)");
  app.add_option("--display-max", display_max, "display's brightest luminance, cd/m² (default 100)");
  app.add_option("--exposure-scale", exposure_scale,
                 "linear method only: pixel = radiance × this (default: 99th percentile → white)");
  app.add_option("--gamma", gamma, "display gamma (default 2.2)");
  app.add_flag("--srgb", srgb, "encode with the sRGB curve instead of a pure gamma");
  app.add_flag("--compare", compare,
               "write every method side by side, labelled (the --method is ignored)");
  app.add_option("--width", width, "resize each picture to this width in pixels (0: as is)");
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;

  ToneMapOptions options;
  if (!config_path.empty()) {
    auto config = LoadConfigOrError(config_path);
    if (!config.ok()) return ReportError("tonemap", config.error());
    options.field_of_view_deg = config->process.field_of_view_deg;
    options.display_min_cd_m2 = config->process.display_min_cd_m2;
    options.display_max_cd_m2 = config->process.display_max_cd_m2;
  }
  if ((focal_mm > 0) != (sensor_mm > 0)) {
    return ReportError("tonemap", MakeError(ErrorCode::kInvalidInput, "",
                                            "--focal-length-mm and --sensor-width-mm go together"));
  }
  if (focal_mm > 0) options.field_of_view_deg = FieldOfViewDeg(focal_mm, sensor_mm);
  if (fov_deg > 0) options.field_of_view_deg = fov_deg;
  if (display_min > 0) options.display_min_cd_m2 = display_min;
  if (display_max > 0) options.display_max_cd_m2 = display_max;
  options.gamma = gamma;
  options.srgb = srgb;
  auto method = ParseToneMapMethod(method_name);
  if (!method.ok()) return ReportError("tonemap", method.error());
  options.method = *method;
  auto variant = ParseWardVariant(ward_variant);
  if (!variant.ok()) return ReportError("tonemap", variant.error().Within("--ward-variant"));
  options.ward_variant = *variant;
  if (exposure_scale > 0) {
    if (options.method != ToneMapMethod::kLinear || compare) {
      return ReportError("tonemap", MakeError(ErrorCode::kInvalidInput, "",
                                              "--exposure-scale applies to --method linear only"));
    }
    options.linear_scale = exposure_scale;
  }

  auto radiance = ReadRadianceFile(in);
  if (!radiance.ok()) return ReportError("tonemap", radiance.error());

  std::vector<ToneMapMethod> methods = {options.method};
  if (compare) {
    methods = {ToneMapMethod::kWard, ToneMapMethod::kLinear, ToneMapMethod::kReinhard,
               ToneMapMethod::kDrago, ToneMapMethod::kMantiuk};
  }
  std::vector<cv::Mat> panels;
  for (ToneMapMethod m : methods) {
    ToneMapOptions o = options;
    o.method = m;
    ToneMapReport report;
    const auto start = std::chrono::steady_clock::now();
    auto picture = ToneMap(*radiance, o, &report);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (!picture.ok()) return ReportError("tonemap", picture.error().Within(in));
    std::printf("%s: %s %dx%d in %.1f ms: ", in.c_str(), ToneMapMethodName(m), radiance->cols,
                radiance->rows, ms);
    if (m == ToneMapMethod::kWard) {
      std::printf("fov %.1f deg, foveal %dx%d, scene ln range %.2f (display %.2f), %s, ",
                  o.field_of_view_deg, report.foveal_width, report.foveal_height,
                  report.scene_log_range, std::log(o.display_max_cd_m2 / o.display_min_cd_m2),
                  report.linear_fallback
                      ? "linear mapping"
                      : fmt::format("{} trimming passes", report.trim_iterations).c_str());
    } else if (m == ToneMapMethod::kLinear) {
      std::printf("scale %.4g, ", report.linear_scale);
    }
    std::printf("black %.2f%%, white %.2f%%\n", 100 * report.clipped_low_fraction,
                100 * report.clipped_high_fraction);
    panels.push_back(Panel(*picture, width, compare ? ToneMapMethodName(m) : ""));
  }
  cv::Mat result;
  if (panels.size() == 1) {
    result = panels[0];
  } else {
    cv::hconcat(panels, result);
  }
  if (Status st = WriteImageFile(out, result, {cv::IMWRITE_PNG_COMPRESSION, 9}); !st.ok())
    return ReportError("tonemap", st.error());
  return 0;
}

}  // namespace rig
