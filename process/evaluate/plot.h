// Line and scatter charts drawn with OpenCV into a PNG-ready image: linear or log axes with
// ticks, one colour per series, a legend, and highlighted points (a Pareto front, a choice).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace rig {

struct PlotSeries {
  std::string label;
  std::vector<double> x, y;          // non-finite points (and non-positive on a log axis) are skipped
  std::vector<std::string> point_labels;  // optional, drawn beside each point
  bool line = true;                   // join the points in order
};

struct PlotMarker {
  double x = 0, y = 0;
  enum class Style { kRing, kBigRing, kSquare } style = Style::kRing;
  cv::Scalar color{0, 0, 0};
  std::string label;                  // drawn beside the marker
};

struct PlotOptions {
  std::string title, x_label, y_label;
  bool log_x = false, log_y = false;
  int width = 960, height = 640;
  std::vector<std::string> notes;     // lines printed under the title
};

// The n-th colour of a fixed, distinguishable palette (BGR).
cv::Scalar PlotColor(int n);

// Draws the chart (CV_8UC3, BGR). Axis ranges cover every finite point and marker.
cv::Mat DrawPlot(const std::vector<PlotSeries>& series, const std::vector<PlotMarker>& markers,
                 const PlotOptions& options);

}  // namespace rig
