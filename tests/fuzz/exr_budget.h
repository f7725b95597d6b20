// The fuzzers' memory budget for EXR inputs: a header may claim up to what ReadExr accepts
// (2^28 pixels per channel), which the reader allocates before it finds the pixels missing.
// That is its contract, not a bug, but a fuzzer at 2 GB RSS cannot afford it per input, so
// inputs whose header claims more than 2^22 channel-pixels are skipped (the reader's own bound
// is what rejects beyond it, and the sanitizer suite tests that).
#pragma once

#include <cstdint>
#include <string>

#include <ImfChannelList.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

#include "process/io/exr_io.h"

namespace rig::fuzz {

inline bool ExrWithinFuzzBudget(const std::string& path) {
  // The reader's own header checks first (sizes of attributes against the file), so that
  // this look at the header does not do what the reader refuses to.
  if (!ReadExrAttributes(path).ok()) return true;
  try {
    Imf::InputFile in(path.c_str(), 1);
    const auto& dw = in.header().dataWindow();
    const int64_t w = int64_t{dw.max.x} - dw.min.x + 1, h = int64_t{dw.max.y} - dw.min.y + 1;
    int64_t channels = 0;
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it)
      ++channels;
    return w <= 0 || h <= 0 || (w <= (1 << 16) && h <= (1 << 16) && w * h * channels <= (1 << 22));
  } catch (...) {
    return true;  // the reader refuses it by itself
  }
}

}  // namespace rig::fuzz
