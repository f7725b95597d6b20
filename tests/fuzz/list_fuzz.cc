// Fuzzes the list readers: bracket lists of `rig hdr --list` ("<image> <exposure_s>" lines,
// process/io/image_io.cc LoadBracketList) and radiance-map lists of `rig fit --list`
// ("<radiance.exr> <h_deg> <v_deg>", process/model/map_fit.cc ReadMapList). The first byte
// picks the reader (even: bracket, odd: maps); the list may name the small files of its
// folder: a.jpg, b.jpg (8x6), c.png (8x6, 16-bit), m.exr (8x6 RGB).
#include <cstdint>

#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"
#include "process/io/image_io.h"
#include "process/io/jpeg_io.h"
#include "process/model/session/map_fit.h"
#include "tests/fuzz/fuzz_support.h"

namespace {

void MakeFiles(const std::filesystem::path& dir) {
  cv::Mat a(6, 8, CV_8UC3), c(6, 8, CV_16UC3), m(6, 8, CV_32FC3);
  cv::randu(a, 0, 255);
  cv::randu(c, 0, 65535);
  cv::randu(m, 0.0f, 4.0f);
  if (!rig::WriteJpeg((dir / "a.jpg").string(), a, rig::JpegColor::kYcbcr, 90).ok() ||
      !rig::WriteJpeg((dir / "b.jpg").string(), a * 0.5, rig::JpegColor::kYcbcr, 90).ok() ||
      !cv::imwrite((dir / "c.png").string(), c) ||
      !rig::WriteRgbExr((dir / "m.exr").string(), m).ok())
    std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  MakeFiles(rig::fuzz::Scratch());
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const auto path = (rig::fuzz::Scratch() / "in.list").string();
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data + 1, size - 1));
  if (data[0] % 2 == 0) {
    auto bracket = rig::LoadBracketList(path, /*threads=*/1);
    rig::fuzz::CheckResult(bracket);
    if (bracket.ok())
      for (const auto& f : *bracket)
        if (f.image.empty() || f.source.empty() || !(f.exposure.count() > 0)) __builtin_trap();
  } else {
    auto maps = rig::ReadMapList(path);
    rig::fuzz::CheckResult(maps);
    if (maps.ok())
      for (const auto& e : *maps)
        if (!std::isfinite(e.h_deg) || !std::isfinite(e.v_deg)) __builtin_trap();
  }
  return 0;
}
