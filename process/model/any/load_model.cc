// Reading a model of any family from disk.
#include "process/model/any/load_model.h"

#include <filesystem>

#include "process/model/harmonic/model.h"
#include "process/model/pca/pca.h"

namespace rig {

namespace fs = std::filesystem;

Result<std::unique_ptr<ReflectanceModel>> LoadReflectanceModel(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (fs::exists(fs::path(path) / "info.json", ec)) {
      RIG_ASSIGN_OR_RETURN(PcaModel m, PcaModel::Load(path));
      return WrapPca(std::move(m));
    }
    return MakeError(ErrorCode::kInvalidInput, path,
                     "a folder without info.json is not a model this build reads");
  }
  RIG_ASSIGN_OR_RETURN(Model m, LoadModel(path));
  return WrapHarmonic(std::move(m));
}

uint64_t ModelBytesOnDisk(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return FolderBytes(path);
  const auto n = fs::file_size(path, ec);
  return ec ? 0 : n;
}

}  // namespace rig
