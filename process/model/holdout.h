// Held-out error of a model family on a multi-light capture, measured the way a user of the
// field measures it: for each held-out image, the family is fitted anew to the other images
// (every choice it makes — size, smoothness, ranges — made inside the fold), written to disk
// as it would be shipped, read back, rendered at the held-out light, encoded to 8 bits and
// compared with the photograph.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/light_samples.h"

namespace rig {

// Builds the samples of a capture: images CV_8UC3 in OpenCV's B, G, R order, all one size.
LightSamples SamplesFromImages(const std::vector<cv::Mat>& bgr8, const std::vector<Vec3>& lights);

// What a fold returns: the prediction at the held-out light (CV_32FC3 B, G, R in encoded
// units, code / 255, unclipped) and the bytes of the model it fitted, as written.
struct FoldPrediction {
  cv::Mat predicted;
  uint64_t bytes = 0;
};
using FitAndPredict =
    std::function<Result<FoldPrediction>(const LightSamples& fold, int held_out, const Vec3& light)>;

struct HoldoutScore {
  std::vector<int> held_out;   // image indices
  std::vector<double> mse;     // per held-out image, 8-bit units², over every pixel and channel
  double psnr_mean_mse_db = 0; // 10·log10(255² / mean MSE)
  double psnr_median_db = 0;   // median of the per-image PSNRs
  double bytes_per_pixel = 0;  // mean over the folds
  double fold_time_s = 0;      // mean time of one fold (fit, write, read, render)
};

// `held_out` empty: every image. Errors of a fold name the image index.
Result<HoldoutScore> LeaveOneOut(const LightSamples& all, const std::vector<int>& held_out,
                                 const FitAndPredict& fit);

// MSE in 8-bit units of a prediction against the samples of light `light`.
double EightBitMse(const LightSamples& all, int light, const cv::Mat& predicted_bgr);

double PsnrFromMse(double mse);

}  // namespace rig
