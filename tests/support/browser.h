// The browser the page tests drive (../shared/docs/browser-testing.md).
#pragma once

#include <cstdlib>
#include <filesystem>
#include <string>

namespace rig::testing {

// Debian's chromium (or $RIG_CHROMIUM); empty when none is installed (the test skips).
inline std::string Chromium() {
  if (const char* env = std::getenv("RIG_CHROMIUM")) return env;
  for (const char* p : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (std::filesystem::exists(p)) return p;
  return "";
}

}  // namespace rig::testing
