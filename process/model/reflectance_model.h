// One interface for every reflectance model family: per-pixel coefficients of a fixed
// analytic basis (SH, HSH, PTM: `Model`), PCA with interpolated light dependence
// (`PcaModel`), a neural decoder. Render, evaluate, export and the viewer go through it alone.
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
#include "process/model/model.h"

namespace rig {

class ReflectanceModel {
 public:
  virtual ~ReflectanceModel() = default;

  virtual std::string family() const = 0;    // "sh", "hsh", "ptm", "pca-bilinear", "neural"
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
  // Adds the radiance one lamp gives, ρ(dir) · E_capture · rgb_scale (R, G, B), into *sum
  // (CV_32FC3, created when empty).
  virtual void AddLamp(const Vec3& direction, const std::array<double, 3>& rgb_scale,
                       cv::Mat* sum) const;
  // Where a direction lies relative to the lamps the model was fitted to.
  virtual RegionCheck CheckRegion(const Vec3& direction) const = 0;
  // CV_8U, 1 valid / 0 flagged; empty: every pixel valid.
  virtual cv::Mat valid() const { return {}; }

  // Writes the model (a file or a folder, by family) at `path`.
  virtual Status Save(const std::string& path) const = 0;
};

// The harmonic families (SH, HSH, PTM coefficients in an EXR).
std::unique_ptr<ReflectanceModel> WrapHarmonic(Model model);
// The PCA family (a relight web-format folder); lamp directions as the capture gave them.
class PcaModel;
std::unique_ptr<ReflectanceModel> WrapPca(PcaModel model);

// Reads any family: an EXR file (harmonic), a folder with info.json (relight's web format,
// the types this build reads), a folder with a neural model.
Result<std::unique_ptr<ReflectanceModel>> LoadReflectanceModel(const std::string& path);

// Bytes on disk of a model: the file, or every file of the folder.
uint64_t ModelBytesOnDisk(const std::string& path);

// The nearest fitted lamp and whether a direction is within the sampling's own spacing.
RegionCheck CheckAgainstLamps(const std::vector<Vec3>& lamps, double spacing_deg,
                              const Vec3& direction);

}  // namespace rig
