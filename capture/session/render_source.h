// What a render reads from a SESSION argument: the session's model, its response curve and
// its display settings — or, for a model file, the response of the session it lies in.
#pragma once

#include <optional>
#include <string>

#include "config/config.h"
#include "config/result.h"

namespace rig {

struct RenderSource {
  std::string model_path;
  std::string response_path;             // empty: none known
  std::optional<ProcessConfig> process;  // the session's [process] (session.toml), if any
};

// `source`: a session folder (its model/model.exr, calib/response.csv, session.toml) or a
// model file (SESSION/model/x.exr: that session's calib/response.csv when present).
// `response_override`, when not empty, is the response used instead. Errors: kNotFound (no
// such file or session, a session without a model yet), the session.toml's own errors.
Result<RenderSource> ResolveRenderSource(const std::string& source,
                                         const std::string& response_override = "");

}  // namespace rig
