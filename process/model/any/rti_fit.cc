// Reading a multi-light capture and fitting a model family to it.
#include "process/model/any/rti_fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <thread>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "process/io/jpeg_io.h"
#include "process/model/holdout.h"
#include "process/model/harmonic/model.h"
#include "config/console.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string Lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// One image as 8-bit B, G, R.
Result<cv::Mat> ReadCaptureImage(const std::string& path, const std::string& where) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    return MakeError(ErrorCode::kNotFound, where, "image '{}' is not there", path);
  }
  const std::string ext = Lower(fs::path(path).extension().string());
  if (ext == ".jpg" || ext == ".jpeg") {
    auto rgb = ReadJpeg(path);
    if (!rgb.ok()) return MakeError(rgb.error().code, where, "{}", rgb.error().ToString());
    if (rgb->channels() != 3) {
      return MakeError(ErrorCode::kInvalidInput, where, "image '{}' has {} channels, 3 needed",
                       path, rgb->channels());
    }
    cv::Mat bgr;
    cv::cvtColor(*rgb, bgr, cv::COLOR_RGB2BGR);
    return bgr;
  }
  cv::Mat img;
  try {
    img = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kInvalidInput, where, "cannot read '{}': {}", path, e.what());
  }
  if (img.empty()) return MakeError(ErrorCode::kInvalidInput, where, "cannot read '{}'", path);
  if (img.depth() != CV_8U || (img.channels() != 3 && img.channels() != 4)) {
    return MakeError(ErrorCode::kInvalidInput, where,
                     "image '{}' is not 8-bit colour (depth {}, {} channels)", path, img.depth(),
                     img.channels());
  }
  if (img.channels() == 4) cv::cvtColor(img, img, cv::COLOR_BGRA2BGR);
  return img;
}

Result<std::unique_ptr<ReflectanceModel>> FitHarmonic(const RtiCapture& cap,
                                                      const RtiFitRequest& req,
                                                      std::string* summary, std::string* report,
                                                      double* seconds) {
  FitOptions o = req.harmonic;
  RIG_ASSIGN_OR_RETURN(o.basis, ParseBasisKind(req.family));
  FitInput input;
  const LightSamples& s = cap.samples;
  const int lights = s.lights();
  const size_t pixels = s.pixels();
  for (int l = 0; l < lights; ++l) {
    cv::Mat rad(s.height, s.width, CV_32FC3);
    cv::Mat valid(s.height, s.width, CV_8U);
    float* r = rad.ptr<float>();
    uint8_t* v = valid.ptr<uint8_t>();
    for (size_t p = 0; p < pixels; ++p) {
      bool ok = true;
      for (int c = 0; c < 3; ++c) {
        const float code = s.value(p, l, c) / 255.0f;
        r[p * 3 + (2 - c)] = req.linear ? code : SrgbDecode(code);
        ok = ok && s.is_usable(p, l, c);
      }
      v[p] = ok ? 1 : 0;
    }
    input.radiance.push_back(rad);
    input.valid.push_back(valid);
    input.directions.push_back(s.directions[l]);
  }
  input.weights = UniformHemisphereWeights(input.directions.size());
  RIG_ASSIGN_OR_RETURN(FitOutput fitted, FitModel(input, o));
  // Photographs' codes (sRGB unless told linear): pictures reproduce them by default.
  fitted.model.info().source_encoding = req.linear ? ValueEncoding::kLinear : ValueEncoding::kSrgb;
  fitted.model.info().near_lamp = req.near_lamp;
  *seconds = fitted.fit_time_s;
  const Model& m = fitted.model;
  *summary = fmt::format("{} order {} ({} terms per channel), {} in {} space, {} pixels flagged",
                         m.basis().name(), m.basis().order(), m.basis().size(),
                         FitMethodName(o.method), FitSpaceName(o.transform.space),
                         m.info().flagged_pixels);
  *report += FitReportMarkdown(fitted, o);
  return WrapHarmonic(std::move(fitted.model));
}

}  // namespace

Result<RtiCapture> LoadRtiCapture(const std::string& lp, int downsample,
                                  const LdrMaskThresholds& thresholds) {
  const auto t0 = Clock::now();
  RtiCapture cap;
  cap.lp = lp;
  RIG_ASSIGN_OR_RETURN(cap.entries, ReadLp(lp));
  std::vector<cv::Mat> images;
  std::vector<Vec3> lights;
  // Decoded on two threads (each image on its own); errors reported in .lp order.
  const size_t n = cap.entries.size();
  std::vector<Result<cv::Mat>> decoded(n, MakeError(ErrorCode::kInternal, lp, "not read"));
  ProgressTask task("reading images", static_cast<int64_t>(n));
  auto decode = [&](size_t first) {
    for (size_t i = first; i < n; i += 2) {
      decoded[i] = ReadCaptureImage(cap.entries[i].image,
                                    fmt::format("{}:{}", lp, cap.entries[i].line));
      task.Advance(1);
    }
  };
  std::thread second(decode, 1);
  decode(0);
  second.join();
  for (size_t i = 0; i < n; ++i) {
    const LpEntry& e = cap.entries[i];
    const std::string where = fmt::format("{}:{}", lp, e.line);
    if (!decoded[i].ok()) return decoded[i].error();
    cv::Mat img = std::move(*decoded[i]);
    if (downsample > 1) {
      if (img.cols < downsample || img.rows < downsample) {
        return MakeError(ErrorCode::kInvalidInput, where,
                         "image '{}' ({}x{}) is smaller than --downsample {}", e.image, img.cols,
                         img.rows, downsample);
      }
      cv::Mat small;
      cv::resize(img, small, cv::Size(img.cols / downsample, img.rows / downsample), 0, 0,
                 cv::INTER_AREA);
      img = small;
    }
    if (!images.empty() && img.size() != images[0].size()) {
      return MakeError(ErrorCode::kInvalidInput, where,
                       "image '{}' is {}x{}, the first image is {}x{}", e.image, img.cols,
                       img.rows, images[0].cols, images[0].rows);
    }
    images.push_back(img);
    lights.push_back(e.direction);
  }
  cap.samples = SamplesFromImages(images, lights);
  cap.masked_samples = MaskLdrSamples(&cap.samples, thresholds);
  cap.masked_fraction = static_cast<double>(cap.masked_samples) /
                        static_cast<double>(std::max<size_t>(1, cap.samples.values.size()));
  const size_t row = static_cast<size_t>(cap.samples.lights()) * 3;
  size_t with = 0;
  for (size_t p = 0; p < cap.samples.pixels(); ++p) {
    const uint8_t* u = cap.samples.usable.data() + p * row;
    if (std::find(u, u + row, 0) != u + row) ++with;
  }
  cap.pixels_with_masked = static_cast<double>(with) /
                           static_cast<double>(std::max<size_t>(1, cap.samples.pixels()));
  cap.load_time_s = std::chrono::duration<double>(Clock::now() - t0).count();
  return cap;
}

std::vector<int> LightsBelowHorizon(const RtiCapture& capture) {
  std::vector<int> out;
  for (const auto& e : capture.entries)
    if (!(e.direction[2] > 0)) out.push_back(e.line);
  return out;
}

std::string RtiReportHeader(const RtiCapture& cap, const RtiFitRequest& req) {
  return fmt::format(
      "# Model of {}\n\n{} images {}x{}; masked (at or below {} or at or above {} in any "
      "channel, per channel): {} sample-channels, {:.1f}% of all, in {:.1f}% of pixels\n\n",
      cap.lp, cap.samples.lights(), cap.samples.width, cap.samples.height,
      req.choice.base.thresholds.black_max, req.choice.base.thresholds.clipped_min,
      cap.masked_samples, 100 * cap.masked_fraction, 100 * cap.pixels_with_masked);
}

Result<RtiFitResult> FitRti(const RtiCapture& cap, const RtiFitRequest& req) {
  RtiFitResult out;
  out.family = req.family;
  const bool hemispherical = req.family == "auto" || req.family == "pca" || req.family == "hsh";
  if (hemispherical) {
    const auto below = LightsBelowHorizon(cap);
    if (!below.empty()) {
      return MakeError(ErrorCode::kInvalidInput, fmt::format("{}:{}", cap.lp, below[0]),
                       "{} light(s) at or below the horizon (z <= 0); the {} model covers the "
                       "upper hemisphere only — remove them, or fit sh or ptm",
                       below.size(), req.family == "hsh" ? "hsh" : "pca");
    }
  }
  out.report = RtiReportHeader(cap, req);
  if (req.family == "auto" || req.family == "pca") {
    PcaChoiceOptions co = req.choice;
    if (req.components > 0) co.components = {req.components};
    if (req.grid_resolution > 0) co.resolutions = {req.grid_resolution};
    if (req.jpeg_quality > 0) co.qualities = {req.jpeg_quality};
    RIG_ASSIGN_OR_RETURN(PcaAutoFit fit, FitPcaAuto(cap.samples, nullptr, co));
    out.fit_time_s = fit.stats.time_s;
    out.family = "pca-bilinear";
    out.summary = fmt::format("pca-bilinear, {}", fit.choice.reason);
    out.report += fmt::format(
        "## Choice\n\n{}.\n\nSamples fitted around: {} sample-channels ({} pixels solved "
        "around them, mask {}).\n\n",
        fit.choice.reason, fit.stats.masked_samples, fit.stats.refitted_pixels,
        PcaMaskModeName(co.base.mask));
    out.report += PcaChoiceMarkdown(fit.choice);
    fit.model.set_near_lamp(req.near_lamp);
    out.model = WrapPca(std::move(fit.model));
    return out;
  }
  if (req.family == "sh" || req.family == "hsh" || req.family == "ptm") {
    RIG_ASSIGN_OR_RETURN(out.model,
                         FitHarmonic(cap, req, &out.summary, &out.report, &out.fit_time_s));
    return out;
  }
  return MakeError(ErrorCode::kInvalidInput, "--basis",
                   "'{}' is not a family (auto, pca, sh, hsh, ptm)", req.family);
}

}  // namespace rig
