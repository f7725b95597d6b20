// Fuzzes the camera-RAW decoder (process/io/raw_io.cc DecodeRawBytes through LibRaw: DNG and
// every other format LibRaw recognises by content): any bytes as a RAW frame of a bracket,
// decoded with each white-balance choice the configuration offers.
#include <cstdint>
#include <span>

#include "process/io/raw_io.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const uint8_t> bytes(data, size);
  rig::RawDecodeOptions options;
  // The first byte picks the white balance, so that every path is reached from one corpus.
  if (size > 0) {
    options.white_balance = static_cast<rig::RawWhiteBalance>(data[0] % 3);
    options.fixed_rgb = {2.0, 1.0, 1.5};
  }
  rig::RawInfo info;
  auto r = rig::DecodeRawBytes(bytes, "fuzz.dng", options, &info);
  rig::fuzz::CheckResult(r);
  if (r.ok()) {
    if (r->type() != CV_16UC3 || r->empty()) {
      std::fprintf(stderr, "fuzz: decoded RAW has type %d, %dx%d, not non-empty CV_16UC3\n",
                   r->type(), r->cols, r->rows);
      __builtin_trap();
    }
    if (!(info.white > info.black) || !(info.clipped_fraction >= 0 && info.clipped_fraction <= 1)) {
      std::fprintf(stderr, "fuzz: RAW levels black %g white %g clipped %g out of order\n",
                   info.black, info.white, info.clipped_fraction);
      __builtin_trap();
    }
  }
  return 0;
}
