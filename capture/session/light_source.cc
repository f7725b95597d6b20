// Loading the capture of a light command.
#include "capture/session/light_source.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>

#include "capture/plan/pose.h"
#include "process/export/load_any.h"
#include "process/io/image_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/lp.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace rig {
namespace {

namespace fs = std::filesystem;

Result<LightSource> FromSession(const std::string& dir) {
  RIG_ASSIGN_OR_RETURN(Config config, LoadConfigOrError((fs::path(dir) / "session.toml").string()));
  std::vector<std::string> paths, names;
  std::vector<double> h, v;
  const fs::path hdr = fs::path(dir) / "hdr";
  std::error_code ec;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(hdr, ec))
    if (e.path().extension() == ".exr") files.push_back(e.path());
  if (ec || files.empty())
    return MakeError(ErrorCode::kInvalidInput, hdr.string(),
                     "the session has no radiance maps (run rig process first)");
  std::sort(files.begin(), files.end());
  for (const auto& f : files) {
    auto pose = ParsePoseName(f.stem().string());
    if (!pose.ok()) continue;
    paths.push_back(f.string());
    names.push_back(f.stem().string());
    h.push_back(pose->h_deg);
    v.push_back(pose->v_deg);
  }
  RIG_ASSIGN_OR_RETURN(LightStack stack,
                       LoadRadianceStack(paths, names, h, v, config.light_frame));
  LightSource s{"session", dir, std::move(stack), config, {}};
  // frames/<pose>/<i>_<exposure>.jpg: the camera's originals, their EXIF as the body wrote it.
  std::vector<fs::path> poses;
  for (const auto& e : fs::directory_iterator(fs::path(dir) / "frames", ec))
    if (e.is_directory()) poses.push_back(e.path());
  std::sort(poses.begin(), poses.end());
  for (const auto& p : poses) {
    std::vector<fs::path> jpegs;
    for (const auto& e : fs::directory_iterator(p, ec)) {
      std::string ext = e.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
      if (ext == ".jpg" || ext == ".jpeg") jpegs.push_back(e.path());
    }
    if (jpegs.empty()) continue;
    s.first_photo = std::min_element(jpegs.begin(), jpegs.end())->string();
    break;
  }
  return s;
}

Result<LightSource> FromImages(const std::string& dir, int downsample) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".tif" || ext == ".tiff")
      files.push_back(e.path());
  }
  if (ec) return MakeError(ErrorCode::kInvalidInput, dir, "cannot list the folder: {}", ec.message());
  if (files.size() < 3)
    return MakeError(ErrorCode::kInvalidInput, dir, "holds {} images (JPEG, PNG, TIFF); at least 3 needed",
                     files.size());
  std::sort(files.begin(), files.end());
  LightStack s;
  for (const auto& f : files) {
    RIG_ASSIGN_OR_RETURN(cv::Mat img, DecodeImage(f.string()));
    if (img.depth() != CV_8U)
      return MakeError(ErrorCode::kInvalidInput, f.string(), "is not an 8-bit image");
    if (downsample > 1)
      cv::resize(img, img, cv::Size(img.cols / downsample, img.rows / downsample), 0, 0, cv::INTER_AREA);
    if (s.linear.empty()) {
      s.width = img.cols;
      s.height = img.rows;
    } else if (img.cols != s.width || img.rows != s.height) {
      return MakeError(ErrorCode::kInvalidInput, f.string(), "is {}x{}, the first image {}x{}",
                       img.cols, img.rows, s.width, s.height);
    }
    cv::Mat lin(img.rows, img.cols, CV_32FC3), clip(img.rows, img.cols, CV_8UC1);
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const uint8_t* p = img.ptr<uint8_t>(y) + 3 * x;
        for (int c = 0; c < 3; ++c) lin.ptr<float>(y)[3 * x + c] = SrgbDecode(p[c] / 255.0f);
        clip.at<uint8_t>(y, x) = (p[0] >= 250 || p[1] >= 250 || p[2] >= 250) ? 1 : 0;
      }
    s.names.push_back(f.filename().string());
    s.linear.push_back(lin);
    s.clipped.push_back(clip);
  }
  return LightSource{"images", dir, std::move(s), std::nullopt, files[0].string()};
}

// A model has no photographs: it is rendered at 37 directions over the upper hemisphere
// (the zenith and 12 azimuths at 30, 50 and 70 degrees from it).
Result<LightSource> FromModel(const std::string& path) {
  RIG_ASSIGN_OR_RETURN(auto model, LoadAnyModel(path));
  LightStack s;
  s.width = model->width();
  s.height = model->height();
  std::vector<Vec3> dirs = {{0, 0, 1}};
  for (double polar : {30.0, 50.0, 70.0})
    for (int a = 0; a < 12; ++a) {
      const double t = polar * std::numbers::pi / 180, p = a * std::numbers::pi / 6;
      dirs.push_back({std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t)});
    }
  for (const Vec3& d : dirs) {
    cv::Mat rho = model->EvaluateRho(d);
    cv::max(rho, 0.0, rho);
    s.linear.push_back(rho);
    s.directions.push_back(d);
    s.names.push_back(fmt::format("{} at ({:.3f}, {:.3f}, {:.3f})", path, d[0], d[1], d[2]));
  }
  return LightSource{"model", path, std::move(s), std::nullopt, {}};
}

}  // namespace

Result<LightSource> LoadLightSource(const std::string& positional, const std::string& lp,
                                    const std::string& images, int downsample) {
  const int given = !positional.empty() + !lp.empty() + !images.empty();
  if (given != 1)
    return MakeError(ErrorCode::kInvalidInput, "(arguments)",
                     "give exactly one of SESSION|MODEL, --lp FILE.lp or --images DIR");
  if (!lp.empty()) {
    RIG_ASSIGN_OR_RETURN(LightStack stack, LoadLpStack(lp, downsample));
    std::string first = stack.names.empty() ? std::string() : stack.names[0];
    return LightSource{"lp", lp, std::move(stack), std::nullopt, std::move(first)};
  }
  if (!images.empty()) return FromImages(images, downsample);
  std::error_code ec;
  if (fs::is_directory(positional, ec) && fs::exists(fs::path(positional) / "session.toml", ec))
    return FromSession(positional);
  if (!fs::exists(positional, ec))
    return MakeError(ErrorCode::kNotFound, positional, "no such session or model");
  return FromModel(positional);
}

Status OverrideDirections(const std::string& lp, LightSource* source) {
  RIG_ASSIGN_OR_RETURN(auto entries, ReadLp(lp));
  LightStack& stack = source->stack;
  if (entries.size() != stack.size()) {
    return MakeError(ErrorCode::kInvalidInput, lp, "lists {} lights, the capture has {} images",
                     entries.size(), stack.size());
  }
  for (size_t k = 0; k < stack.size(); ++k) stack.directions[k] = entries[k].direction;
  return Ok();
}

}  // namespace rig
