// The adaptive grid (grid.mode = "adaptive"): the grid is the set of poses allowed, and the
// session takes them one at a time as the next-best-light choice (process/model/light_choice.h)
// proposes, from the frames taken so far. docs/lights.md "The adaptive grid".
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "capture/plan/pose.h"
#include "config/config.h"
#include "config/result.h"
#include "process/model/light_choice.h"

namespace rig {

// At most this many poses: grid.max_poses, or half the allowed poses rounded up (0), never
// more than there are.
int AdaptiveMaxPoses(const GridConfig& grid, int allowed);

// The seconds a pose costs beside its motion: grid.pose_cost_s when set (>= 0), else the
// estimate settle + lamp warm-up + the bracket's exposures + kTransferSecondsPerFrame per
// frame (a camera's download and write of one frame).
inline constexpr double kTransferSecondsPerFrame = 1.0;
double AdaptivePoseCost(const Config& config, const std::vector<double>& exposures_s);

// The choice's options for the session: count = AdaptiveMaxPoses, the seed, the target, the
// region (the grid's span at a quarter of its steps), and the cost of taking a pose = its
// pose cost + the move from the pose taken last.
LightChoiceOptions AdaptiveGridOptions(const Config& config, const std::vector<Pose>& allowed,
                                       double pose_cost_s);

// The lamp direction of every allowed pose (the light frame applied).
std::vector<Vec3> AdaptiveGridDirections(const Config& config, const std::vector<Pose>& allowed);

// Decodes a frame for the choice: a JPEG at 1/2, 1/4 or 1/8 of its size straight from its
// DCT (libjpeg's scaled decoding: a 24 MP frame in tens of milliseconds) while that leaves at
// least `max_pixels`, any other file through DecodeImageBytes; no EXIF orientation.
Result<cv::Mat> DecodeForChoice(const std::vector<uint8_t>& bytes, const std::string& name,
                                int max_pixels);

// The working image of a pose from its bracket's frames (the same exposures at every pose):
// the mean of their 8-bit codes, a tone curve with the bracket's whole range and no response
// needed — highlights resolved by the short frames, shadows by the long ones.
Result<cv::Mat> MeanOfFrames(const std::vector<cv::Mat>& working_frames, const std::string& name);

// A frame as the choice reads it: 8-bit colour (16-bit frames divided by 257), shrunk by
// area averaging by `factor` (WorkingFactorFor: the smallest integer that brings the frame to at
// most `max_pixels`).
int WorkingFactorFor(const cv::Mat& frame, int max_pixels);
Result<cv::Mat> WorkingImage(const cv::Mat& frame, int factor, const std::string& name);

}  // namespace rig
