// The foreign formats first, then the families of process/model.
#include "process/export/load_any.h"

#include <cctype>
#include <filesystem>
#include <fstream>

#include "process/export/relight_coefficients.h"
#include "process/model/any/load_model.h"
#include "process/export/relight_files.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

std::string Extension(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  for (char& ch : e) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return e;
}

std::string FirstBytes(const std::string& path, size_t n) {
  std::ifstream f(path, std::ios::binary);
  std::string s(n, '\0');
  f.read(s.data(), static_cast<std::streamsize>(n));
  s.resize(static_cast<size_t>(std::max<std::streamsize>(0, f.gcount())));
  return s;
}

}  // namespace

Result<std::unique_ptr<ReflectanceModel>> LoadAnyModel(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    const std::string type = RelightWebType(path);
    if (type == "ptm" || type == "hsh" || type == "sh") {
      RIG_ASSIGN_OR_RETURN(RelightCoefficients c, ReadRelightWeb(path));
      return WrapRelight(std::move(c), path + " (relight web format)");
    }
    return LoadReflectanceModel(path);
  }
  if (fs::is_regular_file(path, ec)) {
    const std::string head = FirstBytes(path, 7);
    const std::string ext = Extension(path);
    if (head.rfind("PTM", 0) == 0 || ext == ".ptm") {
      RIG_ASSIGN_OR_RETURN(RelightCoefficients c, ReadPtm(path));
      return WrapRelight(std::move(c), path);
    }
    if (head.rfind("#HSH", 0) == 0 || ext == ".rti") {
      RIG_ASSIGN_OR_RETURN(RelightCoefficients c, ReadRti(path));
      return WrapRelight(std::move(c), path);
    }
  }
  return LoadReflectanceModel(path);
}

}  // namespace rig
