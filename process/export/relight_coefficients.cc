// relight's PTM and HSH bases, its evaluation, and the model behind ReflectanceModel.
#include "process/export/relight_coefficients.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "process/export/relight_files.h"
#include "process/model/harmonic/fit.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

bool HasExtension(const std::string& path, const char* ext) {
  std::string e = fs::path(path).extension().string();
  for (char& ch : e) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return e == ext;
}

class RelightFamily final : public ReflectanceModel {
 public:
  RelightFamily(RelightCoefficients c, std::string origin, int web_quality)
      : c_(std::move(c)), origin_(std::move(origin)), web_quality_(web_quality) {
    CheckRelightCoefficients(c_);
    spacing_deg_ = c_.lights.empty() ? 0 : SampleSpacingDeg(c_.lights);
  }
  std::string family() const override {
    return c_.lrgb ? "ptm-lrgb" : RelightTypeName(c_.type);
  }
  std::string Describe() const override {
    return fmt::format("{} (relight's basis){}", c_.Summary(),
                       origin_.empty() ? "" : ", from " + origin_);
  }
  std::vector<Vec3> fitted_lights() const override { return c_.lights; }
  int width() const override { return c_.width; }
  int height() const override { return c_.height; }
  ValueEncoding encoding() const override { return ValueEncoding::kSrgb; }
  const LightFrameConfig& light_frame() const override { return frame_; }
  cv::Mat EvaluateRho(const Vec3& d) const override {
    cv::Mat v = RenderRelight(c_, d);
    float* p = v.ptr<float>();
    const size_t n = v.total() * 3;
    for (size_t i = 0; i < n; ++i) p[i] = SrgbDecode(p[i] / 255.0f);
    return v;
  }
  cv::Mat EvaluateEncoded(const Vec3& d) const override {
    cv::Mat v = RenderRelight(c_, d);
    v *= 1.0 / 255.0;  // relight's values are code values
    return v;
  }
  RegionCheck CheckRegion(const Vec3& d) const override {
    if (!c_.lights.empty()) return CheckAgainstLamps(c_.lights, spacing_deg_, d);
    // Legacy files carry no lights: an RTI capture samples the hemisphere above the object.
    RegionCheck r;
    r.spacing_deg = 90;
    r.nearest_deg = 0;
    r.inside = d[2] >= 0;
    return r;
  }
  Status Save(const std::string& path) const override {
    if (HasExtension(path, ".ptm")) return WritePtm(path, c_);
    if (HasExtension(path, ".rti")) return WriteRti(path, c_);
    WebWriteOptions o;
    o.quality = web_quality_;
    return WriteRelightWeb(path, c_, o);
  }
  const RelightCoefficients& coefficients() const { return c_; }

 private:
  RelightCoefficients c_;
  std::string origin_;
  int web_quality_ = 95;
  LightFrameConfig frame_;
  double spacing_deg_ = 0;
};

}  // namespace

const char* RelightTypeName(RelightType type) {
  return type == RelightType::kPtm ? "ptm" : type == RelightType::kSh ? "sh" : "hsh";
}

void RelightWeights(RelightType type, int terms, const Vec3& d, double* w) {
  const double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  RIG_CHECK(n > 0, "RelightWeights needs a non-zero direction");
  const double lx = d[0] / n, ly = d[1] / n;
  if (type == RelightType::kPtm) {
    RIG_CHECK(terms == 6, "relight's PTM has 6 terms");
    w[0] = 1;
    w[1] = lx;
    w[2] = ly;
    w[3] = lx * lx;
    w[4] = lx * ly;
    w[5] = ly * ly;
    return;
  }
  RIG_CHECK(terms == 9 || terms == 4 || terms == 1 || (terms == 16 && type == RelightType::kHsh),
            "relight's HSH and SH have 1, 4 or 9 terms (a .rti's HSH 16 too)");
  // relight takes lz = sqrt(1 - lx² - ly²), whatever the sign of the z it was given.
  const double lz = std::sqrt(std::max(0.0, 1.0 - lx * lx - ly * ly));
  if (type == RelightType::kSh) {
    // relight's constants, as floats: 0.282095, 0.488603, 1.092548, 0.315392, 0.546274.
    w[0] = 0.282095;
    if (terms == 1) return;
    w[1] = 0.488603 * ly;
    w[2] = 0.488603 * lz;
    w[3] = 0.488603 * lx;
    if (terms == 4) return;
    w[4] = 1.092548 * lx * ly;
    w[5] = 1.092548 * ly * lz;
    w[6] = 0.315392 * (3 * lz * lz - 1);
    w[7] = 1.092548 * lx * lz;
    w[8] = 0.546274 * (lx * lx - ly * ly);
    return;
  }
  double phi = std::atan2(ly, lx);
  if (phi < 0) phi += 2 * M_PI;
  const double theta = std::min(std::acos(std::min(1.0, lz)), M_PI / 2 - 0.01);
  const double ct = std::cos(theta);
  const double s = std::sqrt(std::max(0.0, ct - ct * ct));
  w[0] = 1 / std::sqrt(2 * M_PI);
  if (terms == 1) return;
  w[1] = std::sqrt(6 / M_PI) * std::cos(phi) * s;
  w[2] = std::sqrt(3 / (2 * M_PI)) * (2 * ct - 1);
  w[3] = std::sqrt(6 / M_PI) * std::sin(phi) * s;
  if (terms == 4) return;
  w[4] = std::sqrt(30 / M_PI) * std::cos(2 * phi) * (ct * ct - ct);
  w[5] = std::sqrt(30 / M_PI) * std::cos(phi) * (2 * ct - 1) * s;
  w[6] = std::sqrt(5 / (2 * M_PI)) * (1 - 6 * ct + 6 * ct * ct);
  w[7] = std::sqrt(30 / M_PI) * std::sin(phi) * (2 * ct - 1) * s;
  w[8] = std::sqrt(30 / M_PI) * std::sin(2 * phi) * (ct * ct - ct);
  if (terms == 9) return;
  // The third degree (RTIViewer's HSH of order 4): s³ = (cosθ - cos²θ)^1.5.
  const double s3 = s * s * s, p3 = 1 - 5 * ct + 5 * ct * ct;
  w[9] = 2 * std::sqrt(35 / M_PI) * std::cos(3 * phi) * s3;
  w[10] = std::sqrt(210 / M_PI) * std::cos(2 * phi) * (2 * ct - 1) * (ct * ct - ct);
  w[11] = 2 * std::sqrt(21 / M_PI) * std::cos(phi) * s * p3;
  w[12] = std::sqrt(7 / (2 * M_PI)) * (-1 + 12 * ct - 30 * ct * ct + 20 * ct * ct * ct);
  w[13] = 2 * std::sqrt(21 / M_PI) * std::sin(phi) * s * p3;
  w[14] = std::sqrt(210 / M_PI) * std::sin(2 * phi) * (2 * ct - 1) * (ct * ct - ct);
  w[15] = 2 * std::sqrt(35 / M_PI) * std::sin(3 * phi) * s3;
}

std::string RelightCoefficients::Summary() const {
  return fmt::format("{} {}, {} terms{}, {}x{}", RelightTypeName(type), colorspace(), terms,
                     lrgb ? " of luminance + RGB albedo" : " per channel", width, height);
}

void CheckRelightCoefficients(const RelightCoefficients& c) {
  RIG_CHECK(c.type == RelightType::kPtm ? c.terms == 6
                                         : (c.terms == 9 || c.terms == 4 || c.terms == 1 ||
                                            (c.terms == 16 && c.type == RelightType::kHsh)),
            "relight coefficients: wrong number of terms for the type");
  RIG_CHECK(!c.lrgb || c.type == RelightType::kPtm, "lrgb is a PTM colorspace");
  RIG_CHECK(static_cast<int>(c.planes.size()) == c.terms, "relight coefficients: plane count");
  for (const auto& p : c.planes) {
    RIG_CHECK(p.rows == c.height && p.cols == c.width, "relight coefficients: plane size");
    RIG_CHECK(p.type() == (c.lrgb ? CV_32FC1 : CV_32FC3), "relight coefficients: plane type");
  }
  if (c.lrgb) {
    RIG_CHECK(c.albedo.rows == c.height && c.albedo.cols == c.width && c.albedo.type() == CV_32FC3,
              "relight coefficients: albedo");
  }
}

cv::Mat RenderRelight(const RelightCoefficients& c, const Vec3& direction) {
  double w[kMaxRelightTerms];
  RelightWeights(c.type, c.terms, direction, w);
  cv::Mat out = cv::Mat::zeros(c.height, c.width, CV_32FC3);
  if (!c.lrgb) {
    for (int j = 0; j < c.terms; ++j) cv::scaleAdd(c.planes[j], w[j], out, out);
    return out;
  }
  cv::Mat lum = cv::Mat::zeros(c.height, c.width, CV_32FC1);
  for (int j = 0; j < c.terms; ++j) cv::scaleAdd(c.planes[j], w[j] / 255.0, lum, lum);
  for (int y = 0; y < c.height; ++y) {
    const float* l = lum.ptr<float>(y);
    const float* a = c.albedo.ptr<float>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < c.width; ++x)
      for (int k = 0; k < 3; ++k) o[3 * x + k] = l[x] * a[3 * x + k];
  }
  return out;
}

std::unique_ptr<ReflectanceModel> WrapRelight(RelightCoefficients c, std::string origin,
                                              int web_quality) {
  return std::make_unique<RelightFamily>(std::move(c), std::move(origin), web_quality);
}

const RelightCoefficients* RelightCoefficientsOf(const ReflectanceModel& model) {
  const auto* f = dynamic_cast<const RelightFamily*>(&model);
  return f ? &f->coefficients() : nullptr;
}

std::vector<Vec3> HemisphereDirections() {
  std::vector<Vec3> dirs{{0, 0, 1}};
  for (int t = 5; t <= 85; t += 5) {
    const double theta = t * M_PI / 180;
    for (int p = 0; p < 360; p += 10) {
      const double phi = p * M_PI / 180;
      dirs.push_back({std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                      std::cos(theta)});
    }
  }
  return dirs;
}

}  // namespace rig
