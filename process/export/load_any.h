// Reading a model of any format this build knows: relight's web format (ptm, hsh), .ptm,
// .rti, and then everything LoadReflectanceModel reads (EXR, bilinear/mrgb folders, neural).
#pragma once

#include <memory>
#include <string>

#include "config/result.h"
#include "process/model/reflectance_model.h"
#include "process/model/any/load_model.h"

namespace rig {

// A .ptm / .rti file (by its first bytes, or its extension), a folder whose info.json says
// type ptm or hsh, else LoadReflectanceModel(path).
Result<std::unique_ptr<ReflectanceModel>> LoadAnyModel(const std::string& path);

}  // namespace rig
