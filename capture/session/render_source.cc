// A render's SESSION argument resolved through the session layout.
#include "capture/session/render_source.h"

#include <filesystem>

#include "capture/session/session_store.h"

namespace rig {

Result<RenderSource> ResolveRenderSource(const std::string& source,
                                         const std::string& response_override) {
  RenderSource in;
  const fs::path p(source);
  if (fs::is_directory(p) && fs::exists(p / "info.json")) {
    // A model folder (relight's web format): no session around it.
    in.model_path = source;
  } else if (fs::is_directory(p)) {
    // A session folder: its model — model/model.exr (the harmonic family) or model/pca/ (the
    // PCA family's folder) — the one its configuration names, or for "auto" (or no
    // configuration) whichever was written last; its response curve, its display settings.
    const SessionLayout layout{p};
    in.model_path = (layout.model() / "model.exr").string();
    const fs::path pca = layout.model() / "pca";
    if (fs::exists(pca / "info.json")) {
      bool pca_family = !fs::exists(in.model_path);
      if (!pca_family) {
        std::string family = "auto";
        if (fs::exists(layout.config())) {
          auto config = LoadConfigOrError(layout.config().string());
          if (config.ok()) family = config->process.model_family;
        }
        std::error_code e1, e2;
        const auto pca_time = fs::last_write_time(pca / "info.json", e1);
        const auto exr_time = fs::last_write_time(in.model_path, e2);
        pca_family = family == "pca" || (family == "auto" && !e1 && (e2 || pca_time > exr_time));
      }
      if (pca_family) in.model_path = pca.string();
    }
    if (!fs::exists(in.model_path)) {
      return MakeError(ErrorCode::kNotFound, in.model_path,
                       "the session has no model yet (run 'rig process {}')", source);
    }
    const fs::path response = layout.calib() / "response.csv";
    if (fs::exists(response)) in.response_path = response.string();
    if (fs::exists(layout.config())) {
      RIG_ASSIGN_OR_RETURN(Config config, LoadConfigOrError(layout.config().string()));
      in.process = config.process;
    }
  } else {
    if (!fs::exists(p)) return MakeError(ErrorCode::kNotFound, source, "no such model file or session");
    in.model_path = source;
    // A model inside a session (SESSION/model/x.exr): the session's response.
    const SessionLayout layout{p.parent_path().parent_path()};
    const fs::path response = layout.calib() / "response.csv";
    if (fs::exists(response)) in.response_path = response.string();
  }
  if (!response_override.empty()) in.response_path = response_override;
  return in;
}

}  // namespace rig
