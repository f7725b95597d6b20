// Reading a model of any family from disk.
#include "process/model/any/load_model.h"

#include <cctype>
#include <filesystem>

#include "config/atomic_file.h"

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

namespace {

// "<prefix><digits><suffix>"
bool Numbered(const std::string& name, const std::string& prefix, const std::string& suffix) {
  if (name.size() <= prefix.size() + suffix.size() || name.compare(0, prefix.size(), prefix) != 0 ||
      name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
    return false;
  for (size_t i = prefix.size(); i < name.size() - suffix.size(); ++i)
    if (!std::isdigit(static_cast<unsigned char>(name[i]))) return false;
  return true;
}

}  // namespace

bool IsModelFolderFile(const std::string& name) {
  return name == "info.json" || name == "neural.json" || name == "decoder.bin" ||
         Numbered(name, "plane_", ".jpg") || Numbered(name, "code_", ".jpg") ||
         Numbered(name, "codes_", ".png");
}

Status WriteModelFolder(const std::string& folder,
                        const std::function<Status(const std::string& dir)>& write) {
  RIG_ASSIGN_OR_RETURN(AtomicFolder staged, AtomicFolder::Begin(folder, IsModelFolderFile));
  RIG_TRY(write(staged.dir().string()));
  return staged.Commit();
}

uint64_t ModelBytesOnDisk(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return FolderBytes(path);
  const auto n = fs::file_size(path, ec);
  return ec ? 0 : n;
}

}  // namespace rig
