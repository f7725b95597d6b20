// Models into relight's bases: exactly where the basis spans the same functions (our PTM
// order <= 2 and HSH order <= 2, fitted in sRGB space: a linear map of the coefficients), by
// least squares at the model's own sampled lights otherwise (SH, other orders, linear or log
// fit spaces, another relight basis) — and in every case the PSNR between the source's render
// and the result's, so nothing different is ever written silently.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "config/result.h"
#include "process/export/relight_coefficients.h"
#include "process/model/harmonic/model.h"
#include "process/model/reflectance_model.h"

namespace rig {

struct RelightTarget {
  RelightType type = RelightType::kPtm;
  int terms = 6;      // ptm: 6; hsh: 9 or 4 (16: a .rti's third order)
  bool lrgb = false;  // ptm only: luminance PTM × per-pixel RGB albedo
};

struct Conversion {
  RelightCoefficients coefficients;
  bool exact = false;      // the same function of the light (to float rounding), unquantised
  double psnr_db = 0;      // source render against the converted one, 8-bit sRGB units (0..255
                           // clamped, not rounded), over `lights`; +inf when identical
  double map_residual = 0; // exact maps: largest |B_relight·M − B_ours| over the hemisphere
  int lights = 0;          // directions of the PSNR (and of the refit)
  double gain = 1;         // the source's ρ was scaled by this before encoding: 1, except for
                           // linear/log models whose ρ goes beyond 1 (radiance maps), where the
                           // 99.5th percentile of ρ at the lights becomes white
  std::string how;         // one line: what was done
};

// Told how far a stage over lights has come ("refitting", "measuring the error"): done of
// total lights. Called from any of the threads, one call at a time.
using LightProgress = std::function<void(const char* stage, size_t done, size_t total)>;

// A harmonic model. Lights: the model's sampled lamps (ModelInfo::lamp_directions), the upper
// hemisphere when it has none. Flagged pixels get zero coefficients (they render 0, as ours).
Result<Conversion> ConvertToRelight(const Model& model, const RelightTarget& target,
                                    const LightProgress& progress = {});

// Any model: a relight-basis model (WrapRelight) is copied or mapped exactly where it can be
// (same basis; lrgb to rgb), any other is refitted at `lights` (empty: its fitted lights when
// it carries them, else the hemisphere directions its CheckRegion calls inside).
Result<Conversion> ConvertToRelight(const ReflectanceModel& model, const RelightTarget& target,
                                    std::vector<Vec3> lights = {},
                                    const LightProgress& progress = {});

// A luminance PTM times a per-pixel RGB albedo from an rgb PTM, by least squares over
// `lights`: luminance a = the mean of the channels' polynomials; albedo ρ_c = aᵀGc_c / aᵀGa
// (G = WᵀW), scaled so the largest channel is 255.
RelightCoefficients FactoriseLrgb(const RelightCoefficients& rgb, const std::vector<Vec3>& lights);

// 8-bit sRGB PSNR of two models' renders over directions (both clamped to 0..255), a's ρ
// scaled by gain_a first (Conversion::gain).
double RenderPsnrDb(const ReflectanceModel& a, const ReflectanceModel& b,
                    const std::vector<Vec3>& directions, double gain_a = 1,
                    const LightProgress& progress = {});

}  // namespace rig
