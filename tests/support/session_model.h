// Test support: whether a session's fit left its model, whichever family [process]
// model_family chose — model/model.exr (harmonic) or model/pca/ (PCA, relight's web format).
#pragma once

#include <filesystem>

namespace rig::testing {

inline bool SessionHasModel(const std::filesystem::path& session) {
  const std::filesystem::path m = session / "model";
  return std::filesystem::exists(m / "model.exr") || std::filesystem::exists(m / "pca" / "info.json");
}

}  // namespace rig::testing
