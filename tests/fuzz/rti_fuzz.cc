// Fuzzes the reader of RTIViewer's .rti (HSH) in process/export/relight_files.cc: any bytes as
// a .rti file. A file that reads must then relight without dying (rig render, rig export).
#include <cstdint>

#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/model/light_direction.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = (rig::fuzz::Scratch() / "in.rti").string();
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data, size));
  auto c = rig::ReadRti(path);
  if (!c.ok()) {
    rig::fuzz::CheckRefusal(c.error());
    return 0;
  }
  if (static_cast<double>(c->width) * c->height > 1 << 16) return 0;
  auto model = rig::WrapRelight(std::move(*c), path);
  cv::Mat rho = model->EvaluateRho(rig::LightDirection(30, 20));
  if (rho.rows != model->height() || rho.cols != model->width()) __builtin_trap();
  return 0;
}
