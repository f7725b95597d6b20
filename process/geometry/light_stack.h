// A multi-light capture as linear images: what light calibration and photometric stereo read,
// from an .lp capture (8-bit, sRGB-decoded, clipped samples marked) or from radiance maps.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/model/light_direction.h"

namespace rig {

struct LightStack {
  int width = 0, height = 0;
  std::vector<std::string> names;  // image file or pose name: every message names it
  std::vector<cv::Mat> linear;     // CV_32FC3 B, G, R, linear in radiance (any common scale)
  // CV_8UC1 per image, 1 where a channel was clipped (8-bit code >= 250); empty for radiance
  // maps (their clipping is already resolved by the bracket).
  std::vector<cv::Mat> clipped;
  std::vector<Vec3> directions;    // the nominal directions (the .lp's, or the arm's)
  std::vector<double> h_deg, v_deg;  // commanded arm angles (sessions), else empty
  size_t size() const { return linear.size(); }
};

// An .lp capture: ReadLp and LoadRtiImages (sRGB decoded), `downsample` >= 1.
Result<LightStack> LoadLpStack(const std::string& lp, int downsample = 1);

// Radiance maps (EXR, R, G, B) with their commanded angles and the frame that maps them to
// directions. `names` name them in messages (pose names).
Result<LightStack> LoadRadianceStack(const std::vector<std::string>& exr_paths,
                                     const std::vector<std::string>& names,
                                     const std::vector<double>& h_deg,
                                     const std::vector<double>& v_deg,
                                     const LightFrameConfig& frame);

// Grey (linear luminance, Rec. 709 weights) of a CV_32FC3 BGR image: CV_32FC1.
cv::Mat LinearGrey(const cv::Mat& bgr);

}  // namespace rig
