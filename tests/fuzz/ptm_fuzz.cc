// Fuzzes the reader of RTIViewer's .ptm (PTM 1.2, RGB and LRGB) in process/export/relight_files.cc: any bytes as
// a .ptm file. A file that reads must then relight without dying (rig render, rig export).
#include <cstdint>
#include <string>

#include "tests/fuzz/coefficient_file_fuzz.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return rig::fuzz::FuzzCoefficientFile(data, size, "in.ptm",
                                        [](const std::string& p) { return rig::ReadPtm(p); });
}
