// `rig export`'s formats: a model in relight's web format or RTIViewer's .ptm/.rti, exactly
// where the format holds it, refitted where it does not (convert.h), every file written read
// back as a reader of the format would.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "config/result.h"
#include "process/export/convert.h"
#include "process/export/relight_coefficients.h"
#include "process/model/reflectance_model.h"

namespace rig {

struct ExportRequest {
  std::string format;          // relight, ptm or rti
  std::string out;             // the folder (relight) or file (.ptm, .rti)
  std::string variant = "rgb"; // PTM targets: rgb or lrgb
  std::string basis;           // relight: ptm or hsh; empty: the model's, else hsh
  int hsh_terms = 0;           // HSH targets: 16 (.rti only), 9 or 4; 0: from the source
  int quality = 98;            // relight: JPEG quality (q98: 48.2 dB for the icon's web PTM)
  bool jpeg_rgb = false;       // relight: planes in the JPEG RGB colour space
  // Told, before the conversion starts, what it will do and what the target cannot hold.
  std::function<void(const std::string&)> announce;
  LightProgress progress;  // the conversion's stages over lights
};

// One sentence before a conversion: the model's family onto the target, and what the target's
// basis holds (so what it loses of a model that holds more).
std::string ExportPlan(const std::string& family, int source_terms, const RelightTarget& target,
                       bool harmonic_source);

// The target from the format and the source's own basis (its family name and terms).
Result<RelightTarget> ExportTarget(const ExportRequest& request, const std::string& family,
                                   int source_terms);

// The chosen format written, and read back as a reader of the file would; *what says what.
Result<RelightCoefficients> WriteExportFormat(const ExportRequest& request,
                                              const RelightCoefficients& c, std::string* what);

// What the format does not hold of the model, one sentence each.
std::vector<std::string> ExportNotes(const ExportRequest& request, const ReflectanceModel& model,
                                     const Conversion& conversion);

// The model at `path` loaded for export and converted to the request's target: a harmonic EXR
// from its coefficients (exact maps), every other model through ReflectanceModel.
// A PCA model to relight's web format with no other basis asked is that format already
// (bilinear, mrgb): `as_stored`, nothing converted (CopyDeclaredWebFiles writes it again).
struct ExportSource {
  std::unique_ptr<ReflectanceModel> model;
  Conversion conversion;
  bool as_stored = false;
};
Result<ExportSource> ConvertForExport(const std::string& path, const ExportRequest& request);

// The files a web-format folder's info.json declares, byte for byte, into `out` (created),
// each source opened without following a link.
Status CopyDeclaredWebFiles(const std::string& folder, const std::string& out);

}  // namespace rig
