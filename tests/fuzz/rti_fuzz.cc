// Fuzzes the reader of RTIViewer's .rti (HSH) in process/export/relight_files.cc: any bytes as
// a .rti file. A file that reads must then relight without dying (rig render, rig export).
#include <cstdint>
#include <string>

#include "tests/fuzz/coefficient_file_fuzz.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return rig::fuzz::FuzzCoefficientFile(data, size, "in.rti",
                                        [](const std::string& p) { return rig::ReadRti(p); });
}
