// Where a job may read and write (service_paths.h).
#include "capture/service/service_paths.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "capture/service/request_checks.h"

namespace rig {

fs::path DefaultSessionsRoot() {
  if (const char* xdg = std::getenv("XDG_DATA_HOME"); xdg && *xdg && fs::path(xdg).is_absolute())
    return fs::path(xdg) / "rig" / "sessions";
  if (const char* home = std::getenv("HOME"); home && *home)
    return fs::path(home) / ".local" / "share" / "rig" / "sessions";
  return {};
}

Result<fs::path> ResolveUnderRoot(const std::string& given, const fs::path& root, const char* what,
                                  const char* root_name) {
  if (root.empty())
    return MakeError(ErrorCode::kInvalidInput, what,
                     "the daemon has no sessions root (--sessions-root): jobs name no path");
  if (std::string problem = ClientPathProblem(given); !problem.empty())
    return MakeError(ErrorCode::kInvalidInput, what, "the path holds {}: refused", problem);
  if (given.empty()) return MakeError(ErrorCode::kInvalidInput, what, "empty path");
  std::error_code ec;
  const fs::path base = fs::weakly_canonical(root, ec);
  if (ec) return MakeError(ErrorCode::kIo, root.string(), "the sessions root: {}", ec.message());
  const fs::path p = fs::path(given).is_absolute() ? fs::path(given) : base / given;
  fs::path resolved = fs::weakly_canonical(p, ec);
  if (ec) return MakeError(ErrorCode::kInvalidInput, what, "'{}': {}", given, ec.message());
  if (!resolved.has_filename()) resolved = resolved.parent_path();
  // Strictly under the root: both resolved, the relative path climbs nowhere.
  const fs::path rel = resolved.lexically_relative(base);
  const bool under = !rel.empty() && *rel.begin() != ".." && rel != ".";
  if (!under)
    return MakeError(ErrorCode::kInvalidInput, what, "'{}' is not under {} {}{}", given,
                     root_name ? root_name : "the daemon's sessions root", base.string(),
                     root_name ? "" : " (--sessions-root)");
  return resolved;
}

Result<std::string> ReadRegularFile(const fs::path& path, size_t max_bytes, const char* what) {
  // O_NOFOLLOW: the last component is no link (those before were resolved by the caller);
  // O_NONBLOCK: opening a FIFO does not wait for a writer.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0)
    return MakeError(errno == ENOENT ? ErrorCode::kNotFound : ErrorCode::kInvalidInput, path.string(),
                     "cannot open the {}: {}", what, std::strerror(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return MakeError(ErrorCode::kInvalidInput, path.string(),
                     "the {} is not a regular file (a FIFO, device or folder): refused", what);
  }
  if (static_cast<uint64_t>(st.st_size) > max_bytes) {
    ::close(fd);
    return MakeError(ErrorCode::kInvalidInput, path.string(), "the {} is {} bytes: at most {}", what,
                     st.st_size, max_bytes);
  }
  std::string text(static_cast<size_t>(st.st_size), '\0');
  size_t got = 0;
  while (got < text.size()) {
    ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<size_t>(n);
  }
  ::close(fd);
  text.resize(got);
  return text;
}

Result<std::string> ReadJobConfigFile(const std::string& given, const fs::path& root) {
  RIG_ASSIGN_OR_RETURN(fs::path path, ResolveUnderRoot(given, root, "config"));
  return ReadRegularFile(path, kMaxJobConfigBytes, "configuration");
}

Result<std::string> ReadSessionFile(const fs::path& session, const std::string& relative,
                                    size_t max_bytes) {
  RIG_ASSIGN_OR_RETURN(fs::path path, ResolveUnderRoot(relative, session, "file", "the session"));
  // Resolved before opening, and opened without following a last link: a link planted in
  // the session that points out of it is refused either way.
  if (fs::is_symlink(session / relative))
    return MakeError(ErrorCode::kInvalidInput, (session / relative).string(),
                     "is a symbolic link: refused");
  return ReadRegularFile(path, max_bytes, "file");
}

}  // namespace rig
