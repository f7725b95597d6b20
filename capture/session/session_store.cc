// Durable storage of a session: atomic writes, the fsync'd journal, the session lock.
#include "capture/session/session_store.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "config/log.h"
#include "config/settings.h"

namespace rig {
namespace {

Error Errno(const fs::path& where, const char* what) {
  return MakeError(ErrorCode::kIo, where.string(), "{}: {}", what, std::strerror(errno));
}

Status WriteAll(int fd, const uint8_t* data, size_t size, const fs::path& where) {
  while (size > 0) {
    ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Errno(where, "write failed");
    }
    data += n;
    size -= static_cast<size_t>(n);
  }
  return Ok();
}

std::string UtcNow() {
  auto now = std::chrono::system_clock::now();
  auto secs = std::chrono::system_clock::to_time_t(now);
  auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()) % 1000;
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
  return fmt::format("{}.{:03d}Z", buf, static_cast<int>(ms.count()));
}

// Closes a descriptor when it goes out of scope.
struct Fd {
  int fd = -1;
  Fd() = default;
  explicit Fd(int f) : fd(f) {}
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  Fd(Fd&& o) noexcept : fd(o.fd) { o.fd = -1; }
  Fd& operator=(Fd&& o) noexcept {
    std::swap(fd, o.fd);
    return *this;
  }
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

Error LinkRefused(const fs::path& where) {
  return MakeError(ErrorCode::kInvalidInput, where.string(),
                   "is a symbolic link or not of its kind; a session's parts must be inside "
                   "it, so nothing is read or written through it");
}

// The components of a relative path ("frames/h000_v00/0_0.01000.jpg").
std::vector<std::string> Components(const std::string& rel) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= rel.size()) {
    size_t slash = rel.find('/', start);
    if (slash == std::string::npos) slash = rel.size();
    out.push_back(rel.substr(start, slash - start));
    start = slash + 1;
  }
  return out;
}

// Opens the folder `parts` (all but none of them links) below `root`; creates missing ones
// when `create`.
Result<Fd> OpenFolderInside(const fs::path& root, const std::vector<std::string>& parts,
                            bool create) {
  Fd dir(::open(root.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.fd < 0) return Errno(root, "cannot open session folder");
  fs::path where = root;
  for (const auto& part : parts) {
    where /= part;
    int fd = ::openat(dir.fd, part.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0 && errno == ENOENT && create) {
      if (::mkdirat(dir.fd, part.c_str(), 0755) != 0 && errno != EEXIST)
        return Errno(where, "cannot create folder");
      fd = ::openat(dir.fd, part.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    }
    if (fd < 0) {
      if (errno == ELOOP || errno == ENOTDIR) return LinkRefused(where);
      return Errno(where, "cannot open folder");
    }
    dir = Fd(fd);
  }
  return dir;
}

Result<std::pair<Fd, std::string>> SplitInside(const fs::path& root, const std::string& rel,
                                               bool create) {
  const std::string problem = SessionRelativePathProblem(rel);
  if (!problem.empty())
    return MakeError(ErrorCode::kInvalidInput, (root / rel).string(), "path {}", problem);
  std::vector<std::string> parts = Components(rel);
  std::string name = parts.back();
  parts.pop_back();
  RIG_ASSIGN_OR_RETURN(Fd dir, OpenFolderInside(root, parts, create));
  return std::make_pair(std::move(dir), std::move(name));
}

// The session's write of `name` in the open folder `dir_fd`: a link or a folder at the name is
// refused (a session's parts are its own), then the project's one writer (config/atomic_file.h).
Status WriteAtomicAt(int dir_fd, const fs::path& dir, const std::string& name,
                     std::span<const uint8_t> bytes, bool overwrite) {
  struct stat st {};
  if (overwrite && ::fstatat(dir_fd, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 &&
      !S_ISREG(st.st_mode))
    return LinkRefused(dir / name);
  return WriteFileAtomicAt(dir_fd, dir, name, bytes, overwrite);
}

// Reads a whole open file, at most `limit` bytes.
Result<std::string> ReadAllFd(int fd, const fs::path& where, size_t limit) {
  std::string text;
  char buf[1 << 16];
  for (;;) {
    ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Errno(where, "read failed");
    }
    if (n == 0) break;
    if (text.size() + static_cast<size_t>(n) > limit)
      return MakeError(ErrorCode::kCorrupt, where.string(), "larger than {} bytes", limit);
    text.append(buf, static_cast<size_t>(n));
  }
  return text;
}

}  // namespace

uint32_t Crc32(std::span<const uint8_t> bytes) {
  uLong crc = crc32(0L, Z_NULL, 0);
  // zlib takes uInt lengths; feed large buffers in pieces.
  size_t off = 0;
  while (off < bytes.size()) {
    uInt n = static_cast<uInt>(std::min<size_t>(bytes.size() - off, 1u << 30));
    crc = crc32(crc, bytes.data() + off, n);
    off += n;
  }
  return static_cast<uint32_t>(crc);
}

Status WriteSessionFile(const fs::path& root, const std::string& rel,
                        std::span<const uint8_t> bytes, bool overwrite) {
  RIG_ASSIGN_OR_RETURN(auto dir, SplitInside(root, rel, /*create=*/true));
  return WriteAtomicAt(dir.first.fd, (root / rel).parent_path(), dir.second, bytes, overwrite);
}

Result<std::vector<uint8_t>> ReadSessionFile(const fs::path& root, const std::string& rel) {
  RIG_ASSIGN_OR_RETURN(auto dir, SplitInside(root, rel, /*create=*/false));
  const fs::path path = root / rel;
  Fd fd(::openat(dir.first.fd, dir.second.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC));
  if (fd.fd < 0) {
    if (errno == ELOOP) return LinkRefused(path);
    return MakeError(ErrorCode::kNotFound, path.string(), "cannot open file: {}", std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd.fd, &st) != 0 || !S_ISREG(st.st_mode)) return LinkRefused(path);
  RIG_ASSIGN_OR_RETURN(std::string text, ReadAllFd(fd.fd, path, size_t{1} << 34));
  return std::vector<uint8_t>(text.begin(), text.end());
}

Result<fs::path> EnsureSessionFolder(const fs::path& root, const std::string& rel) {
  const std::string problem = SessionRelativePathProblem(rel);
  if (!problem.empty())
    return MakeError(ErrorCode::kInvalidInput, (root / rel).string(), "path {}", problem);
  RIG_ASSIGN_OR_RETURN(Fd dir, OpenFolderInside(root, Components(rel), /*create=*/true));
  return root / rel;
}

Status CheckSessionTree(const fs::path& root) {
  auto check = [&](const fs::path& p, bool folder) -> Status {
    struct stat st {};
    if (::lstat(p.c_str(), &st) != 0) return Ok();  // absent: made when needed
    if (folder ? !S_ISDIR(st.st_mode) : !S_ISREG(st.st_mode)) return LinkRefused(p);
    return Ok();
  };
  for (const char* f : {".lock", "journal.jsonl", "log.txt", "session.toml"})
    RIG_TRY(check(root / f, false));
  for (const char* d : {"frames", "hdr", "calib", "model", "truth", "render"})
    RIG_TRY(check(root / d, true));
  std::error_code ec;
  if (fs::is_directory(fs::symlink_status(root / "frames", ec)))
    for (auto it = fs::directory_iterator(root / "frames", ec); !ec && it != fs::directory_iterator();
         it.increment(ec))
      RIG_TRY(check(it->path(), true));
  return Ok();
}

Result<std::vector<uint8_t>> ReadFileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeError(ErrorCode::kNotFound, path.string(), "cannot open file");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) return MakeError(ErrorCode::kIo, path.string(), "read failed");
  return bytes;
}

// ---- Journal ---------------------------------------------------------------------------

Result<JournalContents> Journal::Read(const fs::path& path) {
  Fd fd(::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC));
  if (fd.fd < 0) {
    if (errno == ELOOP) return LinkRefused(path);
    return MakeError(ErrorCode::kNotFound, path.string(), "cannot open journal");
  }
  struct stat st {};
  if (::fstat(fd.fd, &st) != 0 || !S_ISREG(st.st_mode)) return LinkRefused(path);
  RIG_ASSIGN_OR_RETURN(std::string text, ReadAllFd(fd.fd, path, kMaxJournalBytes));
  return ParseJournal(text, path.string());
}

Result<Journal> Journal::Open(const fs::path& path, JournalContents* contents) {
  int raw = ::open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (raw < 0) {
    if (errno == ELOOP) return LinkRefused(path);
    return Errno(path, "cannot open journal");
  }
  Fd fd(raw);
  struct stat st {};
  if (::fstat(fd.fd, &st) != 0 || !S_ISREG(st.st_mode)) return LinkRefused(path);
  RIG_ASSIGN_OR_RETURN(std::string text, ReadAllFd(fd.fd, path, kMaxJournalBytes));
  RIG_ASSIGN_OR_RETURN(JournalContents c, ParseJournal(text, path.string()));
  if (c.torn_tail) {
    for (const auto& w : c.warnings) Log("session")->warn("{}", w);
    if (::ftruncate(fd.fd, static_cast<off_t>(c.valid_bytes)) != 0)
      return Errno(path, "cannot cut the torn journal tail");
  }
  if (::fsync(fd.fd) != 0) return Errno(path, "fsync failed");
  RIG_TRY(FsyncDirectory(path.parent_path().empty() ? fs::path(".") : path.parent_path()));
  if (contents) *contents = std::move(c);
  Journal j(path, fd.fd);
  fd.fd = -1;
  return j;
}

Journal::Journal(Journal&& o) noexcept : path_(std::move(o.path_)), fd_(o.fd_) { o.fd_ = -1; }
Journal& Journal::operator=(Journal&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(o.path_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}
Journal::~Journal() {
  if (fd_ >= 0) ::close(fd_);
}

Status Journal::Append(nlohmann::json record) {
  RIG_CHECK(fd_ >= 0, "append to a closed journal");
  record["t"] = UtcNow();
  std::string line = record.dump() + "\n";
  // One write() of the whole line on an O_APPEND descriptor.
  RIG_TRY(WriteAll(fd_, reinterpret_cast<const uint8_t*>(line.data()), line.size(), path_));
  if (::fdatasync(fd_) != 0) return Errno(path_, "fsync of journal failed");
  return Ok();
}

// ---- Lock ------------------------------------------------------------------------------

Result<SessionLock> SessionLock::Acquire(const fs::path& session_dir) {
  fs::path p = session_dir / ".lock";
  int fd = ::open(p.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_CLOEXEC, 0644);
  if (fd < 0) {
    if (errno == ELOOP) return LinkRefused(p);
    return Errno(p, "cannot open session lock");
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return LinkRefused(p);
  }
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    int err = errno;
    char buf[32] = {0};
    ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
    ::close(fd);
    if (err == EWOULDBLOCK) {
      std::string holder = n > 0 ? std::string(buf, static_cast<size_t>(n)) : "?";
      while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' ')) holder.pop_back();
      return MakeError(ErrorCode::kBusy, session_dir.string(),
                       "session is in use by another rig process (pid {}); refusing to interleave",
                       holder);
    }
    errno = err;
    return Errno(p, "cannot lock session");
  }
  std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) == 0) {
    ssize_t ignored = ::pwrite(fd, pid.data(), pid.size(), 0);
    (void)ignored;
  }
  return SessionLock(fd);
}

SessionLock::SessionLock(SessionLock&& o) noexcept : fd_(o.fd_) { o.fd_ = -1; }
SessionLock& SessionLock::operator=(SessionLock&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.fd_;
    o.fd_ = -1;
  }
  return *this;
}
SessionLock::~SessionLock() {
  if (fd_ >= 0) ::close(fd_);  // closing the descriptor releases the flock
}

// ---- Session ---------------------------------------------------------------------------

fs::path SessionLayout::Frame(const std::string& pose, int index, double exposure_s,
                              const std::string& ext) const {
  return frames() / pose / fmt::format("{}_{:.5f}.{}", index, exposure_s, ext);
}

namespace {

// Opens SESSION/log.txt for appending without following a link, and hands the logger that
// very file (through /proc/self/fd, which names the open file, not a path to resolve again).
void OpenSessionLog(const SessionLayout& layout) {
  const fs::path log = layout.log();
  Fd fd(::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_NOFOLLOW | O_CLOEXEC, 0644));
  struct stat st {};
  if (fd.fd < 0 || ::fstat(fd.fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    Log("session")->warn("cannot open {} ({}); logging to the console only", log.string(),
                         fd.fd < 0 ? std::strerror(errno) : "not a regular file");
    return;
  }
  const std::string via = fmt::format("/proc/self/fd/{}", fd.fd);
  if (!AddLogFile(via))
    Log("session")->warn("cannot open {}; logging to the console only", log.string());
}

std::string ConfigText(const Config& config) {
  return "# The resolved configuration of this session. Never edit it: device settings change\n"
         "# through 'rig resume SESSION --set KEY=VALUE', which journals the change.\n"
         "# Read from: " + config.source + "\n\n" + ToToml(config);
}

nlohmann::json SettingsRecord(const char* event, const Config& config) {
  const auto settings = FlattenConfig(config);
  return {{"event", event}, {"digest", SettingsDigest(settings)}, {"settings", settings}};
}

}  // namespace

Result<Session> Session::Create(const fs::path& dir, const Config& config) {
  std::error_code ec;
  const bool existed = fs::exists(fs::symlink_status(dir, ec));
  fs::create_directories(dir, ec);
  if (ec) return MakeError(ErrorCode::kIo, dir.string(), "cannot create session folder: {}", ec.message());
  SessionLayout layout{dir};
  RIG_TRY(CheckSessionTree(dir));
  RIG_ASSIGN_OR_RETURN(SessionLock lock, SessionLock::Acquire(dir));
  if (fs::exists(fs::symlink_status(layout.journal(), ec)) ||
      fs::exists(fs::symlink_status(layout.config(), ec)))
    return MakeError(ErrorCode::kInvalidInput, dir.string(),
                     "already holds a session; use 'rig resume {}' or choose another folder",
                     dir.string());
  for (const char* p : {"frames", "hdr", "calib", "model"}) {
    auto made = EnsureSessionFolder(dir, p);
    if (!made.ok()) return made.error();
  }
  const std::string text = ConfigText(config);
  RIG_TRY(WriteSessionFile(dir, "session.toml",
                           std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()),
                           /*overwrite=*/false));
  RIG_ASSIGN_OR_RETURN(Journal journal, Journal::Open(layout.journal()));
  OpenSessionLog(layout);
  // What the stored configuration is: `rig resume` refuses a session.toml that differs.
  nlohmann::json rec = SettingsRecord("config", config);
  RIG_TRY(journal.Append(rec));
  JournalContents history;
  history.records.push_back(rec);
  Session s(layout, config, std::move(lock), std::move(journal), std::move(history));
  s.created_session_ = true;
  s.created_root_ = !existed;
  return s;
}

Result<Session> Session::OpenExisting(const fs::path& dir) {
  SessionLayout layout{dir};
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(layout.config(), ec)))
    return MakeError(ErrorCode::kNotFound, dir.string(), "not a session (no session.toml)");
  RIG_TRY(CheckSessionTree(dir));
  RIG_ASSIGN_OR_RETURN(SessionLock lock, SessionLock::Acquire(dir));
  RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> toml, ReadSessionFile(dir, "session.toml"));
  if (toml.size() > kMaxConfigBytes)
    return MakeError(ErrorCode::kInvalidInput, layout.config().string(),
                     "{} bytes: a configuration is at most {} bytes", toml.size(), kMaxConfigBytes);
  ConfigResult cr = ParseConfig(std::string(toml.begin(), toml.end()), layout.config().string());
  if (!cr.ok()) return cr.AsError();
  JournalContents history;
  RIG_ASSIGN_OR_RETURN(Journal journal, Journal::Open(layout.journal(), &history));
  OpenSessionLog(layout);
  // Temporaries of writers that were killed (".<name>.tmp..."): never anything's only copy —
  // a file exists under its own name only once complete — and nobody else writes here while
  // the lock is held.
  int stale = 0;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (IsWriterTemporaryName(name) && it->is_regular_file(ec) && !it->is_symlink(ec)) {
      std::error_code rm;
      if (fs::remove(it->path(), rm)) ++stale;
    }
  }
  if (stale > 0) Log("session")->info("removed {} unfinished temporary file(s) of an interrupted run", stale);
  return Session(layout, cr.config, std::move(lock), std::move(journal), std::move(history));
}

Status Session::CheckStoredConfig() const {
  const nlohmann::json* last = nullptr;
  for (const auto& r : history_.records)
    if (r["event"] == "config" || r["event"] == "settings_changed") last = &r;
  if (!last) {
    Log("session")->warn("{} holds no digest of the configuration (an older session); "
                         "session.toml is taken as it is", layout_.journal().string());
    return Ok();
  }
  std::map<std::string, std::string> journaled =
      (*last)["settings"].get<std::map<std::string, std::string>>();
  if (SettingsDigest(journaled) != (*last)["digest"].get<std::string>())
    return MakeError(ErrorCode::kCorrupt, layout_.journal().string(),
                     "the journaled configuration does not match its own digest");
  const auto now = FlattenConfig(config_);
  if (SettingsDigest(now) == SettingsDigest(journaled)) return Ok();
  std::string changed;
  int n = 0;
  auto note = [&](const std::string& key, const std::string& before, const std::string& after) {
    if (++n <= 8)
      changed += fmt::format("{}{} ({} -> {})", changed.empty() ? "" : ", ", key,
                             before.empty() ? "unset" : before, after.empty() ? "unset" : after);
  };
  for (const auto& [k, v] : journaled) {
    auto it = now.find(k);
    const std::string after = it == now.end() ? "" : it->second;
    if (after != v) note(k, v, after);
  }
  for (const auto& [k, v] : now)
    if (!journaled.count(k)) note(k, "", v);
  if (n > 8) changed += fmt::format(" and {} more", n - 8);
  return MakeError(ErrorCode::kInvalidInput, layout_.config().string(),
                   "changed since the session started: {}; a session's stored configuration "
                   "does not change (device settings only through 'rig resume {} --set "
                   "KEY=VALUE', which journals the change)",
                   changed, layout_.root.string());
}

Result<std::vector<SettingChange>> Session::ChangeDeviceSettings(
    const std::vector<std::string>& assignments) {
  Config next = config_;
  std::vector<SettingChange> changes;
  for (const auto& a : assignments) {
    SettingChange c;
    RIG_ASSIGN_OR_RETURN(next, ApplySetting(next, a, &c));
    changes.push_back(c);
  }
  // The change against the journal's last configuration (a session.toml rewrite a crash cut
  // off is finished by giving the same --set again).
  nlohmann::json rec = SettingsRecord("settings_changed", next);
  nlohmann::json list = nlohmann::json::array();
  const auto before = FlattenConfig(config_);
  for (auto& c : changes) {
    auto it = before.find(c.key);
    c.old_value = it == before.end() ? "" : it->second;
    list.push_back({{"key", c.key}, {"old", c.old_value}, {"new", c.new_value}});
  }
  rec["changes"] = list;
  RIG_TRY(journal_.Append(rec));
  history_.records.push_back(rec);
  const std::string text = ConfigText(next);
  RIG_TRY(WriteSessionFile(layout_.root, "session.toml",
                           std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()),
                           /*overwrite=*/true));
  config_ = next;
  for (const auto& c : changes)
    Log("session")->info("setting changed key={} old=\"{}\" new=\"{}\"", c.key, c.old_value, c.new_value);
  return changes;
}

bool Session::RemoveIfNothingStored() {
  if (!created_session_) return false;
  // Anything captured keeps the whole session.
  for (const auto& r : history_.records)
    if (r["event"] == "frame") return false;
  auto journal = Journal::Read(layout_.journal());
  if (!journal.ok()) return false;
  for (const auto& r : journal->records)
    if (r["event"] == "frame") return false;
  std::error_code ec;
  if (fs::exists(layout_.frames(), ec))
    for (auto it = fs::recursive_directory_iterator(layout_.frames(), ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
      if (!it->is_directory(ec)) return false;  // a file under frames/: keep everything
  for (const char* f : {"session.toml", "journal.jsonl", "log.txt"}) fs::remove(layout_.root / f, ec);
  // Folders Create() made (and the simulator's truth/ written for this run); only when empty
  // of anything but folders and the truth this run wrote.
  fs::remove_all(layout_.truth(), ec);
  for (const fs::path& d : {layout_.frames(), layout_.hdr(), layout_.calib(), layout_.model()}) {
    bool empty = true;
    for (auto it = fs::recursive_directory_iterator(d, ec);
         !ec && it != fs::recursive_directory_iterator(); it.increment(ec))
      if (!it->is_directory(ec)) empty = false;
    if (empty) fs::remove_all(d, ec);
  }
  fs::remove(layout_.root / ".lock", ec);  // our flock dies with the descriptor
  if (!created_root_) return false;
  return fs::remove(layout_.root, ec);  // only if now empty
}

Result<nlohmann::json> Session::StoreFrame(const std::string& pose, int index, double exposure_s,
                                           const std::string& ext, std::span<const uint8_t> bytes,
                                           nlohmann::json extra) {
  const std::string rel =
      fs::relative(layout_.Frame(pose, index, exposure_s, ext), layout_.root).string();
  RIG_TRY(WriteSessionFile(layout_.root, rel, bytes, /*overwrite=*/false));
  nlohmann::json rec = extra.is_object() ? std::move(extra) : nlohmann::json::object();
  rec["event"] = "frame";
  rec["pose"] = pose;
  rec["index"] = index;
  rec["exposure_s"] = exposure_s;
  rec["file"] = rel;
  rec["bytes"] = bytes.size();
  rec["crc32"] = Crc32(bytes);
  RIG_TRY(journal_.Append(rec));
  return rec;
}

}  // namespace rig
