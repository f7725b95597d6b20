// Metering one frame for an adaptive bracket (see metering.h).
#include "capture/daemon/metering.h"

#include <array>
#include <cmath>

namespace rig {
namespace {

// The nominal curve: level (0..1) to relative exposure.
double Nominal(double level, bool linear) { return linear ? level : std::pow(level, 2.2); }

}  // namespace

AdaptiveBracketOptions MeteringWindow(int depth, bool linear) {
  AdaptiveBracketOptions o;
  if (depth == CV_16U) {
    // LibRaw's linear values: eight stops below clipping, where the simulated sensor's
    // shot noise is about 10% per frame, up to 90% of the white level.
    o.x_lo = std::exp2(-8.0);
    o.x_hi = 0.9;
  } else {
    // The levels the planner's evaluation uses (docs/adaptive-brackets.md): 24 and 235.
    o.x_lo = Nominal(24.0 / 255.0, linear);
    o.x_hi = Nominal(235.0 / 255.0, linear);
  }
  return o;
}

Result<std::vector<float>> MeterFrame(const cv::Mat& image, double exposure_s, bool linear,
                                      const std::string& name) {
  if (image.empty() || image.channels() != 3 ||
      (image.depth() != CV_8U && image.depth() != CV_16U))
    return MakeError(ErrorCode::kInvalidInput, name,
                     "a metering frame must be 8- or 16-bit with three channels");
  if (!(exposure_s > 0))
    return MakeError(ErrorCode::kInvalidInput, name, "metering exposure {} s is not positive",
                     exposure_s);
  const bool deep = image.depth() == CV_16U;
  const bool lin = deep || linear;
  // A table per level: 256 or 65536 entries.
  const int levels = deep ? 65536 : 256;
  const int clip = deep ? 65535 : 250;
  std::vector<float> table(static_cast<size_t>(levels));
  for (int z = 0; z < levels; ++z) {
    const double x = Nominal(double(z) / double(levels - 1), lin) / exposure_s;
    table[static_cast<size_t>(z)] = z == 0 ? 0.f : float(z >= clip ? 4 * x : x);
  }
  std::vector<float> out;
  out.reserve(image.total() * 3);
  for (int y = 0; y < image.rows; ++y) {
    const int n = image.cols * 3;
    if (deep) {
      const uint16_t* p = image.ptr<uint16_t>(y);
      for (int k = 0; k < n; ++k) out.push_back(table[p[k]]);
    } else {
      const uint8_t* p = image.ptr<uint8_t>(y);
      for (int k = 0; k < n; ++k) out.push_back(table[p[k]]);
    }
  }
  return out;
}

}  // namespace rig
