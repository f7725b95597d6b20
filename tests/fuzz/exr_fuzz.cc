// Fuzzes the EXR reader (process/io/exr_io.cc): any bytes as a radiance map; the header alone
// (ReadExrAttributes), every channel (ReadExr) and the RGB convenience (ReadRgbExr).
#include <cstdint>

#include "process/io/exr_io.h"
#include "tests/fuzz/exr_budget.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = (rig::fuzz::Scratch() / "in.exr").string();
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data, size));
  if (!rig::fuzz::ExrWithinFuzzBudget(path)) return -1;
  rig::fuzz::CheckResult(rig::ReadExrAttributes(path));
  auto image = rig::ReadExr(path, /*threads=*/1);
  rig::fuzz::CheckResult(image);
  if (image.ok()) {
    if (image->channels.size() != image->channel_names.size()) __builtin_trap();
    for (const auto& c : image->channels)
      if (c.rows != image->height || c.cols != image->width || c.type() != CV_32FC1)
        __builtin_trap();
  }
  rig::fuzz::CheckResult(rig::ReadRgbExr(path, nullptr, /*threads=*/1));
  return 0;
}
