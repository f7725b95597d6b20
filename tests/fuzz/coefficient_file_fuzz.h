// Shared by the fuzzers of RTIViewer's files (ptm_fuzz.cc, rti_fuzz.cc): any bytes as the file;
// a file that reads must then relight without dying (rig render, rig export).
#pragma once

#include <cstdint>
#include <string>

#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/model/light_direction.h"
#include "tests/fuzz/fuzz_support.h"

namespace rig::fuzz {

// `read(path)` is the reader under test (ReadPtm, ReadRti); `name` the scratch file's name.
template <typename Reader>
int FuzzCoefficientFile(const uint8_t* data, size_t size, const char* name, Reader read) {
  const auto path = (Scratch() / name).string();
  WriteFile(path, AsText(data, size));
  auto c = read(path);
  if (!c.ok()) {
    CheckRefusal(c.error());
    return 0;
  }
  if (static_cast<double>(c->width) * c->height > 1 << 16) return 0;
  auto model = WrapRelight(std::move(*c), path);
  cv::Mat rho = model->EvaluateRho(LightDirection(30, 20));
  if (rho.rows != model->height() || rho.cols != model->width()) __builtin_trap();
  return 0;
}

}  // namespace rig::fuzz
