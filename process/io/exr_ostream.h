// OpenEXR's output stream over the project's one writer (config/atomic_file.h): an EXR is
// written into a temporary with a fresh name (O_EXCL|O_NOFOLLOW) and moved over its target by
// Commit(), never through a link, never seen half written.
#pragma once

#include <cstdint>
#include <filesystem>

#include <ImfIO.h>

#include "config/atomic_file.h"
#include "config/result.h"

namespace rig {

class AtomicExrStream : public Imf::OStream {
 public:
  // `file` from AtomicFile::Create; the stream's name (in OpenEXR's messages) is the target.
  explicit AtomicExrStream(AtomicFile file);
  // OpenEXR's interface: a failed write throws Iex::IoExc naming the file.
  void write(const char c[], int n) override;
  uint64_t tellp() override;
  void seekp(uint64_t pos) override;
  // After the Imf::OutputFile is destroyed (it writes its offset table then).
  Status Commit(double* sync_s = nullptr) { return file_.Commit(sync_s); }

 private:
  AtomicFile file_;
};

}  // namespace rig
