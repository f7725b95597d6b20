// What every libFuzzer harness of tests/fuzz/ shares: a private scratch folder for readers that
// need a path, quiet logs, and the check that a reader's refusal is a proper error.
#pragma once

#include <stdlib.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "config/log.h"
#include "config/result.h"

namespace rig::fuzz {

namespace fs = std::filesystem;

// One scratch folder per process (libFuzzer's -fork/-jobs workers each get their own), removed
// at exit. Harnesses write the input there when the reader wants a path.
inline const fs::path& Scratch() {
  static const fs::path dir = [] {
    std::string tmpl = (fs::temp_directory_path() / "rig-fuzz-XXXXXX").string();
    if (::mkdtemp(tmpl.data()) == nullptr) {
      std::perror("mkdtemp");
      std::abort();
    }
    static const fs::path keep = tmpl;
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(keep, ec);
    });
    return fs::path(tmpl);
  }();
  return dir;
}

inline void WriteFile(const fs::path& path, std::string_view bytes) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!f) {
    std::fprintf(stderr, "fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
}

inline std::string_view AsText(const uint8_t* data, size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// Logs off (a reader's warnings would otherwise be printed for every input), unless
// RIG_LOG_LEVEL is set.
inline void QuietLogs() {
  if (std::getenv("RIG_LOG_LEVEL") == nullptr) SetLogLevel("off");
}

// A refusal must be a reported error with a message (a "wrong exit code" otherwise: the command
// would print nothing useful). Traps so that libFuzzer records the input.
inline void CheckRefusal(const Error& e) {
  if (e.message.empty()) {
    std::fprintf(stderr, "fuzz: error without a message (code %d, context '%s')\n",
                 static_cast<int>(e.code), e.context.c_str());
    __builtin_trap();
  }
  // Every input is a file given to us, so a refusal is bad input: exit code 2 (kInvalidInput,
  // kNotFound, kCorrupt), never 1 ("the work failed") nor an internal error.
  if (e.ExitCode() != 2) {
    std::fprintf(stderr, "fuzz: bad input refused with exit code %d (%s): %s\n", e.ExitCode(),
                 ErrorCodeName(e.code), e.ToString().c_str());
    __builtin_trap();
  }
}

template <typename T>
void CheckResult(const Result<T>& r) {
  if (!r.ok()) CheckRefusal(r.error());
}

// Splits an input into named parts: "name\n" headers after a line "--8<-- " (the seeds use
// this to carry a folder of several files in one input). Text before the first marker is part
// `first`.
struct Part {
  std::string name;
  std::string bytes;
};
inline std::vector<Part> SplitParts(std::string_view input, const std::string& first) {
  static constexpr std::string_view kMark = "\n--8<-- ";
  std::vector<Part> parts;
  std::string name = first;
  size_t pos = 0;
  while (true) {
    const size_t m = input.find(kMark, pos);
    parts.push_back({name, std::string(input.substr(pos, m == std::string_view::npos ? m : m - pos))});
    if (m == std::string_view::npos) break;
    const size_t name_begin = m + kMark.size();
    const size_t nl = input.find('\n', name_begin);
    name = std::string(input.substr(name_begin, nl == std::string_view::npos ? nl : nl - name_begin));
    if (nl == std::string_view::npos) break;
    pos = nl + 1;
  }
  return parts;
}

// A part's name made safe as a file name inside the scratch folder (no folders, no "..").
inline std::string SafeName(const std::string& name, size_t index) {
  std::string out;
  for (char c : name)
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '-') out += c;
  if (out.empty() || out[0] == '.' || out.size() > 64) out = "part" + std::to_string(index);
  return out;
}

}  // namespace rig::fuzz
