// Fuzzes the readers of model folders (info.json + plane_N.jpg): relight's web format
// (ReadRelightWeb, types ptm, hsh and sh) and the PCA types (PcaModel::Load: bilinear and rbf,
// mrgb and mycc — ours and relight's), both reached through
// LoadAnyModel as `rig render` and `rig export` reach them. The input is info.json, then each
// plane after a line "--8<-- plane_N.jpg" (fuzz_support.h SplitParts).
#include <cstdint>

#include "process/export/load_any.h"
#include "process/model/light_direction.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace fs = std::filesystem;
  const fs::path folder = rig::fuzz::Scratch() / "model";
  std::error_code ec;
  fs::remove_all(folder, ec);
  fs::create_directories(folder);
  const auto parts = rig::fuzz::SplitParts(rig::fuzz::AsText(data, size), "info.json");
  for (size_t i = 0; i < parts.size() && i < 64; ++i)
    rig::fuzz::WriteFile(folder / (i == 0 ? "info.json" : rig::fuzz::SafeName(parts[i].name, i)),
                         parts[i].bytes);
  auto model = rig::LoadAnyModel(folder.string());
  if (!model.ok()) {
    rig::fuzz::CheckRefusal(model.error());
    return 0;
  }
  const rig::ReflectanceModel& m = **model;
  if (static_cast<double>(m.width()) * m.height() > 1 << 16) return 0;
  cv::Mat rho = m.EvaluateRho(rig::LightDirection(30, 20, m.light_frame()));
  if (rho.rows != m.height() || rho.cols != m.width()) __builtin_trap();
  return 0;
}
