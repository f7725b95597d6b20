// The reflectance model: per-pixel basis coefficients with the header that says how to read
// them (basis, order, fit method and space, light frame, lamp radiance, fit statistics, the
// sampled lamp region); fitting it from radiance maps, storing it as EXR, evaluating it.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/model/harmonic/basis.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/light_direction.h"
#include "process/model/reflectance_model.h"

namespace rig {

struct ModelInfo {
  FitMethod method = FitMethod::kRls;
  FitTransform transform;
  double lambda_relative = 0;
  std::array<double, 3> lamp_radiance_rgb = {1, 1, 1};  // R, G, B of the capture lamp
  LightFrameConfig light_frame;
  double loo_rmse = 0;       // fit space
  double condition = 0;
  double solved_condition = 0;
  std::vector<Vec3> lamp_directions;  // the sampled lamps, object frame
  double sample_spacing_deg = 0;      // largest nearest-neighbour angle between lamps
  size_t flagged_pixels = 0;
  // kSrgb: fitted to 8-bit photographs (an .lp set), so a picture is by default their encoding.
  ValueEncoding source_encoding = ValueEncoding::kLinear;
  // A near lamp's correction of the samples (the header's "near_lamp"); empty: none.
  std::string near_lamp;
};

// The header of a fitted model, the same for the in-memory fit and the streamed one: what the
// options, the chosen projector and the fit's input say (flagged_pixels left to the caller).
ModelInfo FittedModelInfo(const FitOptions& options, const Projector& projector, double loo_rmse,
                          const std::array<double, 3>& lamp_radiance_rgb,
                          const LightFrameConfig& light_frame, const std::vector<Vec3>& directions);

class Model {
 public:
  Model() = default;
  Model(Basis basis, ModelInfo info, int width, int height);

  const Basis& basis() const { return basis_; }
  const ModelInfo& info() const { return info_; }
  ModelInfo& info() { return info_; }
  int width() const { return width_; }
  int height() const { return height_; }
  // Coefficient planes, one CV_32FC3 (BGR) per term, in fit space.
  std::vector<cv::Mat>& coefficients() { return coefficients_; }
  const std::vector<cv::Mat>& coefficients() const { return coefficients_; }
  // CV_8U, 1 valid / 0 flagged (too few valid samples); empty: every pixel valid.
  cv::Mat& valid() { return valid_; }
  const cv::Mat& valid() const { return valid_; }

  // ρ at one lamp direction (linear, CV_32FC3 BGR): Σ_k b_k(dir)·C_k, then the inverse fit
  // transform. Flagged pixels are 0.
  cv::Mat EvaluateRho(const Vec3& direction) const;
  // Adds the radiance one lamp gives: ρ(dir) · E_capture · rgb_scale (R, G, B) into *sum
  // (CV_32FC3, created when empty).
  void AddLamp(const Vec3& direction, const std::array<double, 3>& rgb_scale,
               cv::Mat* sum) const;
  RegionCheck CheckRegion(const Vec3& direction) const;

 private:
  Basis basis_{BasisKind::kSh, 0};
  ModelInfo info_;
  int width_ = 0, height_ = 0;
  std::vector<cv::Mat> coefficients_;
  cv::Mat valid_;
};

// Channel names "c00.R", "c00.G", "c00.B", "c01.R", ... (plus "valid" when some pixel is
// flagged); header attributes: see ModelHeaderAttributes.
Status SaveModel(const std::string& path, const Model& model, ExrPixelType type);
Result<Model> LoadModel(const std::string& path);
std::map<std::string, std::string> ModelHeaderAttributes(const Model& model);
// Parses the header attributes back (basis and order too).
Result<Model> ModelFromHeader(const std::map<std::string, std::string>& attributes, int width,
                              int height, const std::string& context);
std::string CoefficientChannelName(int term, char channel);  // 'R', 'G', 'B'

// In-memory fit of radiance maps with known lamp directions.
struct FitInput {
  std::vector<cv::Mat> radiance;        // CV_32FC3 BGR, all the same size
  std::vector<Vec3> directions;         // one per map
  std::vector<double> weights;          // quadrature weights; empty: 2π/N each
  std::vector<cv::Mat> valid;           // optional CV_8U per map, non-zero = valid
  std::array<double, 3> lamp_radiance_rgb = {1, 1, 1};
  LightFrameConfig light_frame;
};
struct FitOutput {
  Model model;
  Selection selection;
  MissingStats missing;
  double fit_time_s = 0;  // samples + selection + product + missing-sample solves
};
Result<FitOutput> FitModel(const FitInput& input, const FitOptions& options);

// A Markdown report of a fit: the per-order table and the choice.
std::string FitReportMarkdown(const FitOutput& output, const FitOptions& options);

// The harmonic families (SH, HSH, PTM coefficients in an EXR) behind ReflectanceModel.
std::unique_ptr<ReflectanceModel> WrapHarmonic(Model model);

}  // namespace rig
