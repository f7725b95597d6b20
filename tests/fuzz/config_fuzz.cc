// Fuzzes the configuration reader (config/config.cc): any bytes as a TOML file. A file it
// accepts must also survive the round trip through ToToml (what session.toml stores).
#include <cstdint>
#include <cstdio>

#include "config/config.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rig::fuzz::QuietLogs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(rig::fuzz::AsText(data, size));
  rig::ConfigResult r = rig::ParseConfig(text, "fuzz.toml");
  if (!r.ok()) {
    rig::fuzz::CheckRefusal(r.AsError());
    return 0;
  }
  // session.toml is ToToml of the resolved configuration; resume reads it back.
  const std::string stored = rig::ToToml(r.config);
  rig::ConfigResult again = rig::ParseConfig(stored, "session.toml");
  if (!again.ok()) {
    std::fprintf(stderr, "fuzz: an accepted configuration does not read back:\n%s\n---\n%s\n",
                 again.AsError().ToString().c_str(), stored.c_str());
    __builtin_trap();
  }
  if (rig::ToToml(again.config) != stored) {
    std::fprintf(stderr, "fuzz: ToToml is not stable across a round trip\n");
    __builtin_trap();
  }
  return 0;
}
