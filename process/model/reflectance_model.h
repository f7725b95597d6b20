// One interface for every reflectance model family: per-pixel coefficients of a fixed
// analytic basis (SH, HSH, PTM: `Model`), PCA with interpolated light dependence
// (`PcaModel`). Render, evaluate, export and the viewer go through it alone; each family
// wraps its own model (WrapHarmonic, WrapPca), any/load_model.h reads any of them.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/model/light_direction.h"

namespace rig {

// What a model's values came from: ρ from radiance maps (linear), or the display-referred code
// values of 8-bit photographs (sRGB), which renders by default reproduce as the photos did.
enum class ValueEncoding { kLinear, kSrgb };

// Where a lamp direction lies relative to the sampled lamps.
struct RegionCheck {
  double nearest_deg = 0;  // angle to the nearest sampled lamp
  bool inside = true;      // nearest_deg <= the sampling's own spacing (+0.5° slack)
  double spacing_deg = 0;  // that spacing: the largest nearest-neighbour angle between lamps
};

class ReflectanceModel {
 public:
  virtual ~ReflectanceModel() = default;

  virtual std::string family() const = 0;    // "sh", "hsh", "ptm", "pca-bilinear" (pca-rbf, -ybilinear, -yrbf read), "neural"
  virtual std::string Describe() const = 0;  // one line: family, size, how it was fitted
  virtual int width() const = 0;
  virtual int height() const = 0;
  virtual ValueEncoding encoding() const = 0;
  // The frame that turns the rig's angles into directions (identity for .lp captures).
  virtual const LightFrameConfig& light_frame() const = 0;
  // The lamp radiance the model's ρ is relative to (R, G, B); 1 for photographs.
  virtual std::array<double, 3> lamp_radiance_rgb() const { return {1, 1, 1}; }

  // ρ at a lamp direction in the object frame: linear, CV_32FC3 in B, G, R order; pixels the
  // fit flagged are 0.
  virtual cv::Mat EvaluateRho(const Vec3& direction) const = 0;
  // The model's values in its own encoding (CV_32FC3, B, G, R): ρ for kLinear; for kSrgb the
  // display code values 0..1 the photographs had, i.e. SrgbEncode(ρ) — which a family that
  // holds code values gives without the decode and encode (export's refits run on these).
  virtual cv::Mat EvaluateEncoded(const Vec3& direction) const;
  // Adds the radiance one lamp gives, ρ(dir) · E_capture · rgb_scale (R, G, B), into *sum
  // (CV_32FC3, created when empty).
  virtual void AddLamp(const Vec3& direction, const std::array<double, 3>& rgb_scale,
                       cv::Mat* sum) const;
  // Where a direction lies relative to the lamps the model was fitted to.
  virtual RegionCheck CheckRegion(const Vec3& direction) const = 0;
  // CV_8U, 1 valid / 0 flagged; empty: every pixel valid.
  virtual cv::Mat valid() const { return {}; }
  // The lamp directions (object frame) the model was fitted to, where the model keeps them
  // (the page's default light is their mean); empty when it does not.
  virtual std::vector<Vec3> fitted_lights() const { return {}; }

  // Writes the model (a file or a folder, by family) at `path`.
  virtual Status Save(const std::string& path) const = 0;
};

// The nearest fitted lamp and whether a direction is within the sampling's own spacing.
RegionCheck CheckAgainstLamps(const std::vector<Vec3>& lamps, double spacing_deg,
                              const Vec3& direction);

}  // namespace rig
