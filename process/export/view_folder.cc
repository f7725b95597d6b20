#include "process/export/view_folder.h"

#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "config/atomic_file.h"
#include "config/console.h"
#include "process/export/convert.h"
#include "process/export/deepzoom.h"
#include "process/export/load_any.h"
#include "process/export/relight_files.h"
#include "process/export/viewer_page.h"
#include "process/model/harmonic/model.h"
#include "process/render/tonemap.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

Vec3 MeanDirection(const std::vector<Vec3>& lights) {
  Vec3 m{0, 0, 0};
  for (const auto& l : lights)
    for (int k = 0; k < 3; ++k) m[k] += l[k];
  const double n = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
  if (!(n > 0)) return {0, 0, 1};
  return {m[0] / n, m[1] / n, m[2] / n};
}

Status CopyFile(const fs::path& from, const fs::path& to) { return CopyFileNoFollow(from, to); }

// Ward's global curve for the source's radiance at `light` (as `rig render` maps it), as a
// table of pixel luminance (before the sRGB encoding) over ln L_w.
nlohmann::json WardDisplay(const ReflectanceModel& model, const Vec3& light, double gain,
                           const ToneMapOptions& options) {
  cv::Mat radiance;
  model.AddLamp(light, {1, 1, 1}, &radiance);
  // The luminance weights rig render uses (the white-balanced Y of the radiance's primaries).
  const cv::Vec3f w = LuminanceWeightsBgr(options);
  const cv::Mat foveal = FovealLuminance(Luminance(radiance, w), options.field_of_view_deg);
  std::vector<float> samples(foveal.begin<float>(), foveal.end<float>());
  const WardMapping mapping = ComputeWardMapping(samples, options);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (float s : samples)
    if (s > 0 && std::isfinite(s)) lo = std::min(lo, std::log(double(s))), hi = std::max(hi, std::log(double(s)));
  if (!(hi > lo)) lo = -10, hi = 10;
  lo -= 2;
  hi += 2;
  const int n = 4096;
  std::vector<double> lut(n);
  for (int i = 0; i < n; ++i) lut[i] = mapping.PixelLuminance(std::exp(lo + (hi - lo) * i / (n - 1)));
  const auto e = model.lamp_radiance_rgb();
  return {{"encoding", "linear"}, {"gain", gain}, {"lamp_rgb", {e[0], e[1], e[2]}},
          {"tonemap", "ward"}, {"lut_log_min", lo}, {"lut_log_max", hi}, {"lut", lut},
          {"lut_light", {light[0], light[1], light[2]}},
          {"luminance_rgb", {w[2], w[1], w[0]}}};
}

// The conversion's stages (refit, comparison) as progress tasks, one a stage, shown as every
// long step is (a bar on a terminal, a line every few seconds elsewhere).
class StageProgress {
 public:
  LightProgress Callback() {
    return [this](const char* stage, size_t done, size_t total) {
      if (!task_ || stage_ != stage) {
        task_.reset();
        stage_ = stage;
        task_ = std::make_unique<ProgressTask>(stage_, static_cast<int64_t>(total));
      }
      task_->Set(static_cast<int64_t>(done));
    };
  }

 private:
  std::string stage_;
  std::unique_ptr<ProgressTask> task_;
};

// A model not in relight's web format: converted to it in `out` (as rig export does), read
// back and compared with the source; *model, *lights, *gain and *how receive what the page needs.
Status ConvertForView(const std::string& path, const std::string& ext, int quality,
                             const std::string& out, std::unique_ptr<ReflectanceModel>* model_out,
                             std::vector<Vec3>* lights_out, double* gain, std::string* how) {
  std::unique_ptr<ReflectanceModel>& model = *model_out;
  std::vector<Vec3>& lights = *lights_out;
  RelightTarget target;
  StageProgress progress;
  Result<Conversion> conversion = MakeError(ErrorCode::kInternal, "view", "not converted");
  if (ext == ".exr") {
    auto m = LoadModel(path);
    if (!m.ok()) return m.error();
    const std::string family = m->basis().name();
    target.type = family.rfind("ptm", 0) == 0 ? RelightType::kPtm : RelightType::kHsh;
    target.terms = target.type == RelightType::kPtm ? 6 : (family == "hsh" && m->basis().size() <= 4 ? 4 : 9);
    lights = m->info().lamp_directions;
    conversion = ConvertToRelight(*m, target, progress.Callback());
    model = WrapHarmonic(std::move(*m));
  } else {
    auto m = LoadAnyModel(path);
    if (!m.ok()) return m.error();
    model = std::move(*m);
    const RelightCoefficients* rc = RelightCoefficientsOf(*model);
    if (rc) {
      target.type = rc->type;
      target.terms = rc->terms;
      target.lrgb = rc->lrgb;
      lights = rc->lights;
      // relight's JS viewer has no sh weights: the page shows the model refitted as hsh.
      // Nor weights past 9 HSH terms: a .rti of RTIViewer's third order is shown refitted to 9.
      if (rc->type == RelightType::kSh || rc->terms > 9) {
        target.type = RelightType::kHsh;
        target.terms = 9;
      }
    } else {
      target.type = RelightType::kHsh;
      target.terms = 9;
    }
    conversion = ConvertToRelight(*model, target, {}, progress.Callback());
  }
  if (!conversion.ok()) return conversion.error();
  WebWriteOptions o;
  o.quality = quality;
  if (Status st = WriteRelightWeb(out, conversion->coefficients, o); !st.ok()) return st.error();
  auto back = ReadRelightWeb(out);
  if (!back.ok()) return back.error().Within("reading back what was written");
  const auto reread = WrapRelight(std::move(*back), out);
  std::vector<Vec3> at = lights.empty() ? HemisphereDirections() : lights;
  const double psnr = RenderPsnrDb(*model, *reread, at, conversion->gain, progress.Callback());
  *gain = conversion->gain;
  *how = fmt::format("{}; as written, {} against the source over {} lights (8-bit sRGB)", conversion->how,
                    std::isinf(psnr) ? std::string("identical") : fmt::format("{:.2f} dB", psnr), at.size());
  return Ok();
}

}  // namespace

Result<ViewReport> WriteViewFolder(const ViewRequest& request) {
  const ViewRequest& a = request;
  const std::string& path = a.model_path;
  std::error_code ec;
  std::string ext = fs::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));

  std::unique_ptr<ReflectanceModel> model;
  std::string how;
  double gain = 1;
  std::vector<Vec3> lights;
  const std::string web_type = fs::is_directory(path, ec) ? RelightWebType(path) : "";
  const bool wants_tiles_on = a.tiles == "on", wants_tiles_auto = a.tiles == "auto";
  std::string describe;
  int width = 0, height = 0;
  const bool pca_type = web_type == "bilinear" || web_type == "rbf";  // mrgb or mycc
  if (web_type == "ptm" || web_type == "hsh" || pca_type) {
    if (!pca_type) {
      // info.json and the plane headers first; a model that gets tiles is decoded by the tiler
      // (which refuses a damaged plane, naming it), not held whole as float planes here.
      auto info = ReadRelightWebInfo(path);
      if (!info.ok()) return info.error();
      lights = info->lights;
      width = info->width;
      height = info->height;
      describe = fmt::format("{} (relight's basis), from {} (relight web format)", info->Summary(), path);
    }
    const bool tiled = wants_tiles_on || (wants_tiles_auto && width > 0 && WantsDeepZoom(width, height));
    if (!tiled) {
      auto m = LoadAnyModel(path);  // checks the whole folder
      if (!m.ok()) return m.error();
      model = std::move(*m);
      if (lights.empty()) lights = model->fitted_lights();  // a PCA (bilinear) model's too
    }
    fs::create_directories(a.out, ec);
    if (ec) return MakeError(ErrorCode::kIo, a.out, "cannot create: {}", ec.message());
    // Only what info.json declares (a plane past them is no part of the model).
    auto names = DeclaredWebFiles(path);
    if (!names.ok()) return names.error();
    for (const auto& n : *names)
      if (Status st = CopyFile(fs::path(path) / n, fs::path(a.out) / n); !st.ok()) return st.error();
    how = fmt::format("{} web format copied as it is (nothing refitted)", web_type);
  } else {
    if (Status st = ConvertForView(path, ext, a.quality, a.out, &model, &lights, &gain, &how); !st.ok())
      return st.error();
  }

  if (model) {
    if (lights.empty()) lights = model->fitted_lights();
    describe = model->Describe();
    width = model->width();
    height = model->height();
  }
  const bool srgb = !model || model->encoding() == ValueEncoding::kSrgb;
  ViewerPage page;
  page.source = describe;
  if (a.light) {
    page.default_light = *a.light;
  } else if (!lights.empty()) {
    page.default_light = MeanDirection(lights);
  }
  if (!srgb) {
    ToneMapOptions options = a.process ? ToneMapOptionsFor(*a.process) : ToneMapOptions{};
    options.srgb = true;
    page.display = WardDisplay(*model, page.default_light, gain, options);
  }
  // normals.png / albedo.png beside the model (rig normals writes them there).
  const fs::path beside = fs::is_directory(path, ec) ? fs::path(path) : fs::path(path).parent_path();
  for (const char* name : {"normals.png", "albedo.png"}) {
    if (!fs::exists(fs::symlink_status(beside / name, ec))) continue;  // a link: refused by CopyFile
    if (Status st = CopyFile(beside / name, fs::path(a.out) / name); !st.ok()) return st.error();
    page.images.push_back(name);
  }
  page.tiles = wants_tiles_on || (wants_tiles_auto && WantsDeepZoom(width, height));
  std::string tiles_line;
  if (page.tiles) {
    page.tile_options.quality = a.quality;
    auto report = WriteDeepZoom(a.out, page.tile_options);
    if (!report.ok()) return report.error();
    tiles_line = fmt::format("\n  deep zoom: {} plane files x {} levels, {} tiles of {} px (overlap {}) in {:.2f} s",
                             report->files, report->levels, report->tiles, page.tile_options.tile_size,
                             page.tile_options.overlap, report->seconds);
  }
  if (Status st = WriteViewerPage(a.out, page); !st.ok()) return st.error();
  ViewReport report;
  report.width = width;
  report.height = height;
  report.describe = describe;
  report.how = how;
  report.tiles_line = tiles_line;
  report.tiled = page.tiles;
  report.srgb = srgb;
  return report;
}

}  // namespace rig
