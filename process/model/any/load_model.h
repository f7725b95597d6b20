// Reading a model of any family from disk, and its size there.
#pragma once

#include <cstdint>
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

}  // namespace rig
