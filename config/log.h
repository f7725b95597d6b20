// Logging: one spdlog logger per module (capture, motion, lamp, session, process, sim),
// all writing to the console and, once a session is open, to SESSION/log.txt.
#pragma once

#include <memory>
#include <string>

#include <spdlog/spdlog.h>

namespace rig {

// The module's logger ("capture", "motion", "lamp", "session", "process", "sim", "rig").
std::shared_ptr<spdlog::logger> Log(const std::string& module);

// Level from a name ("trace" ... "off"); empty: from $RIG_LOG_LEVEL, else "info".
// Returns false for an unknown name.
bool SetLogLevel(const std::string& level);

// Adds SESSION/log.txt (appending) to every logger. Returns false if it cannot be opened.
bool AddLogFile(const std::string& path);

}  // namespace rig
