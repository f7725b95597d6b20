// Test support: running the rig binary.
#include "tests/support/run_rig.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <fmt/format.h>
#include <gtest/gtest.h>

namespace rig::testing {

CommandResult RunRig(const std::string& args) {
  const char* bin = std::getenv("RIG_BINARY");
  EXPECT_NE(bin, nullptr) << "RIG_BINARY is not set (run through ctest)";
  if (!bin) return {};
  std::string cmd = std::string(bin) + " " + args + " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  CommandResult r;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, p)) r.output.append(buf, n);
  int st = pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : (WIFSIGNALED(st) ? 128 + WTERMSIG(st) : -1);
  return r;
}

std::string SourceDir() {
  const char* s = std::getenv("RIG_SOURCE_DIR");
  return s ? s : ".";
}

std::string SharedDir() {
  const char* s = std::getenv("RIG_SHARED_DIR");
  return s ? s : SourceDir() + "/../shared";
}

std::string FreshTempDir(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / fmt::format("rig_{}_{}", name, ::getpid());
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p.string();
}

}  // namespace rig::testing
