// The adaptive grid's options and working images.
#include "capture/daemon/adaptive_grid.h"

#include <algorithm>
#include <numeric>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "process/io/image_io.h"

#include "process/model/light_direction.h"

namespace rig {

int AdaptiveMaxPoses(const GridConfig& grid, int allowed) {
  const int m = grid.max_poses > 0 ? grid.max_poses : (allowed + 1) / 2;
  return std::clamp(m, 1, std::max(1, allowed));
}

double AdaptivePoseCost(const Config& config, const std::vector<double>& exposures_s) {
  if (config.grid.pose_cost_s >= 0) return config.grid.pose_cost_s;
  return config.motor.settle_time_s + config.lamp.warmup_s +
         std::accumulate(exposures_s.begin(), exposures_s.end(), 0.0) +
         kTransferSecondsPerFrame * static_cast<double>(exposures_s.size());
}

std::vector<Vec3> AdaptiveGridDirections(const Config& config, const std::vector<Pose>& allowed) {
  std::vector<Vec3> dirs;
  for (const Pose& p : allowed) dirs.push_back(LightDirection(p.h_deg, p.v_deg, config.light_frame));
  return dirs;
}

LightChoiceOptions AdaptiveGridOptions(const Config& config, const std::vector<Pose>& allowed,
                                       double pose_cost_s) {
  LightChoiceOptions o;
  o.count = AdaptiveMaxPoses(config.grid, static_cast<int>(allowed.size()));
  o.seed = config.grid.seed_poses;
  o.target = config.grid.target;
  for (const Pose& p : allowed) o.names.push_back(p.Name());
  // The region a model of the session is relit in: the grid's span at a quarter of its steps
  // (between the poses, where a relit lamp falls and no pose is).
  const GridConfig& g = config.grid;
  const double dh = g.h_step_deg / 4, dv = g.v_step_deg / 4;
  for (double v = g.v_min_deg; v <= g.v_max_deg + 1e-9; v += dv)
    for (double h = g.h_min_deg; h <= g.h_max_deg + 1e-9; h += dh)
      o.region.push_back(LightDirection(h, v, config.light_frame));
  const MotorConfig motor = config.motor;
  o.cost_s = [motor, allowed, pose_cost_s](int last, int candidate) {
    return pose_cost_s + MoveSeconds(motor, allowed[static_cast<size_t>(last)],
                                     allowed[static_cast<size_t>(candidate)]);
  };
  return o;
}

int WorkingFactorFor(const cv::Mat& frame, int max_pixels) {
  int f = 1;
  while (static_cast<int64_t>(frame.cols / f) * (frame.rows / f) > max_pixels) ++f;
  return f;
}

Result<cv::Mat> WorkingImage(const cv::Mat& frame, int factor, const std::string& name) {
  cv::Mat img;
  if (frame.type() == CV_8UC3) {
    img = frame;
  } else if (frame.type() == CV_16UC3) {
    frame.convertTo(img, CV_8UC3, 1.0 / 257.0);
  } else {
    return MakeError(ErrorCode::kInvalidInput, name,
                     "the adaptive grid reads 8- or 16-bit colour frames");
  }
  if (factor > 1) {
    cv::Mat small;
    cv::resize(img, small, cv::Size(img.cols / factor, img.rows / factor), 0, 0, cv::INTER_AREA);
    img = small;
  }
  return img.isContinuous() ? img : img.clone();
}

Result<cv::Mat> DecodeForChoice(const std::vector<uint8_t>& bytes, const std::string& name,
                                int max_pixels) {
  const bool jpeg = bytes.size() > 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF;
  if (jpeg) {
    // The size from a full decode's header would need a parse; the scaled decode is cheap
    // enough to try from the smallest up.
    for (int flag : {cv::IMREAD_REDUCED_COLOR_8, cv::IMREAD_REDUCED_COLOR_4,
                     cv::IMREAD_REDUCED_COLOR_2}) {
      cv::Mat img;
      try {
        img = cv::imdecode(bytes, flag | cv::IMREAD_IGNORE_ORIENTATION);
      } catch (const cv::Exception&) {
        img.release();
      }
      if (img.empty()) break;  // undecodable: the full decoder names why
      if (static_cast<int64_t>(img.cols) * img.rows >= max_pixels) return img;
    }
  }
  return DecodeImageBytes(bytes, name);
}

Result<cv::Mat> MeanOfFrames(const std::vector<cv::Mat>& frames, const std::string& name) {
  if (frames.empty()) return MakeError(ErrorCode::kInternal, name, "no frame to read");
  cv::Mat sum = cv::Mat::zeros(frames[0].size(), CV_32FC3);
  for (const cv::Mat& f : frames) {
    if (f.size() != frames[0].size() || f.type() != CV_8UC3)
      return MakeError(ErrorCode::kInvalidInput, name, "the bracket's frames differ in size");
    cv::accumulate(f, sum);
  }
  cv::Mat mean;
  sum.convertTo(mean, CV_8UC3, 1.0 / static_cast<double>(frames.size()));
  return mean;
}

}  // namespace rig
