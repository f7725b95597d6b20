// Coefficient models in relight's own bases (PTM with its term order, HSH with its weights),
// held as relight holds them after dequantisation, evaluated with relight's formulas, and put
// behind ReflectanceModel: what the web-format, .ptm and .rti readers return and the writers
// take. Facts from ../shared/docs/rti-formats.md (relight 2026.03, HEAD 5cca5c3e).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "process/model/light_direction.h"
#include "process/model/reflectance_model.h"

namespace rig {

enum class RelightType { kPtm, kHsh, kSh };
const char* RelightTypeName(RelightType type);  // "ptm", "hsh", "sh"

// relight's light weights at a direction (normalised inside; lz = sqrt(1 - lx² - ly²) as
// relight takes it). PTM, 6 terms: [1, lx, ly, lx², lx·ly, ly²] (Rti::lightWeightsPtm).
// HSH, 4 or 9 terms: Rti::lightWeightsHsh, θ clamped at π/2 - 0.01; 16 terms (order 4, the
// .rti's largest HSH in RTIViewer, whose hsh weights add w9..w15) for .rti files only:
// relight's renderer and its web format stop at 9.
// SH, 4 or 9 terms: Rti::lightWeightsSh, the real spherical harmonics of degree ≤ 2 in
// Cartesian form with relight's constants (Y00, Y1-1 = y, Y10 = z, Y11 = x, Y2-2 ... Y22).
// relight's JS viewer draws no sh: a page of an sh model is made as hsh (rig view says so).
// `w` holds kMaxRelightTerms values.
constexpr int kMaxRelightTerms = 16;
void RelightWeights(RelightType type, int terms, const Vec3& direction, double* w);

// One model in relight's basis. Values are relight's: 0..255 pixel units of sRGB-encoded
// values, not clamped here (relight clamps and truncates its 8-bit output).
//   rgb:  planes[j] CV_32FC3 (B, G, R) = coefficient j;  out_c = Σ_j w_j(l) · planes[j]_c
//   lrgb: planes[j] CV_32FC1 = luminance coefficient j, albedo CV_32FC3 (B, G, R) 0..255
//         (whole numbers: bytes);                       out_c = (Σ_j w_j(l) · planes[j] / 255) · albedo_c
struct RelightCoefficients {
  RelightType type = RelightType::kPtm;
  int terms = 6;  // ptm: 6; hsh, sh: 9 or 4; hsh of a .rti: 16 too
  bool lrgb = false;  // ptm only
  int width = 0, height = 0;
  std::vector<cv::Mat> planes;
  cv::Mat albedo;
  std::vector<Vec3> lights;  // the lights it was fitted to, when the file says (web "lights")

  // The colorspace name relight uses: "rgb" or "lrgb".
  const char* colorspace() const { return lrgb ? "lrgb" : "rgb"; }
  // "ptm rgb, 6 terms per channel" style.
  std::string Summary() const;
};

// Checks the shape (terms for the type, plane count, sizes, types); a bug when violated.
void CheckRelightCoefficients(const RelightCoefficients& c);

// relight's value at a direction: CV_32FC3 (B, G, R), 0..255 units, unclamped.
cv::Mat RenderRelight(const RelightCoefficients& c, const Vec3& direction);

// Behind the interface: family "ptm" / "ptm-lrgb" / "hsh", encoding sRGB (ρ = the sRGB
// decode of value / 255), identity light frame. The region check uses `lights` when known;
// without them (legacy files carry none) every direction above the horizon counts as inside.
// `origin` says where it came from, for Describe(). Save() writes by the path's form: .ptm,
// .rti, otherwise a web-format folder with its planes at JPEG quality `web_quality`.
std::unique_ptr<ReflectanceModel> WrapRelight(RelightCoefficients c, std::string origin,
                                              int web_quality = 95);
// The coefficients of a model made by WrapRelight; nullptr for any other model.
const RelightCoefficients* RelightCoefficientsOf(const ReflectanceModel& model);

// Directions for maps and PSNRs when a model carries no sampled lights: the upper hemisphere,
// θ = 0..85° in 5° steps, φ in 10° steps (613 directions).
std::vector<Vec3> HemisphereDirections();

}  // namespace rig
