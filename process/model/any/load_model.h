// Reading a model of any family from disk, and its size there.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "config/result.h"
#include "process/model/reflectance_model.h"

namespace rig {

// Reads any family: an EXR file (harmonic), a folder with info.json (relight's web format,
// the types this build reads).
Result<std::unique_ptr<ReflectanceModel>> LoadReflectanceModel(const std::string& path);

// Bytes on disk of a model: the file, or every file of the folder.
uint64_t ModelBytesOnDisk(const std::string& path);

// The names a model folder of this project holds: info.json and plane_<n>.jpg (relight's web
// format, PCA), neural.json, decoder.bin, code_<n>.jpg and codes_<n>.png (the neural family).
bool IsModelFolderFile(const std::string& name);

// A model folder written whole (config/atomic_file.h AtomicFolder): `write` fills a fresh
// sibling ".<name>.XXXXXX", which then replaces `folder` in one exchange, so a reader sees the
// old model or the new one, never a mix (a killed writer leaves only its temporary, removed by
// the next write). An existing `folder` that is a link, not a folder, or holds any file that is
// not a model's (IsModelFolderFile) is refused (kInvalidInput, naming it): nothing of anyone
// else's is removed.
Status WriteModelFolder(const std::string& folder,
                        const std::function<Status(const std::string& dir)>& write);

}  // namespace rig
