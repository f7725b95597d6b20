// The PCA model of a session's radiance maps fitted band by band from wherever the maps are
// (held in memory as they arrived, or their files): the same model, byte for byte, as
// FitPcaHdrAuto on the whole maps when the choice region is the whole image, without ever
// holding every map in floats or every pixel's codes at once.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/model/pca/pca_hdr.h"
#include "process/model/pca/pca_stream.h"
#include "process/model/session/model_stream.h"

namespace rig {

struct PcaSessionFit {
  PcaHdrFit choice;      // the candidates and the chosen one (choice.model is left empty)
  HdrCodeCurve curve;    // the model's, from every map
  cv::Rect choice_region;  // where the candidates were fitted and scored
  int width = 0, height = 0, components = 0;
  PcaStreamFit planes;   // sample counts of the plane pass
  double choice_s = 0, gather_s = 0, write_s = 0, time_s = 0;
};

// The candidates are fitted and scored on the maps' central region of at most
// kPcaHdrChoiceSide × kPcaHdrChoiceSide pixels (the whole image when it is no larger), so that
// the choice costs the same at any size; the model is then fitted to every pixel.
inline constexpr int kPcaHdrChoiceSide = 512;
cv::Rect PcaHdrChoiceRegion(int width, int height);

// The choice region of every map (CV_32FC3 BGR), read from `maps`.
Result<std::vector<cv::Mat>> ReadChoiceRegion(MapBands& maps);

// `maps`: the session's radiance maps (CV_32FC3 BGR), one per direction; ρ = radiance ÷ lamp.
// `choice`: the choice already made on the choice region (ChoosePcaHdr with `options`), or
// null to make it here. Three passes over bands of `band_rows` rows: the choice region; the curve's sample and the
// components' sampled pixels; every pixel's codes, solved and written into the plane files of
// `out_folder` (created; files replaced), then info.json with the HDR values.
Result<PcaSessionFit> FitPcaHdrFromBands(MapBands& maps, const std::vector<Vec3>& directions,
                                         const std::array<double, 3>& lamp_radiance_rgb,
                                         const LightFrameConfig& light_frame,
                                         const PcaHdrChoiceOptions& options,
                                         const std::string& out_folder, int band_rows = 32,
                                         const PcaHdrFit* choice = nullptr);

}  // namespace rig
