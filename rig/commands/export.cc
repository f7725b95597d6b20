// rig export MODEL --format relight|ptm|rti --out PATH: a model in relight's web format or
// RTIViewer's .ptm/.rti, exactly where the format holds it, refitted (and the PSNR lost
// printed) where it does not; every file written is read back and its PSNR measured.
// rig export SESSION --format lp --out DIR: the session's radiance maps as an RTI capture.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>

#include <fmt/format.h>

#include <algorithm>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "capture/plan/pose.h"
#include "config/atomic_file.h"
#include "process/io/image_io.h"
#include "capture/session/render_source.h"
#include "capture/session/session_store.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/export/convert.h"
#include "process/export/deepzoom.h"
#include "process/export/load_any.h"
#include "process/export/relight_files.h"
#include "process/model/harmonic/model.h"
#include "rig/commands/command.h"
#include "config/console.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

struct ExportArgs {
  std::string source, format, out, variant = "rgb", basis, log_level, tiles = "auto";
  int hsh_terms = 0, quality = 98;  // q98: 48.2 dB for the icon's web PTM (q95: 44.1)
  bool jpeg_rgb = false;
};

std::string Db(double db) { return std::isinf(db) ? "identical (inf dB)" : fmt::format("{:.2f} dB", db); }

// The target from the format and the source's own basis.
Result<RelightTarget> TargetFor(const ExportArgs& a, const std::string& family, int source_terms) {
  RelightTarget t;
  std::string basis = a.basis;
  if (a.format == "ptm") {
    if (!basis.empty() && basis != "ptm")
      return MakeError(ErrorCode::kInvalidInput, "--basis", "'{}' with --format ptm", basis);
    basis = "ptm";
  } else if (a.format == "rti") {
    if (!basis.empty() && basis != "hsh")
      return MakeError(ErrorCode::kInvalidInput, "--basis", "'{}' with --format rti (HSH only)", basis);
    basis = "hsh";
  } else if (a.format != "relight") {
    return MakeError(ErrorCode::kInvalidInput, "--format", "'{}': relight, ptm, rti or lp", a.format);
  }
  if (basis.empty()) basis = family.rfind("ptm", 0) == 0 ? "ptm" : "hsh";
  if (basis == "ptm") {
    t.type = RelightType::kPtm;
    t.terms = 6;
  } else if (basis == "hsh") {
    t.type = RelightType::kHsh;
    t.terms = a.hsh_terms ? a.hsh_terms : (family == "hsh" && source_terms <= 4 ? 4 : 9);
  } else {
    return MakeError(ErrorCode::kInvalidInput, "--basis", "'{}': ptm or hsh", basis);
  }
  if (a.variant == "lrgb") {
    if (t.type != RelightType::kPtm)
      return MakeError(ErrorCode::kInvalidInput, "--ptm-variant", "lrgb is a PTM variant");
    t.lrgb = true;
  } else if (a.variant != "rgb") {
    return MakeError(ErrorCode::kInvalidInput, "--ptm-variant", "'{}': rgb or lrgb", a.variant);
  }
  if (a.hsh_terms && t.type != RelightType::kHsh)
    return MakeError(ErrorCode::kInvalidInput, "--hsh-terms", "only for an HSH target");
  return t;
}

// A session's radiance maps as an RTI capture: hdr/<pose>.exr -> OUT/<pose>.png (8-bit sRGB,
// one exposure for all: the 99.5th percentile of every map's values becomes white) and
// OUT/dirs.lp with each pose's direction in the object frame (the session's light frame).
int ExportSessionLp(const ExportArgs& a) {
  const SessionLayout layout{fs::path(a.source)};
  std::error_code ec;
  if (!fs::is_directory(layout.hdr(), ec)) {
    return ReportError("export", MakeError(ErrorCode::kNotFound, layout.hdr().string(),
                                           "no radiance maps (--format lp needs a session)"));
  }
  LightFrameConfig frame;
  if (fs::exists(layout.config(), ec)) {
    auto config = LoadConfigOrError(layout.config().string());
    if (!config.ok()) return ReportError("export", config.error());
    frame = config->light_frame;
  }
  std::vector<std::pair<std::string, Pose>> poses;
  for (const auto& e : fs::directory_iterator(layout.hdr(), ec)) {
    if (e.path().extension() != ".exr") continue;
    auto pose = ParsePoseName(e.path().stem().string());
    if (!pose.ok()) return ReportError("export", pose.error().Within(e.path().string()));
    poses.emplace_back(e.path().string(), *pose);
  }
  if (poses.empty()) {
    return ReportError("export", MakeError(ErrorCode::kNotFound, layout.hdr().string(), "no radiance maps"));
  }
  std::sort(poses.begin(), poses.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<cv::Mat> maps;
  std::vector<float> sample;
  std::optional<ProgressTask> reading(std::in_place, "reading radiance maps",
                                      static_cast<int64_t>(poses.size()));
  for (const auto& [path, pose] : poses) {
    reading->Advance(1, pose.Name());
    auto m = ReadRgbExr(path);
    if (!m.ok()) return ReportError("export", m.error());
    if (!maps.empty() && m->size() != maps[0].size()) {
      return ReportError("export", MakeError(ErrorCode::kInvalidInput, path, "{}x{}, the first map is {}x{}",
                                             m->cols, m->rows, maps[0].cols, maps[0].rows));
    }
    const float* p = m->ptr<float>();
    const size_t n = m->total() * 3, stride = std::max<size_t>(1, n / 20000);
    for (size_t i = 0; i < n; i += stride) sample.push_back(p[i]);
    maps.push_back(*m);
  }
  reading.reset();
  const size_t q = static_cast<size_t>(0.995 * (sample.size() - 1));
  std::nth_element(sample.begin(), sample.begin() + q, sample.end());
  const float white = sample[q] > 0 ? sample[q] : 1.0f;
  fs::create_directories(a.out, ec);
  if (ec) return ReportError("export", MakeError(ErrorCode::kIo, a.out, "cannot create: {}", ec.message()));
  std::vector<std::string> names;
  std::vector<Vec3> dirs;
  for (size_t i = 0; i < maps.size(); ++i) {
    cv::Mat out(maps[i].size(), CV_8UC3);
    const float* in = maps[i].ptr<float>();
    uint8_t* o = out.ptr<uint8_t>();
    for (size_t k = 0; k < maps[i].total() * 3; ++k)
      o[k] = static_cast<uint8_t>(std::lround(255.0f * SrgbEncode(std::clamp(in[k] / white, 0.0f, 1.0f))));
    const std::string name = poses[i].second.Name() + ".png";
    const std::string path = (fs::path(a.out) / name).string();
    if (Status st = WriteImageFile(path, out); !st.ok()) return ReportError("export", st.error());
    names.push_back(name);
    dirs.push_back(LightDirection(poses[i].second.h_deg, poses[i].second.v_deg, frame));
  }
  const std::string lp = (fs::path(a.out) / "dirs.lp").string();
  if (Status st = WriteLp(lp, names, dirs); !st.ok()) return ReportError("export", st.error());
  std::printf("rig export: wrote %s and %zu images (%dx%d, 8-bit sRGB, radiance %.4g = white) to %s\n",
              lp.c_str(), names.size(), maps[0].cols, maps[0].rows, white, a.out.c_str());
  return 0;
}

// Deep-zoom tiles of a written web-format folder, by --tiles.
int WriteTilesIfWanted(const ExportArgs& a, int width, int height) {
  if (a.tiles == "off" || (a.tiles == "auto" && !WantsDeepZoom(width, height))) return 0;
  DeepZoomOptions o;
  o.quality = a.quality;
  auto report = WriteDeepZoom(a.out, o);
  if (!report.ok()) return ReportError("export", report.error());
  std::printf("  deep zoom: %d plane files x %d levels, %ld tiles of %d px (overlap %d) in %.2f s\n",
              report->files, report->levels, report->tiles, o.tile_size, o.overlap, report->seconds);
  return 0;
}

}  // namespace

// The chosen format written, and read back as a reader of the file would; *what says what.
static Result<RelightCoefficients> WriteExportFormat(const ExportArgs& a, const RelightCoefficients& c,
                                                     std::string* what_out) {
  std::string& what = *what_out;
  Status written = Ok();
  Result<RelightCoefficients> back = MakeError(ErrorCode::kInternal, "export", "not read");
  if (a.format == "relight") {
    WebWriteOptions o;
    o.quality = a.quality;
    o.ycbcr = !a.jpeg_rgb;
    written = WriteRelightWeb(a.out, c, o);
    const int nplanes = c.lrgb ? 9 : 3 * c.terms;
    what = fmt::format("relight web format, {}, {} planes in {} JPEGs q{} ({})", c.Summary(),
                       nplanes, (nplanes + 2) / 3, a.quality, a.jpeg_rgb ? "RGB" : "YCbCr 4:4:4");
    if (written.ok()) back = ReadRelightWeb(a.out);
  } else if (a.format == "ptm") {
    written = WritePtm(a.out, c);
    what = fmt::format("PTM 1.2, {}, raw", c.lrgb ? "PTM_FORMAT_LRGB" : "PTM_FORMAT_RGB");
    if (written.ok()) back = ReadPtm(a.out);
  } else {
    written = WriteRti(a.out, c);
    what = fmt::format("HSH .rti (#HSH1.2, rti_type 3), {} terms per channel, 1-byte elements", c.terms);
    if (written.ok()) back = ReadRti(a.out);
  }
  if (!written.ok()) return written.error();
  if (!back.ok()) return back.error().Within("reading back what was written");
  return back;
}

// What the format does not hold, said once.
static void PrintExportNotes(const ExportArgs& a, const ReflectanceModel& model_ref,
                             const Conversion& conversion_ref) {
  const ReflectanceModel* model = &model_ref;
  const Conversion* conversion = &conversion_ref;
  const LightFrameConfig& frame = model->light_frame();
  if (frame.h_sign != 1 || frame.v_sign != 1 || frame.h_offset_deg != 0 || frame.v_offset_deg != 0) {
    std::printf("  note: the format holds object-frame directions; the model's light frame "
                "(rig angles) is not stored\n");
  }
  const auto e = model->lamp_radiance_rgb();
  if (model->encoding() == ValueEncoding::kLinear && conversion->gain == 1 &&
      (e[0] != 1 || e[1] != 1 || e[2] != 1)) {
    std::printf("  note: values are the sRGB encoding of rho (a unit lamp); the capture lamp's "
                "radiance (%g, %g, %g) is not stored\n", e[0], e[1], e[2]);
  }
  if (a.format == "relight" && a.jpeg_rgb) {
    std::printf("  note: RGB-colour-space planes: relight's C++ reader (Rti::load) decodes planes as "
                "YCbCr and would misread them; its web viewer and this reader do not\n");
  }
  if (conversion->gain != 1) {
    std::printf("  note: rho was scaled by %.4g to fit 8-bit values (relight stores display values)\n",
                conversion->gain);
  }
}

int RunExport(int argc, char** argv) {
  CLI::App app{"Write a reflectance model in relight's web format (info.json + plane_N.jpg, types "
               "ptm and hsh) or as RTIViewer's .ptm (PTM 1.2, RGB or LRGB) or .rti (HSH). Where "
               "the format cannot hold the model exactly (SH, a linear or log fit space, another "
               "order), it is refitted at the model's sampled lights and the PSNR lost is printed.",
               "rig export"};
  ExportArgs a;
  app.add_option("MODEL", a.source,
                 "a model (EXR, relight folder, .ptm, .rti) or a session folder (its model)")
      ->required();
  app.add_option("--format", a.format,
                 "relight, ptm or rti; lp: a SESSION's radiance maps as 8-bit sRGB images + dirs.lp")
      ->required();
  app.add_option("--out", a.out, "the folder (relight) or file (.ptm, .rti) to write; must not exist")
      ->required();
  app.add_option("--ptm-variant", a.variant,
                 "PTM targets: rgb (default) or lrgb (luminance PTM x RGB albedo; relight's lptm)");
  app.add_option("--basis", a.basis, "--format relight: ptm or hsh (default: the model's, else hsh)");
  app.add_option("--hsh-terms", a.hsh_terms, "HSH targets: 9 (default) or 4")
      ->check(CLI::IsMember({4, 9}));
  app.add_option("--jpeg-quality", a.quality, "--format relight: JPEG quality (default 98; relight writes 95, which loses ~4 dB on "
                 "PTM planes: docs/viewer.md)")
      ->check(CLI::Range(1, 100));
  app.add_flag("--jpeg-rgb", a.jpeg_rgb,
               "--format relight: planes in the JPEG RGB colour space (Adobe marker; ~2 dB more, "
               "~2x the bytes). Not for relight's C++ reader, which decodes every plane as YCbCr "
               "(Rti::load); browsers and libjpeg's default honour the marker. Default: YCbCr 4:4:4, "
               "as relight writes rgb planes");
  app.add_option("--tiles", a.tiles,
                 "--format relight: deep-zoom tiles (plane_N.dzi + plane_N_files/, 256 px, overlap 1) "
                 "beside the planes: auto (longer side > 4096), on, off")
      ->check(CLI::IsMember({"auto", "on", "off"}));
  AddLogLevelOption(app, &a.log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(a.log_level)) return *rc;

  std::error_code ec;
  if (fs::exists(a.out, ec)) {
    return ReportError("export", MakeError(ErrorCode::kInvalidInput, a.out,
                                           "exists; choose another --out (nothing is overwritten)"));
  }
  if (a.format == "lp") return ExportSessionLp(a);
  auto source = ResolveRenderSource(a.source);
  if (!source.ok()) return ReportError("export", source.error());
  const std::string& path = source->model_path;
  std::string ext = fs::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));

  // Harmonic EXRs convert from their coefficients (exact maps); every other model through
  // ReflectanceModel.
  std::unique_ptr<ReflectanceModel> model;
  Result<Conversion> conversion = MakeError(ErrorCode::kInternal, "export", "not converted");
  if (ext == ".exr") {
    auto m = LoadModel(path);
    if (!m.ok()) return ReportError("export", m.error());
    auto target = TargetFor(a, m->basis().name(), m->basis().size());
    if (!target.ok()) return ReportError("export", target.error());
    conversion = ConvertToRelight(*m, *target);
    model = WrapHarmonic(std::move(*m));
  } else {
    auto m = LoadAnyModel(path);
    if (!m.ok()) return ReportError("export", m.error());
    model = std::move(*m);
    // A PCA model is relight's web format already (bilinear, mrgb): written again as it is,
    // not refitted onto a smaller basis.
    if (a.format == "relight" && model->family() == "pca-bilinear" && a.basis.empty()) {
      // Its files, byte for byte (saving again would compress the planes a second time).
      // Only what info.json declares, each opened without following a link.
      auto names = DeclaredWebFiles(path);
      if (!names.ok()) return ReportError("export", names.error());
      for (const auto& n : *names) {
        Status st = CopyFileNoFollow(std::filesystem::path(path) / n, std::filesystem::path(a.out) / n);
        if (!st.ok()) return ReportError("export", st.error());
      }
      std::printf("rig export: wrote %s (relight web format, bilinear mrgb, as the model is "
                  "stored: nothing refitted, nothing lost)\n  from %s: %s\n",
                  a.out.c_str(), path.c_str(), model->Describe().c_str());
      return WriteTilesIfWanted(a, model->width(), model->height());
    }
    const RelightCoefficients* rc = RelightCoefficientsOf(*model);
    auto target = TargetFor(a, model->family(), rc ? rc->terms : 0);
    if (!target.ok()) return ReportError("export", target.error());
    conversion = ConvertToRelight(*model, *target);
  }
  if (!conversion.ok()) return ReportError("export", conversion.error());
  const RelightCoefficients& c = conversion->coefficients;

  std::string what;
  Result<RelightCoefficients> back = WriteExportFormat(a, c, &what);
  if (!back.ok()) return ReportError("export", back.error());
  std::printf("rig export: wrote %s (%s, %dx%d)\n", a.out.c_str(), what.c_str(), c.width, c.height);
  std::printf("  from %s: %s\n", path.c_str(), model->Describe().c_str());
  std::printf("  %s\n", conversion->how.c_str());
  if (conversion->exact) {
    std::printf("  held exactly before quantisation (%s over %d lights)\n",
                Db(conversion->psnr_db).c_str(), conversion->lights);
  } else {
    std::printf("  refitted: %s PSNR against the source's render over %d lights, before "
                "quantisation (8-bit sRGB)\n",
                Db(conversion->psnr_db).c_str(), conversion->lights);
  }
  // The whole loss: what a reader of the file renders against the source, at the same lights.
  std::vector<Vec3> lights = c.lights.empty() ? HemisphereDirections() : c.lights;
  const auto reread = WrapRelight(std::move(*back), a.out);
  std::printf("  as written, read back: %s PSNR against the source over %zu lights (8-bit sRGB)\n",
              Db(RenderPsnrDb(*model, *reread, lights, conversion->gain)).c_str(), lights.size());
  PrintExportNotes(a, *model, *conversion);
  if (a.format == "relight") return WriteTilesIfWanted(a, c.width, c.height);
  return 0;
}

}  // namespace rig
