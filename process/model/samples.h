// Samples of ρ in a fit space, shared by every model family and the session's fit: the
// transforms a fit minimises error in (linear, sRGB, log), the sample matrix built from
// radiance maps with its missing samples, its Gram matrix, and the lamp radiance from a
// reference patch.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "config/result.h"

namespace rig {

enum class FitSpace { kLinear, kSrgb, kLog };

const char* FitSpaceName(FitSpace space);     // "linear", "srgb", "log"
Result<FitSpace> ParseFitSpace(const std::string& name);

// The transform of ρ the fit minimises error in, and back. Rendering evaluates the model,
// applies the inverse per lamp and only then adds lamps (lamps add in linear radiance).
//   linear: y = ρ;  srgb: the sRGB curve extended oddly beyond [0, 1];  log: y = ln(ρ + ε).
struct FitTransform {
  FitSpace space = FitSpace::kLinear;
  double log_epsilon = 1e-3;  // ε of the log space (in units of ρ)
  float Forward(float rho) const;
  float Inverse(float y) const;
  void ForwardInPlace(float* data, size_t n) const;  // vectorised where it matters
  void InverseInPlace(float* data, size_t n) const;
};

// The sRGB transfer function and its inverse, for values in [0, 1] (and beyond, oddly
// extended).
float SrgbEncode(float linear);
float SrgbDecode(float encoded);

// Samples in fit space: row i = pose i, columns = pixels x 3 channels (BGR interleaved).
using SampleMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Builds the sample matrix from radiance images (CV_32FC3, BGR) of one band of rows:
// ρ = radiance / lamp radiance, then the fit transform. `valid` (optional, CV_8U per pose,
// non-zero = valid) and non-finite or negative radiance mark missing samples; missing
// samples are stored as 0 and listed in *missing (pose-major N x pixels, 1 = missing), which
// is left empty when nothing is missing.
Status BuildSamples(const std::vector<cv::Mat>& radiance, const std::vector<cv::Mat>& valid,
                    const std::array<double, 3>& lamp_radiance_rgb,
                    const FitTransform& transform, SampleMatrix* samples,
                    std::vector<uint8_t>* missing);

// The same from rows given one at a time: `row(i, y)` is row y (0-based in the band) of pose
// i's radiance (cols x BGR floats, valid until the next call), `valid_row(i, y)` its validity
// or nullptr. The same arithmetic as BuildSamples, so a source that converts its rows on the
// fly (maps held in half, MapStore) gives the same samples without a band of floats between.
Status BuildSamplesFromRows(size_t poses, int rows, int cols,
                            const std::function<const float*(size_t, int)>& row,
                            const std::function<const uint8_t*(size_t, int)>& valid_row,
                            const std::array<double, 3>& lamp_radiance_rgb,
                            const FitTransform& transform, SampleMatrix* samples,
                            std::vector<uint8_t>* missing);

// Gram matrix of the columns of pixels without missing samples, every `stride`-th pixel.
Eigen::MatrixXd SampleGram(const SampleMatrix& samples, const std::vector<uint8_t>& missing,
                           size_t stride, double* count);

// Lamp radiance from a reference patch of known (apparent) reflectance: per channel, the
// median over poses of the patch's mean radiance, divided by the reflectance. The patch
// then has ρ = reflectance (median over poses).
Result<std::array<double, 3>> CalibrateLampRadiance(const std::vector<cv::Mat>& radiance,
                                                    const std::array<int, 4>& patch_px,
                                                    double reflectance);

}  // namespace rig
