// Shared plumbing of the commands: parsing, log level, error reporting.
#include "rig/commands/command.h"

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "config/did_you_mean.h"
#include "config/log.h"

namespace rig {

namespace {

void CollectLongNames(const CLI::App& app, std::vector<std::string>* names) {
  for (const CLI::Option* o : app.get_options())
    for (const std::string& n : o->get_lnames()) names->push_back("--" + n);
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    CollectLongNames(*sub, names);
}

// The first "--word" on the command line that no option of the command (or its subcommands)
// has, and the closest one it has: "" when every --word is known.
std::string UnknownOptionHint(const CLI::App& app, int argc, char** argv) {
  std::vector<std::string> known;
  CollectLongNames(app, &known);
  for (int i = 1; i < argc; ++i) {
    std::string word = argv[i];
    if (word == "--") break;
    if (word.rfind("--", 0) != 0) continue;
    word = word.substr(0, word.find('='));
    if (std::find(known.begin(), known.end(), word) != known.end()) continue;
    const std::string hint = DidYouMean(word, known);
    return fmt::format("unknown option '{}'{}", word, hint.empty() ? "" : " (did you mean '" + hint + "'?)");
  }
  return "";
}

}  // namespace

std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);  // 0
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    const std::string unknown = UnknownOptionHint(app, argc, argv);
    if (!unknown.empty()) {
      // The command's own name ("rig collection init"), not just its word on the command line.
      const std::string name = app.get_name().empty() ? std::string("rig ") + argv[0] : app.get_name();
      std::fprintf(stderr, "%s: %s\nRun with --help for more information.\n", name.c_str(), unknown.c_str());
      return 2;
    }
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
