#include "process/hdr/focus.h"

#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

double LaplacianVariance(const cv::Mat& laplacian) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(laplacian, mean, stddev);
  return stddev[0] * stddev[0];
}

}  // namespace

Result<FocusStats> AnalyzeFocus(const cv::Mat& image) {
  if (image.empty() || image.cols < 9 || image.rows < 9)
    return MakeError(ErrorCode::kInvalidInput, "focus", "the frame is {}x{}: too small to judge focus",
                     image.cols, image.rows);
  cv::Mat grey;
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 1) {
    grey = image;
  } else {
    return MakeError(ErrorCode::kInvalidInput, "focus", "{} channels: expected 1 or 3", image.channels());
  }
  cv::Mat grey32;
  grey.convertTo(grey32, CV_32F, grey.depth() == CV_16U ? 1.0 / 257.0 : 1.0);
  cv::Mat lap;
  cv::Laplacian(grey32, lap, CV_32F, 1, 1.0, 0.0, cv::BORDER_REFLECT);
  // The outermost pixel ring is reflected, not seen: leave it out of every figure.
  const cv::Mat inner = lap(cv::Rect(1, 1, lap.cols - 2, lap.rows - 2));
  FocusStats out;
  out.whole = LaplacianVariance(inner);
  for (int ty = 0; ty < 3; ++ty) {
    for (int tx = 0; tx < 3; ++tx) {
      const int x0 = inner.cols * tx / 3, x1 = inner.cols * (tx + 1) / 3;
      const int y0 = inner.rows * ty / 3, y1 = inner.rows * (ty + 1) / 3;
      const int i = ty * 3 + tx;
      out.tiles[i] = LaplacianVariance(inner(cv::Rect(x0, y0, x1 - x0, y1 - y0)));
      if (out.tiles[i] > out.tiles[out.sharpest_tile]) out.sharpest_tile = i;
    }
  }
  return out;
}

}  // namespace rig
