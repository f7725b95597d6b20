// The simulated camera: response curves, the sensor model, encoding, faults and latency.
#include "sim/sim_camera.h"
#include "sim/dng_writer.h"

#include <algorithm>
#include <limits>
#include <thread>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/plan/bracket.h"
#include "config/log.h"

namespace rig {
namespace {

constexpr const char* kCameraDevice = "sim camera";

// Hable's filmic curve ("Uncharted 2"): a toe, a linear part and a shoulder.
double Hable(double x) {
  constexpr double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
  return ((x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F)) - E / F;
}

uint64_t SplitMix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// Acklam's rational approximation of the standard normal quantile (relative error 1e-9).
double NormalQuantile(double p) {
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  const double lo = 0.02425;
  if (p < lo || p > 1 - lo) {
    double q = std::sqrt(-2 * std::log(p < lo ? p : 1 - p));
    double x = (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
               ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
    return p < lo ? x : -x;
  }
  double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

// 65536 standard normal samples at the quantiles (k + 0.5) / 65536: a 16-bit random index
// gives a normal deviate (tails cut at 4.3 sigma) far faster than std::normal_distribution,
// and identically on every platform.
const std::array<float, 65536>& NormalTable() {
  static const std::array<float, 65536> table = [] {
    std::array<float, 65536> t{};
    for (int k = 0; k < 65536; ++k) t[k] = static_cast<float>(NormalQuantile((k + 0.5) / 65536));
    return t;
  }();
  return table;
}

Error DeviceError(ErrorCode code, const std::string& message) {
  return Error{code, message, kCameraDevice};
}

}  // namespace

// ---------------------------------------------------------------------------------------
// SimResponse

Result<SimResponse> SimResponse::Create(const SimCameraConfig& camera) {
  if (camera.response != "filmic" && camera.response != "gamma" && camera.response != "linear")
    return MakeError(ErrorCode::kInvalidInput, "sim.camera.response",
                     "unknown response '{}' (filmic, gamma or linear)", camera.response);
  if (!(camera.gain > 0) || !(camera.full_well > 0))
    return MakeError(ErrorCode::kInvalidInput, "sim.camera", "gain and full_well must be positive");
  SimResponse r;
  r.kind_ = camera.response;
  for (int c = 0; c < 3; ++c) {
    r.gamma_[c] = camera.response_gamma_rgb[2 - c];
    if (!(r.gamma_[c] > 0))
      return MakeError(ErrorCode::kInvalidInput, "sim.camera.response_gamma_rgb",
                       "gammas must be positive");
  }
  r.white_ = {9.0, 13.0, 11.2};
  r.saturation_exposure_ = camera.full_well / camera.gain;
  r.Build();
  return r;
}

double SimResponse::Encode(int c, double x) const {
  x = std::clamp(x, 0.0, 1.0);
  if (kind_ == "linear") return x;
  if (kind_ == "gamma") return std::pow(x, 1.0 / gamma_[c]);
  double y = Hable(white_[c] * x) / Hable(white_[c]);
  return std::pow(std::clamp(y, 0.0, 1.0), 1.0 / gamma_[c]);
}

double SimResponse::Decode(int c, double y) const {
  y = std::clamp(y, 0.0, 1.0);
  if (kind_ == "linear") return y;
  if (kind_ == "gamma") return std::pow(y, gamma_[c]);
  // The filmic curve is strictly increasing on [0, 1]: bisect to double precision.
  double lo = 0, hi = 1;
  for (int k = 0; k < 200 && hi - lo > 0; ++k) {
    double mid = 0.5 * (lo + hi);
    if (mid == lo || mid == hi) break;
    (Encode(c, mid) < y ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

void SimResponse::Build() {
  for (int c = 0; c < 3; ++c) {
    for (int z = 0; z < 255; ++z) thresholds_[c][z] = static_cast<float>(Decode(c, (z + 0.5) / 255));
    // The float thresholds are what Quantize compares against, so they define the bins.
    g_[c][0] = std::log(saturation_exposure_ * 0.5 * thresholds_[c][0]);
    for (int z = 1; z < 255; ++z) g_[c][z] = std::log(saturation_exposure_ * Decode(c, z / 255.0));
    g_[c][255] = std::log(saturation_exposure_);
    int z = 0;
    for (int i = 0; i <= kLutMax + 1; ++i) {
      double x = std::min(1.0, static_cast<double>(i) / kLutMax);
      x *= x;
      while (z < 255 && static_cast<float>(x) >= thresholds_[c][z]) ++z;
      // The cell starts at x; a level at its start never exceeds the level of any x inside.
      lut_[c][i] = static_cast<uint8_t>(z);
    }
  }
}

double SimResponse::LogExposureLow(int c, int z) const {
  if (z <= 0) return -std::numeric_limits<double>::infinity();
  return std::log(saturation_exposure_ * static_cast<double>(thresholds_[c][z - 1]));
}

double SimResponse::LogExposureHigh(int c, int z) const {
  if (z >= 255) return std::numeric_limits<double>::infinity();
  return std::log(saturation_exposure_ * static_cast<double>(thresholds_[c][z]));
}

nlohmann::json SimResponse::ToJson() const {
  return {{"kind", kind_},
          {"channels", "B, G, R"},
          {"gamma_bgr", {gamma_[0], gamma_[1], gamma_[2]}},
          {"white_bgr", {white_[0], white_[1], white_[2]}},
          {"saturation_exposure", saturation_exposure_},
          {"curve",
           "x = clamp(radiance * seconds / saturation_exposure, 0, 1); level = round(255 f(x)); "
           "filmic f = (hable(W x) / hable(W))^(1/gamma), hable(x) = (x(Ax+CB)+DE)/(x(Ax+B)+DF) "
           "- E/F, A=0.15 B=0.5 C=0.1 D=0.2 E=0.02 F=0.3; gamma f = x^(1/gamma); linear f = x"}};
}

Result<SimResponse> SimResponse::FromJson(const nlohmann::json& j) {
  try {
    SimResponse r;
    r.kind_ = j.at("kind").get<std::string>();
    if (r.kind_ != "filmic" && r.kind_ != "gamma" && r.kind_ != "linear")
      return MakeError(ErrorCode::kCorrupt, "response", "unknown response kind '{}'", r.kind_);
    for (int c = 0; c < 3; ++c) {
      r.gamma_[c] = j.at("gamma_bgr").at(c).get<double>();
      r.white_[c] = j.at("white_bgr").at(c).get<double>();
    }
    r.saturation_exposure_ = j.at("saturation_exposure").get<double>();
    if (!(r.saturation_exposure_ > 0))
      return MakeError(ErrorCode::kCorrupt, "response", "saturation_exposure must be positive");
    r.Build();
    return r;
  } catch (const nlohmann::json::exception& e) {
    return MakeError(ErrorCode::kCorrupt, "response", "{}", e.what());
  }
}

// ---------------------------------------------------------------------------------------
// SimCamera

Result<std::unique_ptr<SimCamera>> SimCamera::Create(const Config& config,
                                                     std::shared_ptr<SimWorld> world) {
  RIG_CHECK(world != nullptr, "SimCamera needs a world");
  RIG_ASSIGN_OR_RETURN(SimScene scene, SimScene::Create(config.sim));
  RIG_ASSIGN_OR_RETURN(SimResponse response, SimResponse::Create(config.sim.camera));
  if (config.sim.camera.format != "jpg" && config.sim.camera.format != "png")
    return MakeError(ErrorCode::kInvalidInput, "sim.camera.format",
                     "unknown format '{}' (jpg or png)", config.sim.camera.format);
  auto* cam = new SimCamera(config, std::move(world), std::move(scene), std::move(response));
  if (cam->speeds_.empty()) {
    delete cam;
    return MakeError(ErrorCode::kInvalidInput, "sim.camera",
                     "no third-stop shutter speed between shutter_min_s and shutter_max_s");
  }
  return std::unique_ptr<SimCamera>(cam);
}

SimCamera::SimCamera(const Config& config, std::shared_ptr<SimWorld> world, SimScene scene,
                     SimResponse response)
    : sim_(config.sim),
      light_frame_(config.light_frame),
      lamp_rgb_(config.lamp.radiance_rgb),
      world_(std::move(world)),
      scene_(std::move(scene)),
      response_(std::move(response)),
      speeds_(ThirdStopShutterSpeeds(Seconds(config.sim.camera.shutter_min_s),
                                     Seconds(config.sim.camera.shutter_max_s))),
      raw_only_(config.camera.format == "raw"),
      capture_raw_(raw_only_) {}

std::string SimCamera::Describe() const {
  return fmt::format("sim camera {}x{} scene {} seed {} response {} {}", sim_.width, sim_.height,
                     sim_.scene, sim_.seed, sim_.camera.response, sim_.camera.format);
}

Status SimCamera::Open() {
  std::lock_guard<std::mutex> lock(mu_);
  open_ = true;
  return Ok();
}

void SimCamera::Close() {
  std::lock_guard<std::mutex> lock(mu_);
  open_ = false;
}

Result<std::vector<Seconds>> SimCamera::ShutterSpeeds() { return speeds_; }

Result<CameraSettings> SimCamera::Configure(const CameraSettings& wanted) {
  CameraSettings applied = wanted;
  applied.iso = "100";
  applied.aperture = "8";
  applied.white_balance = "Daylight";
  applied.capture_raw = wanted.capture_raw || raw_only_;
  std::lock_guard<std::mutex> lock(mu_);
  capture_raw_ = applied.capture_raw;
  return applied;
}

std::optional<Error> SimCamera::FaultAt(int64_t n) const {
  const auto& k = sim_.camera;
  if (k.fail_forever_after > 0 && n >= k.fail_forever_after)
    return DeviceError(ErrorCode::kDevice,
                       fmt::format("capture {} failed: the body does not respond any more "
                                   "(simulated fault from capture {} on)", n, k.fail_forever_after));
  if (k.disconnect_at > 0 && n >= k.disconnect_at && n < k.disconnect_at + k.disconnect_captures)
    return DeviceError(ErrorCode::kDevice,
                       fmt::format("capture {} failed: disconnected (simulated, captures {} .. {})",
                                   n, k.disconnect_at, k.disconnect_at + k.disconnect_captures - 1));
  if (std::find(k.fail_capture_at.begin(), k.fail_capture_at.end(), n) != k.fail_capture_at.end())
    return DeviceError(ErrorCode::kDevice,
                       fmt::format("capture {} failed (simulated fault)", n));
  if (k.fail_capture_every > 0 && n % k.fail_capture_every == 0)
    return DeviceError(ErrorCode::kTimeout,
                       fmt::format("capture {} timed out (simulated fault every {} captures)", n,
                                   k.fail_capture_every));
  return std::nullopt;
}

cv::Mat SimCamera::Expose(const cv::Mat& radiance, Seconds exposure, uint64_t noise_seed,
                          cv::Mat* raw_dn) const {
  RIG_CHECK(radiance.type() == CV_32FC3, "radiance must be CV_32FC3");
  cv::Mat out(radiance.rows, radiance.cols, CV_8UC3);
  const auto& k = sim_.camera;
  const float to_e = static_cast<float>(exposure.count() * k.gain);
  const float inv_fw = static_cast<float>(1.0 / k.full_well);
  const bool shot = k.shot_noise;
  const float read_var = static_cast<float>(k.read_noise_e * k.read_noise_e);
  const bool noisy = shot || read_var > 0;
  const float inv_e_per_dn = static_cast<float>(1.0 / RawElectronsPerDn());
  if (raw_dn) raw_dn->create(radiance.rows, radiance.cols, CV_16UC3);
  const auto& normal = NormalTable();
  uint64_t state = SplitMix(noise_seed);
  uint64_t bits = 0;
  int left = 0;
  for (int j = 0; j < radiance.rows; ++j) {
    const float* in = radiance.ptr<float>(j);
    uint8_t* o = out.ptr<uint8_t>(j);
    uint16_t* raw = raw_dn ? raw_dn->ptr<uint16_t>(j) : nullptr;
    for (int i = 0; i < 3 * radiance.cols; ++i) {
      float e = in[i] * to_e;
      if (noisy) {
        if (left == 0) {
          state += 0x9e3779b97f4a7c15ull;
          bits = SplitMix(state);
          left = 4;
        }
        const float n = normal[bits & 0xffff];
        bits >>= 16;
        --left;
        e += std::sqrt((shot ? std::max(e, 0.f) : 0.f) + read_var) * n;
      }
      o[i] = response_.Quantize(i % 3, e * inv_fw);
      if (raw) raw[i] = static_cast<uint16_t>(std::clamp(std::lround(e * inv_e_per_dn) + kRawBlack,
                                                         0L, long(kRawWhite)));
    }
  }
  return out;
}

Result<std::vector<uint8_t>> SimCamera::EncodeRaw(const cv::Mat& raw_dn, Seconds exposure) const {
  DngOptions o;
  o.mosaic = false;  // LinearRaw: see Configure() in sim_camera.h
  o.black = kRawBlack;
  o.white = kRawWhite;
  o.exposure_s = exposure.count();
  o.model = "rig simulator";
  auto bytes = EncodeDng(raw_dn, o);
  if (!bytes.ok()) return DeviceError(ErrorCode::kInternal, "RAW encoding failed: " + bytes.error().ToString());
  return bytes;
}

Result<std::vector<uint8_t>> SimCamera::Encode(const cv::Mat& bgr8) const {
  std::vector<uint8_t> bytes;
  try {
    if (sim_.camera.format == "png") {
      cv::imencode(".png", bgr8, bytes, {cv::IMWRITE_PNG_COMPRESSION, 1});
    } else {
      cv::imencode(".jpg", bgr8, bytes, {cv::IMWRITE_JPEG_QUALITY, sim_.camera.jpeg_quality});
    }
  } catch (const cv::Exception& e) {
    return DeviceError(ErrorCode::kInternal, std::string("encoding failed: ") + e.what());
  }
  return bytes;
}

Result<CapturedFrame> SimCamera::Capture(Seconds exposure) {
  const auto start = std::chrono::steady_clock::now();
  std::lock_guard<std::mutex> lock(mu_);
  auto offered = std::find_if(speeds_.begin(), speeds_.end(), [&](Seconds s) {
    return std::fabs(s.count() - exposure.count()) <= 1e-9 * s.count();
  });
  if (offered == speeds_.end())
    return DeviceError(ErrorCode::kInvalidInput,
                       fmt::format("exposure {:.6g} s is not a shutter speed this body offers "
                                   "(third stops from {:.6g} s to {:.6g} s)",
                                   exposure.count(), speeds_.front().count(),
                                   speeds_.back().count()));
  if (!open_) return DeviceError(ErrorCode::kDevice, "capture before Open()");
  const Seconds t = *offered;
  const int64_t n = ++stats_.attempts;
  if (auto fault = FaultAt(n)) {
    ++stats_.faults;
    return *fault;
  }

  const SimWorldState state = world_->RecordCapture();
  if (state.moving || !state.lamp_on || !state.lamp_ready)
    Log("sim")->warn("capture {} while {}", n,
                     state.moving ? "the arm moves" : (!state.lamp_on ? "the lamp is off"
                                                                      : "the lamp warms up"));
  cv::Mat radiance;
  if (!state.lamp_on) {
    radiance = cv::Mat::zeros(scene_.height(), scene_.width(), CV_32FC3);
  } else {
    if (!cached_ || cached_h_ != state.h_deg || cached_v_ != state.v_deg) {
      cached_radiance_ =
          scene_.Radiance(LightDirection(state.h_deg, state.v_deg, light_frame_), lamp_rgb_);
      cached_ = true;
      cached_h_ = state.h_deg;
      cached_v_ = state.v_deg;
    }
    radiance = cached_radiance_;
  }
  // The noise of a frame depends on (seed, pose, exposure) only, never on how many captures
  // this process made: a killed and resumed dry run stores the same bytes as an uninterrupted
  // one.
  const auto micro = [](double deg) { return static_cast<uint64_t>(std::llround(deg * 1e6)); };
  const uint64_t speed_index = static_cast<uint64_t>(offered - speeds_.begin());
  const uint64_t noise_seed =
      SplitMix(SplitMix(SplitMix(static_cast<uint64_t>(sim_.seed)) ^ micro(state.h_deg)) ^ micro(state.v_deg)) ^
      speed_index;
  cv::Mat raw_dn;
  cv::Mat image = Expose(radiance, t, noise_seed, capture_raw_ ? &raw_dn : nullptr);
  std::vector<uint8_t> bytes, raw_bytes;
  if (!raw_only_) {
    RIG_ASSIGN_OR_RETURN(bytes, Encode(image));
  }
  if (capture_raw_) {
    RIG_ASSIGN_OR_RETURN(raw_bytes, EncodeRaw(raw_dn, t));
  }

  if (sim_.latency_scale > 0) {
    const Seconds wait = (t + Seconds(sim_.camera.download_time_s)) * sim_.latency_scale;
    std::this_thread::sleep_until(start +
                                  std::chrono::duration_cast<std::chrono::nanoseconds>(wait));
  }
  ++stats_.captures;
  stats_.exposure_time += t;
  stats_.download_time += Seconds(sim_.camera.download_time_s);

  CapturedFrame frame;
  frame.exposure = t;
  frame.exif_exposure = t;
  if (!raw_only_) frame.files.push_back({sim_.camera.format, std::move(bytes)});
  if (capture_raw_) frame.files.push_back({"dng", std::move(raw_bytes)});
  return frame;
}

Result<CapturedFile> SimCamera::CapturePreview() {
  std::lock_guard<std::mutex> lock(mu_);
  if (!open_) return DeviceError(ErrorCode::kDevice, "preview before Open()");
  const SimWorldState state = world_->State();
  cv::Mat radiance = state.lamp_on ? scene_.Radiance(LightDirection(state.h_deg, state.v_deg, light_frame_), lamp_rgb_)
                                   : cv::Mat::zeros(scene_.height(), scene_.width(), CV_32FC3);
  // Auto exposure on the brightest channel's 99th percentile.
  std::vector<float> brightest(radiance.total());
  const auto* px = radiance.ptr<cv::Vec3f>();
  for (size_t i = 0; i < brightest.size(); ++i)
    brightest[i] = std::max({px[i][0], px[i][1], px[i][2]});
  auto p99 = brightest.begin() + static_cast<std::ptrdiff_t>(brightest.size() * 99 / 100);
  std::nth_element(brightest.begin(), p99, brightest.end());
  Seconds t = speeds_.back();
  if (*p99 > 0) {
    const double want = 0.8 * sim_.camera.full_well / (sim_.camera.gain * *p99);
    t = std::clamp(Seconds(want), speeds_.front(), speeds_.back());
  }
  const auto micro = [](double deg) { return static_cast<uint64_t>(std::llround(deg * 1e6)); };
  const uint64_t noise_seed =
      SplitMix(SplitMix(SplitMix(static_cast<uint64_t>(sim_.seed) ^ 0x9e3779b97f4a7c15ull) ^ micro(state.h_deg)) ^
               micro(state.v_deg));
  cv::Mat image = Expose(radiance, t, noise_seed);
  const int long_side = std::max(image.cols, image.rows);
  if (long_side > kPreviewLongSide) {
    const double f = static_cast<double>(kPreviewLongSide) / long_side;
    cv::Mat small;
    cv::resize(image, small, cv::Size(), f, f, cv::INTER_AREA);
    image = small;
  }
  CapturedFile file{"jpg", {}};
  try {
    cv::imencode(".jpg", image, file.bytes, {cv::IMWRITE_JPEG_QUALITY, 85});
  } catch (const cv::Exception& e) {
    return DeviceError(ErrorCode::kInternal, std::string("preview encoding failed: ") + e.what());
  }
  return file;
}

SimCamera::Stats SimCamera::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

}  // namespace rig
