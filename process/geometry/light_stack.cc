// Loading a multi-light capture as linear images.
#include "process/geometry/light_stack.h"

#include "process/io/exr_io.h"
#include "process/model/harmonic/loo.h"

namespace rig {

Result<LightStack> LoadLpStack(const std::string& lp, int downsample) {
  RIG_ASSIGN_OR_RETURN(std::vector<LpEntry> entries, ReadLp(lp));
  if (entries.empty()) return MakeError(ErrorCode::kInvalidInput, lp, "the .lp lists no image");
  RIG_ASSIGN_OR_RETURN(RtiImages images, LoadRtiImages(entries, false, std::max(1, downsample)));
  LightStack s;
  s.width = images.radiance[0].cols;
  s.height = images.radiance[0].rows;
  for (size_t k = 0; k < entries.size(); ++k) {
    s.names.push_back(entries[k].image);
    s.linear.push_back(images.radiance[k]);
    cv::Mat clip(s.height, s.width, CV_8UC1);
    const cv::Mat& e = images.encoded[k];
    for (int y = 0; y < s.height; ++y) {
      const uint8_t* src = e.ptr<uint8_t>(y);
      uint8_t* dst = clip.ptr<uint8_t>(y);
      for (int x = 0; x < s.width; ++x)
        dst[x] = (src[3 * x] >= 250 || src[3 * x + 1] >= 250 || src[3 * x + 2] >= 250) ? 1 : 0;
    }
    s.clipped.push_back(clip);
    s.directions.push_back(entries[k].direction);
  }
  return s;
}

Result<LightStack> LoadRadianceStack(const std::vector<std::string>& exr_paths,
                                     const std::vector<std::string>& names,
                                     const std::vector<double>& h_deg,
                                     const std::vector<double>& v_deg,
                                     const LightFrameConfig& frame) {
  LightStack s;
  for (size_t k = 0; k < exr_paths.size(); ++k) {
    RIG_ASSIGN_OR_RETURN(cv::Mat m, ReadRgbExr(exr_paths[k]));
    if (k == 0) {
      s.width = m.cols;
      s.height = m.rows;
    } else if (m.cols != s.width || m.rows != s.height) {
      return MakeError(ErrorCode::kInvalidInput, exr_paths[k], "is {}x{}, the first map {}x{}",
                       m.cols, m.rows, s.width, s.height);
    }
    s.names.push_back(names[k]);
    s.linear.push_back(m);
    s.h_deg.push_back(h_deg[k]);
    s.v_deg.push_back(v_deg[k]);
    s.directions.push_back(LightDirection(h_deg[k], v_deg[k], frame));
  }
  if (s.linear.empty())
    return MakeError(ErrorCode::kInvalidInput, "(radiance maps)", "no radiance map given");
  return s;
}

cv::Mat LinearGrey(const cv::Mat& bgr) {
  cv::Mat grey(bgr.rows, bgr.cols, CV_32FC1);
  for (int y = 0; y < bgr.rows; ++y) {
    const float* s = bgr.ptr<float>(y);
    float* d = grey.ptr<float>(y);
    for (int x = 0; x < bgr.cols; ++x)
      d[x] = 0.0722f * s[3 * x] + 0.7152f * s[3 * x + 1] + 0.2126f * s[3 * x + 2];
  }
  return grey;
}

}  // namespace rig
