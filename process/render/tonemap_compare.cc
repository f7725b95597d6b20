#include "process/render/tonemap_compare.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

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

std::vector<ToneMapMethod> ComparedToneMapMethods() {
  return {ToneMapMethod::kWard, ToneMapMethod::kLinear, ToneMapMethod::kReinhard,
          ToneMapMethod::kDrago, ToneMapMethod::kMantiuk};
}

Result<cv::Mat> ToneMapSideBySide(const cv::Mat& radiance, const ToneMapOptions& options,
                                  const std::vector<ToneMapMethod>& methods, int width, bool label,
                                  std::vector<ToneMapPanel>* panels) {
  std::vector<cv::Mat> pictures;
  for (ToneMapMethod m : methods) {
    ToneMapPanel panel;
    panel.options = options;
    panel.options.method = m;
    const auto start = std::chrono::steady_clock::now();
    auto picture = ToneMap(radiance, panel.options, &panel.report);
    panel.ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (!picture.ok()) return picture.error();
    pictures.push_back(Panel(*picture, width, label ? ToneMapMethodName(m) : ""));
    if (panels) panels->push_back(panel);
  }
  if (pictures.size() == 1) return pictures[0];
  cv::Mat result;
  cv::hconcat(pictures, result);
  return result;
}

std::string DescribeToneMapPanel(const ToneMapPanel& panel) {
  const ToneMapOptions& o = panel.options;
  const ToneMapReport& r = panel.report;
  std::string line;
  if (o.method == ToneMapMethod::kWard) {
    const std::string view =
        o.view_extent[0] > 0 ? fmt::format("the file's view ({:.3f} x {:.3f} image plane)",
                                           o.view_extent[0], o.view_extent[1])
                             : fmt::format("fov {:.1f} deg", o.field_of_view_deg);
    line = fmt::format("{}, foveal {}x{}, scene ln range {:.2f} (display {:.2f}), {}, ", view,
                       r.foveal_width, r.foveal_height, r.scene_log_range,
                       std::log(o.display_max_cd_m2 / o.display_min_cd_m2),
                       r.linear_fallback ? "linear mapping"
                                         : fmt::format("{} trimming passes", r.trim_iterations));
  } else if (o.method == ToneMapMethod::kLinear) {
    line = fmt::format("scale {:.4g}, ", r.linear_scale);
  }
  const cv::Vec3f w = LuminanceWeightsBgr(o);
  line += fmt::format("luminance {:.4f} R + {:.4f} G + {:.4f} B, {}gamut {}, ", w[2], w[1], w[0],
                      o.picture_primaries.SameAs(o.display_primaries)
                          ? ""
                          : "converted to the display's primaries, ",
                      GamutMappingName(o.gamut));
  return line + fmt::format("black {:.2f}%, white {:.2f}%", 100 * r.clipped_low_fraction,
                            100 * r.clipped_high_fraction);
}

}  // namespace rig
