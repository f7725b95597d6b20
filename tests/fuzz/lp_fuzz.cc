// Fuzzes the .lp light-file reader and the capture it names (process/model/rti.cc ReadLp,
// process/model/rti_fit.cc LoadRtiCapture: what `rig fit --lp` reads). The .lp is the input
// after its first byte, which picks --downsample (1..4); the folder holds small images it may
// name: a.jpg, b.jpg (8x6), c.png (8x6), d.jpg (3x2), t.jpg (a.jpg cut short), g.png (grey).
#include <cstdint>

#include <opencv2/imgcodecs.hpp>

#include "process/io/jpeg_io.h"
#include "process/model/any/rti_fit.h"
#include "tests/fuzz/fuzz_support.h"

namespace {

void MakeImages(const std::filesystem::path& dir) {
  cv::Mat a(6, 8, CV_8UC3), b(6, 8, CV_8UC3), d(2, 3, CV_8UC3), g(6, 8, CV_8UC1);
  cv::randu(a, 0, 255);
  cv::randu(b, 0, 255);
  cv::randu(d, 0, 255);
  cv::randu(g, 0, 255);
  if (!rig::WriteJpeg((dir / "a.jpg").string(), a, rig::JpegColor::kYcbcr, 90).ok() ||
      !rig::WriteJpeg((dir / "b.jpg").string(), b, rig::JpegColor::kYcbcr, 90).ok() ||
      !rig::WriteJpeg((dir / "d.jpg").string(), d, rig::JpegColor::kYcbcr, 90).ok() ||
      !cv::imwrite((dir / "c.png").string(), a) || !cv::imwrite((dir / "g.png").string(), g))
    std::abort();
  auto bytes = rig::EncodeJpeg(a, rig::JpegColor::kYcbcr, 90);
  if (!bytes.ok()) std::abort();
  rig::fuzz::WriteFile(dir / "t.jpg", std::string_view(reinterpret_cast<const char*>(bytes->data()),
                                                       bytes->size() / 2));
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  MakeImages(rig::fuzz::Scratch());
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const int downsample = 1 + data[0] % 4;
  const auto path = (rig::fuzz::Scratch() / "in.lp").string();
  rig::fuzz::WriteFile(path, rig::fuzz::AsText(data + 1, size - 1));
  auto capture = rig::LoadRtiCapture(path, downsample);
  rig::fuzz::CheckResult(capture);
  if (capture.ok() && capture->samples.lights() != static_cast<int>(capture->entries.size()))
    __builtin_trap();
  return 0;
}
