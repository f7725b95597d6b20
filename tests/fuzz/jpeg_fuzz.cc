// Fuzzes the libjpeg reader (process/io/jpeg_io.cc): any bytes as a JPEG, in memory and, by
// rows, from a file (JpegReader: what relight's planes and `rig fit --lp` read).
#include <cstdint>

#include "process/io/jpeg_io.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::vector<uint8_t> bytes(data, data + size);
  rig::fuzz::CheckResult(rig::DecodeJpeg(bytes, "fuzz.jpg"));

  const auto path = rig::fuzz::Scratch() / "in.jpg";
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data, size));
  auto reader = rig::JpegReader::Open(path.string());
  if (!reader.ok()) {
    rig::fuzz::CheckRefusal(reader.error());
    return 0;
  }
  cv::Mat rows;
  for (int y = 0; y < (*reader)->height(); y += 16) {
    rig::Status st = (*reader)->Read(std::min(16, (*reader)->height() - y), &rows);
    if (!st.ok()) {
      rig::fuzz::CheckRefusal(st.error());
      break;
    }
  }
  return 0;
}
