#include "process/export/export_model.h"

#include <cctype>
#include <filesystem>

#include <fmt/format.h>

#include "config/atomic_file.h"
#include "process/export/load_any.h"
#include "process/export/relight_files.h"
#include "process/model/harmonic/model.h"

namespace rig {

// The target from the format and the source's own basis.
Result<RelightTarget> ExportTarget(const ExportRequest& a, const std::string& family, int source_terms) {
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
  if (t.terms == 16 && a.format != "rti")
    return MakeError(ErrorCode::kInvalidInput, "--hsh-terms",
                     "16 only with --format rti (relight's web format stops at 9 terms)");
  return t;
}

std::string ExportPlan(const std::string& family, int source_terms, const RelightTarget& t,
                       bool harmonic_source) {
  const std::string name =
      t.type == RelightType::kPtm ? (t.lrgb ? "PTM lrgb (6 terms)" : "PTM rgb (6 terms per channel)")
                                  : fmt::format("HSH of {} terms per channel", t.terms);
  const std::string target_family = t.type == RelightType::kPtm ? (t.lrgb ? "ptm-lrgb" : "ptm") : "hsh";
  if (family == target_family && source_terms == t.terms) return fmt::format("{}: copied as it is", name);
  if (family.rfind("ptm", 0) == 0 && t.type == RelightType::kPtm) {
    return t.lrgb ? fmt::format("{} from the rgb PTM: one luminance polynomial for the three "
                                "channels times a colour per pixel; colour that changes with the "
                                "light is lost", name)
                  : fmt::format("{} from the lrgb PTM: expanded exactly", name);
  }
  const char* holds =
      t.type == RelightType::kPtm
          ? "a biquadratic in the light's x, y: one broad lobe per pixel"
          : t.terms == 4 ? "hemispherical harmonics of the first order: a tilted plane over the hemisphere"
          : t.terms == 9 ? "hemispherical harmonics to the second order: broad lobes"
                         : "hemispherical harmonics to the third order";
  std::string s = fmt::format("{} holds {}; what the {} model holds beyond that (sharp highlights, "
                              "cast shadows, interreflections) is lost: ", name, holds, family);
  s += harmonic_source ? "mapped exactly where the model's basis lies within it, else refitted by "
                         "least squares over the hemisphere, and measured against the model's "
                         "own renders"
                       : "refitted by least squares at the model's lights, and measured against "
                         "the model's own renders there";
  if (t.lrgb) s += "; then one luminance for the three channels times a colour per pixel";
  return s;
}

// The chosen format written, and read back as a reader of the file would; *what says what.
Result<RelightCoefficients> WriteExportFormat(const ExportRequest& a, const RelightCoefficients& c,
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
std::vector<std::string> ExportNotes(const ExportRequest& a, const ReflectanceModel& model_ref,
                                     const Conversion& conversion_ref) {
  std::vector<std::string> notes;
  const ReflectanceModel* model = &model_ref;
  const Conversion* conversion = &conversion_ref;
  const LightFrameConfig& frame = model->light_frame();
  if (frame.h_sign != 1 || frame.v_sign != 1 || frame.h_offset_deg != 0 || frame.v_offset_deg != 0) {
    notes.push_back("the format holds object-frame directions; the model's light frame "
                    "(rig angles) is not stored");
  }
  const auto e = model->lamp_radiance_rgb();
  if (model->encoding() == ValueEncoding::kLinear && conversion->gain == 1 &&
      (e[0] != 1 || e[1] != 1 || e[2] != 1)) {
    notes.push_back(fmt::format("values are the sRGB encoding of rho (a unit lamp); the capture "
                                "lamp's radiance ({:g}, {:g}, {:g}) is not stored", e[0], e[1], e[2]));
  }
  if (a.format == "relight" && a.jpeg_rgb) {
    notes.push_back("RGB-colour-space planes: relight's C++ reader (Rti::load) decodes planes as "
                    "YCbCr and would misread them; its web viewer and this reader do not");
  }
  if (conversion->gain != 1) {
    notes.push_back(fmt::format("rho was scaled by {:.4g} to fit 8-bit values (relight stores "
                                "display values)", conversion->gain));
  }
  return notes;
}

Result<ExportSource> ConvertForExport(const std::string& path, const ExportRequest& request) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  ExportSource s;
  Result<Conversion> conversion = MakeError(ErrorCode::kInternal, "export", "not converted");
  if (ext == ".exr") {
    RIG_ASSIGN_OR_RETURN(Model m, LoadModel(path));
    RIG_ASSIGN_OR_RETURN(RelightTarget target, ExportTarget(request, m.basis().name(), m.basis().size()));
    if (request.announce) request.announce(ExportPlan(m.basis().name(), m.basis().size(), target, true));
    conversion = ConvertToRelight(m, target, request.progress);
    s.model = WrapHarmonic(std::move(m));
  } else {
    RIG_ASSIGN_OR_RETURN(s.model, LoadAnyModel(path));
    // A photographs' PCA model is relight's own format: its files, as they are. A session's PCA
    // model holds reflectance of radiance maps through an HDR curve (info.json's rig.values),
    // which relight's readers do not know (they would show the codes as sRGB photographs):
    // it is refitted into 8-bit display values, as a harmonic session's model is.
    if (request.format == "relight" && s.model->family().rfind("pca-", 0) == 0 && request.basis.empty() &&
        s.model->encoding() != ValueEncoding::kLinear) {
      s.as_stored = true;
      return s;
    }
    const RelightCoefficients* rc = RelightCoefficientsOf(*s.model);
    RIG_ASSIGN_OR_RETURN(RelightTarget target,
                         ExportTarget(request, s.model->family(), rc ? rc->terms : 0));
    if (request.announce) request.announce(ExportPlan(s.model->family(), rc ? rc->terms : 0, target, false));
    conversion = ConvertToRelight(*s.model, target, {}, request.progress);
  }
  if (!conversion.ok()) return conversion.error();
  s.conversion = std::move(*conversion);
  return s;
}

Status CopyDeclaredWebFiles(const std::string& folder, const std::string& out) {
  RIG_ASSIGN_OR_RETURN(std::vector<std::string> names, DeclaredWebFiles(folder));
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) return MakeError(ErrorCode::kIo, out, "cannot create: {}", ec.message());
  for (const auto& n : names)
    RIG_TRY(CopyFileNoFollow(std::filesystem::path(folder) / n, std::filesystem::path(out) / n));
  return Ok();
}

}  // namespace rig
