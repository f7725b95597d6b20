// rig: one executable, a table of commands.
#include <cstdio>
#include <cstring>
#include <string>

#include "build_info.h"
#include "config/console.h"
#include "process/io/image_io.h"
#include "rig/backends.h"
#include "rig/commands/command.h"

namespace {

void PrintUsage(FILE* out) {
  std::fprintf(out,
               "rig %s: capture a reflectance rig's brackets and turn them into a relightable "
               "model.\n\nUsage: rig <command> [options]   (rig <command> --help for its options)\n\n"
               "Commands:\n",
               RIG_VERSION);
  for (const auto& c : rig::Commands()) std::fprintf(out, "  %-14s %s\n", c.name, c.summary);
  std::fprintf(out, "\nOptions:\n  --version      version and the backends built in\n"
                    "  --help         this text\n");
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
  std::fprintf(stderr, "rig: unknown command '%s'\n\n", cmd.c_str());
  PrintUsage(stderr);
  return 2;
}
