// The families behind ReflectanceModel, and reading any of them from disk.
#include "process/model/reflectance_model.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include "process/model/fit.h"
#include "process/model/pca.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

double AngleBetweenDeg(const Vec3& a, const Vec3& b) {
  const double d = std::clamp(a[0] * b[0] + a[1] * b[1] + a[2] * b[2], -1.0, 1.0);
  return std::acos(d) * 180.0 / M_PI;
}

class HarmonicModel final : public ReflectanceModel {
 public:
  explicit HarmonicModel(Model m) : m_(std::move(m)) {}
  std::string family() const override { return m_.basis().name(); }
  std::string Describe() const override {
    return fmt::format("{} order {} ({} terms per channel), {} fit in {} space", m_.basis().name(),
                       m_.basis().order(), m_.basis().size(), FitMethodName(m_.info().method),
                       FitSpaceName(m_.info().transform.space));
  }
  int width() const override { return m_.width(); }
  int height() const override { return m_.height(); }
  ValueEncoding encoding() const override { return m_.info().source_encoding; }
  const LightFrameConfig& light_frame() const override { return m_.info().light_frame; }
  std::array<double, 3> lamp_radiance_rgb() const override { return m_.info().lamp_radiance_rgb; }
  cv::Mat EvaluateRho(const Vec3& d) const override { return m_.EvaluateRho(d); }
  void AddLamp(const Vec3& d, const std::array<double, 3>& rgb, cv::Mat* sum) const override {
    m_.AddLamp(d, rgb, sum);
  }
  RegionCheck CheckRegion(const Vec3& d) const override { return m_.CheckRegion(d); }
  cv::Mat valid() const override { return m_.valid(); }
  Status Save(const std::string& path) const override {
    return SaveModel(path, m_, ExrPixelType::kHalf);
  }

 private:
  Model m_;
};

class PcaFamily final : public ReflectanceModel {
 public:
  explicit PcaFamily(PcaModel m) : m_(std::move(m)) {
    spacing_deg_ = m_.lights().empty() ? 0 : SampleSpacingDeg(m_.lights());
  }
  std::string family() const override { return "pca-bilinear"; }
  std::string Describe() const override {
    const auto& b = m_.basis();
    return fmt::format("pca-bilinear: {} components, {}x{} octahedral grid ({} prior, strength "
                       "{:.3g}), 8-bit planes, JPEG q{}",
                       b.components, b.resolution, b.resolution,
                       b.prior == GridPrior::kBending ? "bending" : "membrane", b.smoothness,
                       m_.jpeg_quality());
  }
  int width() const override { return m_.width(); }
  int height() const override { return m_.height(); }
  ValueEncoding encoding() const override { return ValueEncoding::kSrgb; }
  const LightFrameConfig& light_frame() const override { return frame_; }
  cv::Mat EvaluateRho(const Vec3& d) const override {
    cv::Mat v = m_.Render(d);
    float* p = v.ptr<float>();
    const size_t n = v.total() * 3;
    for (size_t i = 0; i < n; ++i) p[i] = SrgbDecode(p[i]);
    return v;
  }
  RegionCheck CheckRegion(const Vec3& d) const override {
    return CheckAgainstLamps(m_.lights(), spacing_deg_, d);
  }
  Status Save(const std::string& path) const override { return m_.Save(path); }

 private:
  PcaModel m_;
  LightFrameConfig frame_;
  double spacing_deg_ = 0;
};

}  // namespace

void ReflectanceModel::AddLamp(const Vec3& direction, const std::array<double, 3>& rgb_scale,
                               cv::Mat* sum) const {
  const cv::Mat rho = EvaluateRho(direction);
  const auto e = lamp_radiance_rgb();
  const float gain[3] = {static_cast<float>(e[2] * rgb_scale[2]),
                         static_cast<float>(e[1] * rgb_scale[1]),
                         static_cast<float>(e[0] * rgb_scale[0])};  // B, G, R
  if (sum->empty()) *sum = cv::Mat::zeros(height(), width(), CV_32FC3);
  for (int y = 0; y < rho.rows; ++y) {
    const float* r = rho.ptr<float>(y);
    float* out = sum->ptr<float>(y);
    for (int x = 0; x < rho.cols; ++x)
      for (int c = 0; c < 3; ++c) out[3 * x + c] += gain[c] * r[3 * x + c];
  }
}

std::unique_ptr<ReflectanceModel> WrapHarmonic(Model model) {
  return std::make_unique<HarmonicModel>(std::move(model));
}

std::unique_ptr<ReflectanceModel> WrapPca(PcaModel model) {
  return std::make_unique<PcaFamily>(std::move(model));
}

Result<std::unique_ptr<ReflectanceModel>> LoadReflectanceModel(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (fs::exists(fs::path(path) / "info.json", ec)) {
      RIG_ASSIGN_OR_RETURN(PcaModel m, PcaModel::Load(path));
      return WrapPca(std::move(m));
    }
    return MakeError(ErrorCode::kInvalidInput, path,
                     "a folder without info.json is not a model this build reads");
  }
  RIG_ASSIGN_OR_RETURN(Model m, LoadModel(path));
  return WrapHarmonic(std::move(m));
}

uint64_t ModelBytesOnDisk(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return FolderBytes(path);
  const auto n = fs::file_size(path, ec);
  return ec ? 0 : n;
}

RegionCheck CheckAgainstLamps(const std::vector<Vec3>& lamps, double spacing_deg,
                              const Vec3& direction) {
  RegionCheck r;
  r.nearest_deg = 180;
  for (const auto& d : lamps) r.nearest_deg = std::min(r.nearest_deg, AngleBetweenDeg(direction, d));
  r.spacing_deg = spacing_deg;
  r.inside = !lamps.empty() && r.nearest_deg <= spacing_deg + 0.5;
  return r;
}

}  // namespace rig
