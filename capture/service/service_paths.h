// Where a job may read and write: every session lies under the daemon's sessions root
// (`rig daemon --sessions-root`), and a configuration named by path is a regular file there,
// read with its size checked first, without following a link and without blocking (a FIFO
// never hangs the API). Paths from a client holding a NUL or a control character are refused.
#pragma once

#include <string>

#include "config/result.h"
#include <filesystem>

namespace rig {

namespace fs = std::filesystem;

inline constexpr size_t kMaxJobConfigBytes = size_t{1} << 20;

// $XDG_DATA_HOME/rig/sessions, else ~/.local/share/rig/sessions (empty when neither
// XDG_DATA_HOME nor HOME is set).
fs::path DefaultSessionsRoot();

// `given` (absolute, or relative to `root`) resolved (weakly_canonical: links followed as far
// as they exist) and checked to lie strictly under the resolved `root`. `what` names the
// field in messages ("session", "config"), `root_name` the root ("the daemon's sessions root").
Result<fs::path> ResolveUnderRoot(const std::string& given, const fs::path& root, const char* what,
                                  const char* root_name = nullptr);

// The text of a job's configuration file `given`, under `root` (ResolveUnderRoot): a regular
// file, not a link, of at most kMaxJobConfigBytes. The errors name the file, never its content.
Result<std::string> ReadJobConfigFile(const std::string& given, const fs::path& root);

// The file `relative` of a session folder: resolved under `session` (ResolveUnderRoot), not a
// link, a regular file of at most `max_bytes`.
Result<std::string> ReadSessionFile(const fs::path& session, const std::string& relative,
                                    size_t max_bytes);

// `path` (resolved by the caller) opened with O_NOFOLLOW | O_NONBLOCK, a regular file of at
// most `max_bytes`, read whole. `what` names it in messages ("configuration").
Result<std::string> ReadRegularFile(const fs::path& path, size_t max_bytes, const char* what);

}  // namespace rig
