// Fuzzes the EXIF reader (process/io/exif.cc, libexif): any bytes as a photograph whose lens
// `rig calibrate-lights` reads. What it accepts must give a usable camera or none.
#include <cmath>
#include <cstdint>
#include <cstdlib>

#include "process/io/exif.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto path = rig::fuzz::Scratch() / "in.jpg";
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data, size));
  auto lens = rig::ReadExifLens(path.string());
  if (!lens.ok()) {
    rig::fuzz::CheckRefusal(lens.error());
    return 0;
  }
  for (auto [w, h] : {std::pair{640, 480}, std::pair{1, 1}, std::pair{40000, 30000}}) {
    const rig::ExifFocal f = rig::FocalFromExif(*lens, w, h);
    if (f.focal_mm != 0 && !(std::isfinite(f.focal_mm) && f.focal_mm > 0 && f.focal_mm <= 5000 &&
                             std::isfinite(f.sensor_width_mm) && f.sensor_width_mm >= 0.5 &&
                             f.sensor_width_mm <= 500))
      std::abort();
    if (f.focal_mm > 0 && f.how.empty()) std::abort();
  }
  return 0;
}
