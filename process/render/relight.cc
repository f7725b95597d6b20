// Relighting: lamps summed in linear radiance, sweeps, the region check, pictures and video.
#include "process/render/relight.h"
#include "process/io/image_io.h"

#include "process/model/harmonic/fit.h"

#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>
#include <optional>
#include <system_error>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "config/atomic_file.h"
#include "config/log.h"
#include "process/io/exr_io.h"
#include "process/model/light_direction.h"
#include "process/render/exposure_render.h"

namespace rig {
namespace fs = std::filesystem;

namespace {

// ---- Everything that knows the model ------------------------------------------------------
// (the model is read through ReflectanceModel only: every family renders alike)

Vec3 DirectionOf(const ReflectanceModel& model, const RelightLamp& l) {
  if (l.direction) return *l.direction;
  return LightDirection(l.h_deg, l.v_deg, model.light_frame());
}

// Empty when the lamp is inside the sampled region, else what is wrong with it.
std::string OutsideRegion(const ReflectanceModel& model, const RelightLamp& l) {
  const RegionCheck region = model.CheckRegion(DirectionOf(model, l));
  if (region.inside) return {};
  return fmt::format(
      "lamp {} is {:.1f} deg from the nearest sampled lamp (sampling spacing {:.1f} deg): "
      "outside the sampled region",
      LampName(l), region.nearest_deg, region.spacing_deg);
}

// The sum over lamps of ρ(direction) · capture lamp radiance · colour · intensity.
cv::Mat SumOfLamps(const ReflectanceModel& model, const std::vector<RelightLamp>& lamps) {
  cv::Mat sum;
  for (const auto& l : lamps) {
    model.AddLamp(DirectionOf(model, l),
                  {l.rgb[0] * l.intensity, l.rgb[1] * l.intensity, l.rgb[2] * l.intensity}, &sum);
  }
  return sum;
}

// ---- The rest works on lamps and images only -----------------------------------------------

Status CheckLamp(const std::string& outside, const RelightRequest& request) {
  if (outside.empty()) return Ok();
  if (!request.extrapolate) {
    return MakeError(ErrorCode::kInvalidInput, "--light", "{}; --extrapolate renders it anyway",
                     outside);
  }
  const std::string message = outside + ": extrapolated";
  if (request.on_warning) {
    request.on_warning(message);
  } else {
    Log("render")->warn("{}", message);
  }
  return Ok();
}

Status WritePicture(const std::string& path, const cv::Mat& bgr8) {
  try {
    RIG_TRY(WriteImageFile(path, bgr8));
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kIo, path, "cannot write the picture: {}", e.what());
  }
  return Ok();
}

const std::map<std::string, std::string> kRadianceHeader = {
    {"rig.render", "relit radiance (linear)"}};

// The mapping of `reference` (Ward curve or linear scale) fixed into `o`.
Status FixMapping(const cv::Mat& reference, ToneMapOptions* o) {
  if (o->method == ToneMapMethod::kWard) {
    if (reference.empty() || reference.type() != CV_32FC3) {
      return MakeError(ErrorCode::kInvalidInput, "display reference", "must be CV_32FC3 radiance");
    }
    o->ward_fixed = std::make_shared<const WardMapping>(ComputeWardMappingForImage(reference, *o));
    return Ok();
  }
  if (o->method == ToneMapMethod::kLinear) {
    ToneMapReport report;
    ToneMapOptions linear = *o;
    linear.linear_scale = 0;
    RIG_TRY(ToneMap(reference, linear, &report));
    o->linear_scale = report.linear_scale;
    return Ok();
  }
  return MakeError(ErrorCode::kInvalidInput, "--tonemap",
                   "a fixed display takes ward or linear ({} adapts to every picture)",
                   ToneMapMethodName(o->method));
}

}  // namespace

Vec3 AzimuthElevationDirection(double azimuth_deg, double elevation_deg) {
  const double a = azimuth_deg * M_PI / 180, e = elevation_deg * M_PI / 180;
  return {std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)};
}

std::string LampName(const RelightLamp& l) {
  if (l.direction) {
    return fmt::format("dir={:.4g},{:.4g},{:.4g}", (*l.direction)[0], (*l.direction)[1],
                       (*l.direction)[2]);
  }
  return fmt::format("{},{}", l.h_deg, l.v_deg);
}

cv::Mat FillFlaggedPixels(const cv::Mat& radiance, const cv::Mat& valid, size_t* filled) {
  *filled = 0;
  if (valid.empty() || cv::countNonZero(valid) == static_cast<int>(valid.total())) return radiance;
  RIG_CHECK(valid.size() == radiance.size() && valid.type() == CV_8U, "valid mask shape");
  cv::Mat known;
  valid.convertTo(known, CV_32F, 1.0 / 255);
  cv::threshold(known, known, 0, 1, cv::THRESH_BINARY);
  cv::Mat value = radiance.clone();
  {
    cv::Mat known3;
    cv::merge(std::vector<cv::Mat>{known, known, known}, known3);
    value = value.mul(known3);
  }
  *filled = valid.total() - static_cast<size_t>(cv::countNonZero(valid));
  if (cv::countNonZero(valid) == 0) return value;  // nothing to fill from
  const int max_passes = std::max(radiance.rows, radiance.cols);
  for (int pass = 0; pass < max_passes; ++pass) {
    cv::Mat sum_value, sum_known;
    cv::boxFilter(value, sum_value, CV_32F, cv::Size(3, 3), cv::Point(-1, -1), false,
                  cv::BORDER_REPLICATE);
    cv::boxFilter(known, sum_known, CV_32F, cv::Size(3, 3), cv::Point(-1, -1), false,
                  cv::BORDER_REPLICATE);
    bool left = false;
    for (int y = 0; y < value.rows; ++y) {
      float* k = known.ptr<float>(y);
      const float* sk = sum_known.ptr<float>(y);
      cv::Vec3f* v = value.ptr<cv::Vec3f>(y);
      const cv::Vec3f* sv = sum_value.ptr<cv::Vec3f>(y);
      for (int x = 0; x < value.cols; ++x) {
        if (k[x] > 0) continue;
        if (sk[x] > 0) {
          v[x] = sv[x] / sk[x];
          k[x] = 1;
        } else {
          left = true;
        }
      }
    }
    if (!left) break;
  }
  return value;
}

std::vector<RelightLamp> SampleLampPath(const std::vector<RelightLamp>& path, int frames) {
  std::vector<double> cum = {0};
  for (size_t i = 1; i < path.size(); ++i)
    cum.push_back(cum.back() + std::hypot(path[i].h_deg - path[i - 1].h_deg,
                                          path[i].v_deg - path[i - 1].v_deg));
  std::vector<RelightLamp> out;
  for (int f = 0; f < frames; ++f) {
    const double s = frames == 1 ? 0 : cum.back() * f / (frames - 1);
    size_t k = 1;
    while (k + 1 < path.size() && cum[k] < s) ++k;
    const double seg = cum[k] - cum[k - 1];
    const double t = seg > 0 ? (s - cum[k - 1]) / seg : 0;
    RelightLamp l;
    l.h_deg = path[k - 1].h_deg + t * (path[k].h_deg - path[k - 1].h_deg);
    l.v_deg = path[k - 1].v_deg + t * (path[k].v_deg - path[k - 1].v_deg);
    out.push_back(l);
  }
  return out;
}

Result<RenderOutput> Relight(const ReflectanceModel& model, const RelightRequest& request) {
  // Refuse (or warn about) lamps outside the sampled region before rendering anything.
  for (const auto& l : request.lamps) RIG_TRY(CheckLamp(OutsideRegion(model, l), request));
  for (const auto& l : request.sweep) {
    const std::string outside = OutsideRegion(model, l);
    if (outside.empty()) continue;
    if (Status st = CheckLamp(outside, request); !st.ok()) return st.error().Within("--sweep");
    break;  // one warning for a sweep
  }

  RenderOutput output;
  output.tonemap = request.tonemap;
  output.sweep = request.sweep;
  output.valid = model.valid();
  if (!request.envmap.empty()) {
    if (!request.sweep.empty()) {
      return MakeError(ErrorCode::kInvalidInput, "--envmap", "an environment map renders one frame, not a sweep");
    }
    RIG_ASSIGN_OR_RETURN(EnvmapRender env, RenderEnvironment(model, request.harmonic, request.envmap,
                                                             request.envmap_options));
    output.envmap = std::move(env);
  }
  if (request.sweep.empty()) {
    cv::Mat sum = SumOfLamps(model, request.lamps);
    if (output.envmap) sum = sum.empty() ? output.envmap->radiance.clone() : sum + output.envmap->radiance;
    output.radiance.push_back(sum);
  } else {
    for (const auto& l : request.sweep) {
      std::vector<RelightLamp> set = request.lamps;
      set.push_back(l);
      output.radiance.push_back(SumOfLamps(model, set));
    }
  }
  if (request.display != RenderDisplay::kToneMap && request.display != RenderDisplay::kEncoded) {
    return output;
  }
  if (request.display_ev) {
    output.tonemap.method = ToneMapMethod::kLinear;
    output.tonemap.linear_scale = std::exp2(*request.display_ev);
    output.display_note = fmt::format("fixed display: pixel = radiance x 2^{:g}", *request.display_ev);
    return output;
  }
  if (request.display == RenderDisplay::kEncoded) return output;  // intensity already shows
  const ToneMapMethod method = request.tonemap.method;
  const bool fixable = method == ToneMapMethod::kWard || method == ToneMapMethod::kLinear;
  if (!request.display_reference.empty()) {
    RIG_TRY(FixMapping(request.display_reference, &output.tonemap));
    output.display_note = fmt::format("fixed display: the {} mapping of the reference render",
                                      ToneMapMethodName(method));
    return output;
  }
  if (!request.sweep.empty()) {
    if (!fixable) return output;
    // One mapping for the whole sweep, the brightest frame's, applied to every frame (a
    // mapping per frame would make the lamp's motion flicker): Ward's curve from that frame's
    // histogram when Ward was asked for, else its linear scale.
    size_t brightest = 0;
    double best = -1;
    for (size_t i = 0; i < output.radiance.size(); ++i) {
      const double m = cv::mean(Luminance(output.radiance[i]))[0];
      if (m > best) best = m, brightest = i;
    }
    if (method == ToneMapMethod::kWard) {
      RIG_TRY(FixMapping(output.radiance[brightest], &output.tonemap));
      output.display_note = "one Ward mapping for the sweep (its brightest frame's histogram)";
      return output;
    }
    ToneMapReport report;
    ToneMapOptions linear = request.tonemap;
    linear.method = ToneMapMethod::kLinear;
    RIG_TRY(ToneMap(output.radiance[brightest], linear, &report));
    output.tonemap = linear;
    output.tonemap.linear_scale = report.linear_scale;
    output.display_note = "one linear scale for the sweep (its brightest frame's)";
    return output;
  }
  bool unit = true;
  for (const auto& l : request.lamps) unit = unit && l.intensity == 1;
  const double env_intensity = request.envmap_options.intensity;
  if (output.envmap) unit = unit && env_intensity == 1;
  if (fixable && !unit) {
    // The display the same lamps at intensity 1 get: intensity changes the picture.
    std::vector<RelightLamp> ones = request.lamps;
    for (auto& l : ones) l.intensity = 1;
    cv::Mat reference = SumOfLamps(model, ones);
    if (output.envmap && env_intensity > 0) {
      cv::Mat env = output.envmap->radiance / env_intensity;
      reference = reference.empty() ? env : reference + env;
    }
    if (reference.empty()) return output;
    RIG_TRY(FixMapping(reference, &output.tonemap));
    output.display_note = "mapped as the same lamps at intensity 1";
  }
  return output;
}

Result<cv::Mat> RenderPicture(const cv::Mat& radiance, const RelightRequest& request,
                              const ToneMapOptions& tonemap) {
  if (request.display == RenderDisplay::kExposure) {
    return RenderExposure(radiance, request.exposure_s, request.log_exposure);
  }
  if (request.display == RenderDisplay::kEncoded) {
    const float scale = request.display_ev ? static_cast<float>(std::exp2(*request.display_ev)) : 1.0f;
    cv::Mat out(radiance.size(), CV_8UC3);
    for (int y = 0; y < radiance.rows; ++y) {
      const float* r = radiance.ptr<float>(y);
      uint8_t* o = out.ptr<uint8_t>(y);
      for (int x = 0; x < radiance.cols * 3; ++x)
        o[x] = static_cast<uint8_t>(
            std::clamp(std::nearbyint(SrgbEncode(scale * r[x]) * 255.0f), 0.0f, 255.0f));
    }
    return out;
  }
  return ToneMap(radiance, tonemap);
}

RenderFileKind RenderFileKindOf(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".exr") return RenderFileKind::kExr;
  if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff") return RenderFileKind::kPicture;
  if (ext == ".avi") return RenderFileKind::kVideo;
  return RenderFileKind::kUnknown;
}

std::string SweepFrameDir(const std::string& out) {
  const fs::path p(out);
  return (RenderFileKindOf(out) == RenderFileKind::kVideo ? fs::path(p).replace_extension("")
                                                          : p.parent_path() / p.stem())
      .string();
}

Result<RenderFiles> WriteRender(const RenderOutput& output, const RelightRequest& request,
                                const std::string& out, double fps) {
  const RenderFileKind kind = RenderFileKindOf(out);
  const bool to_exr = kind == RenderFileKind::kExr;
  RenderFiles files;
  files.out = out;
  if (output.sweep.empty()) {
    if (output.radiance.size() != 1) {
      return MakeError(ErrorCode::kInvalidInput, out, "a render without a sweep has one frame");
    }
    if (to_exr) {
      RIG_TRY(WriteRgbExr(out, output.radiance[0], kRadianceHeader));
    } else {
      const cv::Mat filled = FillFlaggedPixels(output.radiance[0], output.valid, &files.filled_pixels);
      RIG_ASSIGN_OR_RETURN(cv::Mat pic, RenderPicture(filled, request, output.tonemap));
      RIG_TRY(WritePicture(out, pic));
    }
    files.frames = 1;
    return files;
  }

  files.video = kind == RenderFileKind::kVideo;
  files.frame_dir = SweepFrameDir(out);
  std::error_code ec;
  if (fs::exists(files.frame_dir)) {
    return MakeError(ErrorCode::kInvalidInput, files.frame_dir,
                     "exists; choose another --out (nothing is overwritten)");
  }
  fs::create_directories(files.frame_dir, ec);
  if (ec) return MakeError(ErrorCode::kIo, files.frame_dir, "{}", ec.message());
  cv::VideoWriter video;
  // OpenCV opens the video by name: written in a private folder, then moved over --out.
  std::optional<StagedFile> staged;
  if (files.video) {
    RIG_ASSIGN_OR_RETURN(StagedFile s, StagedFile::Begin(out));
    staged.emplace(std::move(s));
  }
  for (size_t i = 0; i < output.radiance.size(); ++i) {
    const fs::path frame =
        fs::path(files.frame_dir) / fmt::format("frame_{:04d}{}", i, to_exr ? ".exr" : ".png");
    Status st;
    if (to_exr) {
      st = WriteRgbExr(frame.string(), output.radiance[i], kRadianceHeader);
    } else {
      const cv::Mat filled = FillFlaggedPixels(output.radiance[i], output.valid, &files.filled_pixels);
      auto pic = RenderPicture(filled, request, output.tonemap);
      if (!pic.ok()) return pic.error().Within(frame.string());
      st = WritePicture(frame.string(), *pic);
      if (st.ok() && files.video) {
        try {
          if (!video.isOpened()) {
            video.open(staged->file().string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps, pic->size());
            if (!video.isOpened()) st = MakeError(ErrorCode::kIo, out, "cannot open a Motion JPEG video writer");
          }
          if (st.ok()) video.write(*pic);
        } catch (const cv::Exception& e) {
          st = MakeError(ErrorCode::kIo, out, "video: {}", e.what());
        }
      }
    }
    if (!st.ok()) return st.error();
    ++files.frames;
  }
  video.release();
  if (staged) RIG_TRY(staged->Publish());
  return files;
}

}  // namespace rig
