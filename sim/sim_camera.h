// The simulated camera: renders the synthetic scene under the simulated lamp into the 8-bit
// JPEG/PNG bytes a body would return, through a known noise model and response curve.
//
// Per channel: electrons = radiance * exposure_s * gain; shot noise (Gaussian with variance =
// electrons) and read noise (Gaussian, read_noise_e) from a seeded generator; clip to
// [0, full_well]; x = electrons / full_well; code = round(255 * f_c(x)) with the response f_c
// of config sim.camera.response; JPEG (jpeg_quality) or PNG bytes through cv::imencode.
//
// Faults (config [sim.camera]; capture numbers count Capture() calls with a valid exposure,
// from 1, over this object's life — a new process starts again at 1):
//   fail_capture_at = [n, ...]  capture n fails once (kDevice)
//   fail_capture_every = N      captures N, 2N, ... fail (kTimeout, as a body that hangs)
//   fail_forever_after = K      captures K, K+1, ... all fail (kDevice)
//   disconnect_at = D, disconnect_captures = C
//                               captures D .. D+C-1 fail with kDevice "disconnected"; from
//                               D+C on the body answers again. Open() is accepted at any time
//                               (also while disconnected) and is not required afterwards.
// Every error's context is "sim camera".
//
// Latency: each capture lasts (exposure + download_time_s) * sim.latency_scale of wall time
// (0: no waiting), measured from the call, so the rendering time is part of it.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "capture/devices/camera.h"
#include "config/config.h"
#include "sim/scene.h"
#include "sim/world.h"

namespace rig {

// The simulated body's true response, per channel (index 0 = B, 1 = G, 2 = R as in images).
//
// Exposure X = radiance * seconds (scene radiance units, see scene.h). The sensor signal is
// x = clamp(X * gain / full_well, 0, 1) and the recorded level z = round(255 * f_c(x)).
//   "filmic": f_c(x) = (hable(W_c x) / hable(W_c))^(1 / gamma_c), Hable's filmic curve (toe
//             and shoulder) with white point W = (9, 13, 11.2) for (B, G, R), followed by a
//             display gamma gamma_c = response_gamma_rgb; an S-curve in log exposure.
//   "gamma":  f_c(x) = x^(1 / gamma_c).
//   "linear": f_c(x) = x.
// LogExposure(c, z) = ln X at which f_c reaches exactly z/255: this is the g(z) that
// Debevec-Malik recovers (up to an additive constant). Level 0 stands for its bin's middle
// in X (half the first threshold); level 255 for saturation (X = full_well / gain).
class SimResponse {
 public:
  static Result<SimResponse> Create(const SimCameraConfig& camera);

  const std::string& kind() const { return kind_; }
  // f_c: normalised sensor signal in [0, 1] to the encoded value in [0, 1].
  double Encode(int channel, double x) const;
  // f_c^-1: encoded value in [0, 1] to the normalised signal in [0, 1].
  double Decode(int channel, double y) const;
  // The recorded level of a normalised signal: exactly round(255 f_c(x)), x clamped to [0, 1].
  uint8_t Quantize(int channel, float x) const {
    const auto& t = thresholds_[channel];
    x = x < 0.f ? 0.f : (x > 1.f ? 1.f : x);
    int z = lut_[channel][static_cast<int>(std::sqrt(x) * kLutMax)];
    while (z < 255 && x >= t[z]) ++z;
    while (z > 0 && x < t[z - 1]) --z;  // float rounding of sqrt at a cell's edge
    return static_cast<uint8_t>(z);
  }
  // g(z) = ln(radiance * seconds) of level z; see above.
  double LogExposure(int channel, int z) const { return g_[channel][z]; }
  // The bin of level z in ln exposure: every X with Quantize == z lies in [low, high].
  double LogExposureLow(int channel, int z) const;
  double LogExposureHigh(int channel, int z) const;
  const std::array<double, 256>& Curve(int channel) const { return g_[channel]; }
  // X at saturation: full_well / gain (radiance * seconds).
  double saturation_exposure() const { return saturation_exposure_; }

  // Everything needed to re-create it (kind, gammas, white points, gain, full well).
  nlohmann::json ToJson() const;
  static Result<SimResponse> FromJson(const nlohmann::json& j);

 private:
  static constexpr int kLutMax = 4095;
  SimResponse() = default;
  void Build();

  std::string kind_;
  std::array<double, 3> gamma_{}, white_{};  // B, G, R
  double saturation_exposure_ = 1;
  std::array<std::array<double, 256>, 3> g_{};
  std::array<std::array<float, 255>, 3> thresholds_{};  // x where level z turns z + 1
  std::array<std::array<uint8_t, kLutMax + 2>, 3> lut_{};  // level at x = (i / kLutMax)^2
};

class SimCamera final : public Camera {
 public:
  // Uses config.sim (scene, camera, seed, latency_scale), config.light_frame and
  // config.lamp.radiance_rgb. `world` is shared with the SimMotor and SimLamp of the rig.
  static Result<std::unique_ptr<SimCamera>> Create(const Config& config,
                                                   std::shared_ptr<SimWorld> world);

  std::string Describe() const override;
  Status Open() override;
  void Close() override;
  // ThirdStopShutterSpeeds(shutter_min_s, shutter_max_s).
  Result<std::vector<Seconds>> ShutterSpeeds() override;
  // Fixed ISO "100", aperture "8", white balance "Daylight"; RAW+JPEG when asked (the RAW
  // file a DNG: 14-bit linear sensor values, three per pixel (LinearRaw), black level kRawBlack,
  // white level kRawWhite, from the same electrons and noise as the JPEG). Not Bayer: the
  // scene is rendered with three values per pixel, and mosaicking it only to have LibRaw
  // interpolate it back measured demosaicing, not the merge (log-radiance RMS 0.34 against
  // 0.02 on 96x72 frames); LibRaw's Bayer path is tested on its own in tests/process/); both capture targets alike.
  Result<CameraSettings> Configure(const CameraSettings& wanted) override;
  // Refuses (kInvalidInput) an exposure that is not one of ShutterSpeeds(). The frame's
  // exposure and exif_exposure are the offered value. Renders the world as it is when the
  // shutter opens: a capture while the arm moves, with the lamp off or during its warm-up
  // is counted in the world's violations (and the lamp-off frame is dark).
  Result<CapturedFrame> Capture(Seconds exposure) override;
  // Live view: the world as it is now, exposed automatically (the brightest 1% of the
  // brightest channel at 80% of full well, within the offered shutter speeds), at most
  // kPreviewLongSide pixels on the long side, JPEG. Not a capture: no fault, counter or
  // latency applies, and its noise is drawn from (seed, pose) alone.
  Result<CapturedFile> CapturePreview() override;
  static constexpr int kPreviewLongSide = 640;

  // The 8-bit BGR image of `radiance` (CV_32FC3, scene units) exposed for `exposure`, with
  // noise drawn from `noise_seed`: the camera model without faults, latency or counters.
  // With `raw_dn`, also the sensor's 16-bit values of the same electrons (CV_16UC3 BGR, DN =
  // electrons / kRawElectronsPerDn + kRawBlack, clipped at kRawWhite).
  cv::Mat Expose(const cv::Mat& radiance, Seconds exposure, uint64_t noise_seed,
                 cv::Mat* raw_dn = nullptr) const;
  // The RAW file of `raw_dn` as the body writes it (DNG), with its exposure time.
  Result<std::vector<uint8_t>> EncodeRaw(const cv::Mat& raw_dn, Seconds exposure) const;
  static constexpr int kRawBlack = 512, kRawWhite = 16383;
  double RawElectronsPerDn() const { return sim_.camera.full_well / (kRawWhite - kRawBlack); }
  // Encodes as the body would (sim.camera.format).
  Result<std::vector<uint8_t>> Encode(const cv::Mat& bgr8) const;

  const SimScene& scene() const { return scene_; }
  const SimResponse& response() const { return response_; }
  SimWorld& world() { return *world_; }

  struct Stats {
    int64_t attempts = 0;     // Capture() calls with a valid exposure
    int64_t captures = 0;     // successful ones
    int64_t faults = 0;       // injected failures
    Seconds exposure_time{0};  // simulated (unscaled) totals of the successful captures
    Seconds download_time{0};
  };
  Stats stats() const;

 private:
  SimCamera(const Config& config, std::shared_ptr<SimWorld> world, SimScene scene,
            SimResponse response);
  // The injected fault of capture n, if any.
  std::optional<Error> FaultAt(int64_t n) const;

  SimConfig sim_;
  LightFrameConfig light_frame_;
  std::array<double, 3> lamp_rgb_;
  std::shared_ptr<SimWorld> world_;
  SimScene scene_;
  SimResponse response_;
  std::vector<Seconds> speeds_;
  bool raw_only_ = false;   // camera.format = "raw": the body returns its RAW file only
  bool capture_raw_ = false;  // Configure asked for RAW (+JPEG unless raw_only_)

  mutable std::mutex mu_;
  bool open_ = false;
  Stats stats_;
  // The radiance of the last lamp pose rendered (a bracket renders its scene once).
  bool cached_ = false;
  double cached_h_ = 0, cached_v_ = 0;
  cv::Mat cached_radiance_;
};

}  // namespace rig
