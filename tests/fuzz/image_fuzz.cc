// Fuzzes the camera-file decoder (process/io/image_io.cc DecodeImageBytes: JPEG, PNG, TIFF
// through OpenCV and libjpeg, truncation checks): any bytes as a frame of a bracket.
#include <cstdint>

#include "process/io/image_io.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<uchar> bytes(data, data + size);
  auto r = rig::DecodeImageBytes(bytes, "fuzz.img");
  rig::fuzz::CheckResult(r);
  if (r.ok() && r->type() != CV_8UC3 && r->type() != CV_16UC3) {
    std::fprintf(stderr, "fuzz: decoded frame has type %d, not CV_8UC3/CV_16UC3\n", r->type());
    __builtin_trap();
  }
  return 0;
}
