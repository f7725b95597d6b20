// Shared plumbing of the commands: parsing, log level, error reporting.
#include "rig/commands/command.h"

#include <cstdio>

#include "config/log.h"

namespace rig {

std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);  // 0
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 2;
  }
  return std::nullopt;
}

void AddLogLevelOption(CLI::App& app, std::string* level) {
  app.add_option("--log-level", *level,
                 "trace, debug, info, warn, error or off (default: $RIG_LOG_LEVEL, else info)");
}

std::optional<int> ApplyLogLevel(const std::string& level) {
  if (!SetLogLevel(level)) {
    std::fprintf(stderr, "rig: unknown log level '%s'\n", level.c_str());
    return 2;
  }
  return std::nullopt;
}

int ReportError(const char* command, const Error& error) {
  std::fprintf(stderr, "rig %s: %s\n", command, error.ToString().c_str());
  return error.ExitCode();
}

}  // namespace rig
