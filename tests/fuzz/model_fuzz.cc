// Fuzzes the model reader (process/model/model.cc LoadModel through LoadReflectanceModel):
// any bytes as model/model.exr. A model that loads must then evaluate and relight without
// dying — what `rig render` does with it next.
#include <cmath>
#include <cstdint>

#include "process/model/light_direction.h"
#include "process/model/reflectance_model.h"
#include "process/model/any/load_model.h"
#include "tests/fuzz/exr_budget.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = (rig::fuzz::Scratch() / "model.exr").string();
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data, size));
  if (!rig::fuzz::ExrWithinFuzzBudget(path)) return -1;
  auto model = rig::LoadReflectanceModel(path);
  if (!model.ok()) {
    rig::fuzz::CheckRefusal(model.error());
    return 0;
  }
  const rig::ReflectanceModel& m = **model;
  // Keep each input cheap: relight only small models (the reader's size limits are checked
  // by the inputs that fail to load, not here).
  if (static_cast<double>(m.width()) * m.height() > 1 << 16) return 0;
  const rig::Vec3 d = rig::LightDirection(30, 20, m.light_frame());
  cv::Mat rho = m.EvaluateRho(d);
  if (rho.rows != m.height() || rho.cols != m.width()) __builtin_trap();
  cv::Mat sum;
  m.AddLamp(d, {1, 1, 1}, &sum);
  (void)m.CheckRegion(d);
  (void)m.Describe();
  return 0;
}
