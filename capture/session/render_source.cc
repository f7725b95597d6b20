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
    // A session folder: its model (the family its configuration fits: model/model.exr, or
    // model/pca/ for [process] model_family = "pca"), its response curve, its display settings.
    const SessionLayout layout{p};
    in.model_path = (layout.model() / "model.exr").string();
    const fs::path pca = layout.model() / "pca";
    if (fs::exists(pca / "info.json")) {
      bool pca_family = !fs::exists(in.model_path);
      if (!pca_family && fs::exists(layout.config())) {
        auto config = LoadConfigOrError(layout.config().string());
        pca_family = config.ok() && config->process.model_family == "pca";
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
