// rig: one executable, a table of commands.
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "build_info.h"
#include "config/console.h"
#include "config/did_you_mean.h"
#include "process/io/image_io.h"
#include "rig/backends.h"
#include "rig/commands/command.h"

namespace {

void PrintUsage(FILE* out) {
  std::fprintf(out,
               "rig %s: capture a reflectance rig's brackets and turn them into a relightable "
               "model.\n\nUsage: rig <command> [options]   (rig <command> --help for its options)\n",
               RIG_VERSION);
  size_t width = 0;
  for (const auto& c : rig::Commands()) width = std::max(width, std::strlen(c.name));
  for (auto group : {rig::CommandGroup::kAcquisition, rig::CommandGroup::kProcessing,
                     rig::CommandGroup::kViewing, rig::CommandGroup::kBringUp,
                     rig::CommandGroup::kService}) {
    std::fprintf(out, "\n%s:\n", rig::CommandGroupTitle(group));
    for (const auto& c : rig::Commands())
      if (c.group == group)
        std::fprintf(out, "  %-*s  %s\n", static_cast<int>(width), c.name, c.summary);
  }
  std::fprintf(out, "\nOptions:\n  %-*s  version and the backends built in\n  %-*s  this text\n",
               static_cast<int>(width), "--version", static_cast<int>(width), "--help");
}

}  // namespace

int main(int argc, char** argv) {
  rig::ReuseFreedImageMemory();  // poses reuse the memory of the one before (docs/hdr.md)
  // Progress bars on long steps; drawn only when stderr is a terminal (config/console.h).
  rig::EnableProgress(true);
  if (argc < 2) {
    PrintUsage(stderr);
    return 2;
  }
  std::string cmd = argv[1];
  if (cmd == "--help" || cmd == "-h" || cmd == "help") {
    PrintUsage(stdout);
    return 0;
  }
  if (cmd == "--version" || cmd == "version") {
    std::string backends;
    for (const auto& b : rig::BuiltBackends()) backends += (backends.empty() ? "" : " ") + b;
    std::printf("rig %s\nbackends: %s\n", RIG_VERSION, backends.c_str());
    return 0;
  }
  for (const auto& c : rig::Commands()) {
    if (cmd == c.name) return c.run(argc - 1, argv + 1);
  }
  std::vector<std::string> names;
  for (const auto& c : rig::Commands()) names.emplace_back(c.name);
  const std::string hint = rig::DidYouMean(cmd, names);
  if (!hint.empty()) {
    std::fprintf(stderr, "rig: unknown command '%s' (did you mean '%s'?)\n", cmd.c_str(), hint.c_str());
    return 2;
  }
  std::fprintf(stderr, "rig: unknown command '%s'\n\n", cmd.c_str());
  PrintUsage(stderr);
  return 2;
}
