// The rig command table: one entry per command, each command in its own file.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "config/result.h"

namespace rig {

// The groups `rig --help` lists the commands under, in this order.
enum class CommandGroup { kAcquisition, kProcessing, kViewing, kBringUp, kService };
const char* CommandGroupTitle(CommandGroup group);

struct Command {
  CommandGroup group;
  const char* name;
  const char* summary;
  // argv[0] is the command's name; returns the process exit code (0, 1, 2, 128+signal).
  int (*run)(int argc, char** argv);
};

// Every command, in the order `rig --help` lists them. An explicit table: no static
// self-registration (static libraries drop registrars nobody references).
const std::vector<Command>& Commands();

// Parses a command's own options. Returns an exit code when the command must stop now
// (0 after --help, 2 after a usage error), nothing when it should go on. A mistyped option
// ("--ligth") is named with the closest one the command has ("did you mean '--light'?").
std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv);

// Adds --log-level to a command; call ApplyLogLevel after parsing.
void AddLogLevelOption(CLI::App& app, std::string* level);
// Returns an exit code (2) if the level is unknown.
std::optional<int> ApplyLogLevel(const std::string& level);

// Prints "rig <command>: <error>" and returns the error's exit code (2 bad input, 1 other).
int ReportError(const char* command, const Error& error);

// The command functions (one file each in rig/commands/).
int RunCheckConfig(int argc, char** argv);
int RunCapture(int argc, char** argv);
int RunResume(int argc, char** argv);
int RunProcess(int argc, char** argv);
int RunFit(int argc, char** argv);
int RunRender(int argc, char** argv);
int RunTonemap(int argc, char** argv);
int RunView(int argc, char** argv);     // rig/commands/view.cc
int RunHdr(int argc, char** argv);
int RunRatioCheck(int argc, char** argv);
int RunEvaluate(int argc, char** argv);
// Bring-up on a real rig (rig/commands/{devices,jog,home,lamp,shot}.cc).
int RunDevices(int argc, char** argv);
int RunJog(int argc, char** argv);
int RunHome(int argc, char** argv);
int RunLamp(int argc, char** argv);
int RunShot(int argc, char** argv);
int RunDaemon(int argc, char** argv);  // rig/commands/daemon.cc
int RunStatus(int argc, char** argv);  // rig/commands/status.cc
int RunCalibrateLights(int argc, char** argv);  // rig/commands/calibrate_lights.cc
int RunNormals(int argc, char** argv);          // rig/commands/normals.cc
int RunLights(int argc, char** argv);           // rig/commands/lights.cc

}  // namespace rig
