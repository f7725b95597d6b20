// Line and scatter charts drawn with OpenCV.
#include "process/evaluate/plot.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Axis {
  bool log = false;
  double lo = kInf, hi = -kInf;  // in axis units (log10 when log)
  bool Usable(double v) const { return std::isfinite(v) && (!log || v > 0); }
  double Map(double v) const { return log ? std::log10(v) : v; }
  void Include(double v) {
    if (!Usable(v)) return;
    lo = std::min(lo, Map(v));
    hi = std::max(hi, Map(v));
  }
  void Finish() {
    if (!(lo <= hi)) lo = 0, hi = 1;
    if (hi - lo < 1e-12) {
      const double pad = log ? 0.5 : std::max(1e-9, std::abs(lo) * 0.1 + 1e-9);
      lo -= pad, hi += pad;
    }
    const double pad = 0.05 * (hi - lo);
    lo -= pad, hi += pad;
  }
  // Tick positions (axis units) and labels.
  std::vector<std::pair<double, std::string>> Ticks() const {
    std::vector<std::pair<double, std::string>> t;
    if (log) {
      const int a = static_cast<int>(std::floor(lo)), b = static_cast<int>(std::ceil(hi));
      const int step = std::max(1, (b - a) / 8);
      for (int e = a; e <= b; e += step)
        if (e >= lo && e <= hi) t.push_back({double(e), fmt::format("{:g}", std::pow(10.0, e))});
      if (t.size() < 3) {  // about a decade or less: 1-2-5 ticks
        for (int e = a - 1; e <= b; ++e)
          for (double m : {2.0, 5.0}) {
            const double v = e + std::log10(m);
            if (v >= lo && v <= hi) t.push_back({v, fmt::format("{:g}", std::pow(10.0, v))});
          }
      }
      return t;
    }
    const double raw = (hi - lo) / 6;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    double step = mag;
    for (double m : {1.0, 2.0, 5.0, 10.0})
      if (raw <= m * mag) {
        step = m * mag;
        break;
      }
    for (double v = std::ceil(lo / step) * step; v <= hi; v += step)
      t.push_back({v, fmt::format("{:g}", std::abs(v) < step * 1e-6 ? 0.0 : v)});
    return t;
  }
};

void Text(cv::Mat& img, const std::string& s, cv::Point at, double scale, cv::Scalar color,
          int thickness = 1) {
  cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, color, thickness, cv::LINE_AA);
}

int TextWidth(const std::string& s, double scale) {
  int base = 0;
  return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &base).width;
}

}  // namespace

cv::Scalar PlotColor(int n) {
  static const cv::Scalar kPalette[] = {
      {180, 119, 31}, {14, 127, 255}, {44, 160, 44},  {40, 39, 214},  {189, 103, 148},
      {75, 86, 140},  {194, 119, 227}, {127, 127, 127}, {34, 189, 188}, {207, 190, 23},
      // Then the same hues darker, so that up to 20 series are told apart.
      {112, 62, 10},  {0, 78, 170},   {20, 100, 20},  {20, 20, 140},  {120, 50, 90},
      {40, 50, 90},   {130, 60, 160}, {60, 60, 60},   {10, 120, 120}, {130, 110, 0}};
  constexpr int kColours = static_cast<int>(sizeof(kPalette) / sizeof(kPalette[0]));
  return kPalette[((n % kColours) + kColours) % kColours];
}

cv::Mat DrawPlot(const std::vector<PlotSeries>& series, const std::vector<PlotMarker>& markers,
                 const PlotOptions& o) {
  cv::Mat img(o.height, o.width, CV_8UC3, cv::Scalar::all(255));
  Axis ax{o.log_x}, ay{o.log_y};
  for (const auto& s : series)
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i)
      if (ax.Usable(s.x[i]) && ay.Usable(s.y[i])) ax.Include(s.x[i]), ay.Include(s.y[i]);
  for (const auto& m : markers)
    if (ax.Usable(m.x) && ay.Usable(m.y)) ax.Include(m.x), ay.Include(m.y);
  ax.Finish();
  ay.Finish();

  const int notes = static_cast<int>(o.notes.size());
  const int left = 90, right = 230, top = 50 + 18 * notes, bottom = 60;
  const int pw = o.width - left - right, ph = o.height - top - bottom;
  auto px = [&](double v) { return left + static_cast<int>(std::lround((ax.Map(v) - ax.lo) / (ax.hi - ax.lo) * pw)); };
  auto py = [&](double v) { return top + ph - static_cast<int>(std::lround((ay.Map(v) - ay.lo) / (ay.hi - ay.lo) * ph)); };
  const cv::Scalar black(0, 0, 0), grid(225, 225, 225);

  for (const auto& [v, label] : ax.Ticks()) {
    const int x = left + static_cast<int>(std::lround((v - ax.lo) / (ax.hi - ax.lo) * pw));
    cv::line(img, {x, top}, {x, top + ph}, grid, 1);
    Text(img, label, {x - TextWidth(label, 0.45) / 2, top + ph + 18}, 0.45, black);
  }
  for (const auto& [v, label] : ay.Ticks()) {
    const int y = top + ph - static_cast<int>(std::lround((v - ay.lo) / (ay.hi - ay.lo) * ph));
    cv::line(img, {left, y}, {left + pw, y}, grid, 1);
    Text(img, label, {left - 8 - TextWidth(label, 0.45), y + 5}, 0.45, black);
  }
  cv::rectangle(img, {left, top}, {left + pw, top + ph}, black, 1);
  Text(img, o.title, {left, 28}, 0.65, black, 2);
  for (int i = 0; i < notes; ++i) Text(img, o.notes[i], {left, 48 + 18 * i}, 0.45, {60, 60, 60});
  Text(img, o.x_label + (o.log_x ? " (log)" : ""),
       {left + pw / 2 - TextWidth(o.x_label, 0.5) / 2, o.height - 18}, 0.5, black);
  {
    // Vertical y label: draw horizontally into a strip, rotate.
    const std::string yl = o.y_label + (o.log_y ? " (log)" : "");
    cv::Mat strip(24, std::max(10, TextWidth(yl, 0.5) + 8), CV_8UC3, cv::Scalar::all(255));
    Text(strip, yl, {4, 17}, 0.5, black);
    cv::Mat rotated;
    cv::rotate(strip, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int y0 = std::max(0, top + ph / 2 - rotated.rows / 2);
    const int h = std::min(rotated.rows, o.height - y0);
    rotated(cv::Rect(0, 0, rotated.cols, h)).copyTo(img(cv::Rect(6, y0, rotated.cols, h)));
  }

  cv::Mat plot_area = img(cv::Rect(left, top, pw + 1, ph + 1));
  const cv::Point offset(left, top);
  for (size_t si = 0; si < series.size(); ++si) {
    const auto& s = series[si];
    const cv::Scalar c = PlotColor(static_cast<int>(si));
    cv::Point prev;
    bool have_prev = false;
    for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!ax.Usable(s.x[i]) || !ay.Usable(s.y[i])) {
        have_prev = false;
        continue;
      }
      const cv::Point p(px(s.x[i]), py(s.y[i]));
      if (s.line && have_prev) cv::line(plot_area, prev - offset, p - offset, c, 2, cv::LINE_AA);
      cv::circle(plot_area, p - offset, 4, c, cv::FILLED, cv::LINE_AA);
      if (i < s.point_labels.size() && !s.point_labels[i].empty())
        Text(img, s.point_labels[i], p + cv::Point(5, -5), 0.38, c);
      prev = p;
      have_prev = true;
    }
    // Legend.
    const int ly = top + 10 + 22 * static_cast<int>(si);
    cv::line(img, {left + pw + 15, ly}, {left + pw + 40, ly}, c, 2, cv::LINE_AA);
    cv::circle(img, {left + pw + 27, ly}, 4, c, cv::FILLED, cv::LINE_AA);
    Text(img, s.label, {left + pw + 46, ly + 5}, 0.45, black);
  }
  int legend_y = top + 10 + 22 * static_cast<int>(series.size()) + 10;
  std::vector<std::string> seen;
  for (const auto& m : markers) {
    if (!ax.Usable(m.x) || !ay.Usable(m.y)) continue;
    const cv::Point p(px(m.x), py(m.y));
    auto draw = [&](cv::Mat& target, cv::Point at) {
      switch (m.style) {
        case PlotMarker::Style::kRing: cv::circle(target, at, 8, m.color, 2, cv::LINE_AA); break;
        case PlotMarker::Style::kBigRing: cv::circle(target, at, 14, m.color, 3, cv::LINE_AA); break;
        case PlotMarker::Style::kSquare:
          cv::rectangle(target, at - cv::Point(7, 7), at + cv::Point(7, 7), m.color, 2, cv::LINE_AA);
          break;
      }
    };
    draw(plot_area, p - offset);
    if (!m.label.empty() && std::find(seen.begin(), seen.end(), m.label) == seen.end()) {
      seen.push_back(m.label);
      draw(img, {left + pw + 27, legend_y});
      Text(img, m.label, {left + pw + 46, legend_y + 5}, 0.45, black);
      legend_y += 30;
    }
  }
  return img;
}

}  // namespace rig
