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
#include <random>
#include <sstream>

#include "config/log.h"

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

Status FsyncDirectory(const fs::path& dir) {
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return Errno(dir, "cannot open folder to sync");
  int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) return Errno(dir, "fsync of folder failed");
  return Ok();
}

Status WriteFileAtomic(const fs::path& path, std::span<const uint8_t> bytes, bool overwrite) {
  fs::path dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return MakeError(ErrorCode::kIo, dir.string(), "cannot create folder: {}", ec.message());
  if (!overwrite && fs::exists(path))
    return MakeError(ErrorCode::kIo, path.string(), "refusing to overwrite an existing file");
  // A fresh name each time: the process id in it (a forked child inherits this generator's
  // state and would otherwise repeat its parent's names), and another name when one is taken
  // (a temporary left by a writer that was killed).
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  fs::path tmp;
  int fd = -1;
  for (int attempt = 0; attempt < 16 && fd < 0; ++attempt) {
    tmp = dir / fmt::format(".{}.tmp{}.{:016x}", path.filename().string(), ::getpid(), rng());
    fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) return Errno(tmp, "cannot create temporary file");
  Status st = WriteAll(fd, bytes.data(), bytes.size(), tmp);
  if (st.ok() && ::fsync(fd) != 0) st = Errno(tmp, "fsync failed");
  if (::close(fd) != 0 && st.ok()) st = Errno(tmp, "close failed");
  if (!st.ok()) {
    ::unlink(tmp.c_str());
    return st;
  }
  if (overwrite) {
    if (::rename(tmp.c_str(), path.c_str()) != 0) {
      Error e = Errno(path, "rename failed");
      ::unlink(tmp.c_str());
      return e;
    }
  } else {
    // link() fails if the target exists: no window in which an existing file is replaced.
    if (::link(tmp.c_str(), path.c_str()) != 0) {
      Error e = errno == EEXIST
                    ? MakeError(ErrorCode::kIo, path.string(), "refusing to overwrite an existing file")
                    : Errno(path, "link failed");
      ::unlink(tmp.c_str());
      return e;
    }
    ::unlink(tmp.c_str());
  }
  return FsyncDirectory(dir);
}

Status WriteFileAtomic(const fs::path& path, const std::string& text, bool overwrite) {
  return WriteFileAtomic(
      path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()),
      overwrite);
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
  JournalContents out;
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeError(ErrorCode::kNotFound, path.string(), "cannot open journal");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  size_t pos = 0;
  int line_no = 0;
  while (pos < text.size()) {
    size_t nl = text.find('\n', pos);
    ++line_no;
    if (nl == std::string::npos) {
      // No newline: the write of this record never completed.
      out.torn_tail = true;
      out.warnings.push_back(fmt::format("{}:{}: last record is incomplete (cut by a crash); ignored",
                                         path.string(), line_no));
      break;
    }
    std::string line = text.substr(pos, nl - pos);
    if (!line.empty()) {
      auto j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
      if (j.is_discarded()) {
        if (nl + 1 == text.size()) {
          out.torn_tail = true;
          out.warnings.push_back(fmt::format("{}:{}: last record is damaged; ignored",
                                             path.string(), line_no));
          break;
        }
        return MakeError(ErrorCode::kCorrupt, fmt::format("{}:{}", path.string(), line_no),
                         "journal record is not valid JSON");
      }
      out.records.push_back(std::move(j));
    }
    pos = nl + 1;
    out.valid_bytes = pos;
  }
  return out;
}

Result<Journal> Journal::Open(const fs::path& path) {
  if (fs::exists(path)) {
    RIG_ASSIGN_OR_RETURN(JournalContents c, Read(path));
    if (c.torn_tail) {
      for (const auto& w : c.warnings) Log("session")->warn("{}", w);
      if (::truncate(path.c_str(), static_cast<off_t>(c.valid_bytes)) != 0)
        return Errno(path, "cannot cut the torn journal tail");
    }
  }
  int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (fd < 0) return Errno(path, "cannot open journal");
  if (::fsync(fd) != 0) {
    ::close(fd);
    return Errno(path, "fsync failed");
  }
  Status st = FsyncDirectory(path.parent_path().empty() ? fs::path(".") : path.parent_path());
  if (!st.ok()) {
    ::close(fd);
    return st.error();
  }
  return Journal(path, fd);
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
  int fd = ::open(p.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) return Errno(p, "cannot open session lock");
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

Result<Session> Session::Create(const fs::path& dir, const Config& config) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return MakeError(ErrorCode::kIo, dir.string(), "cannot create session folder: {}", ec.message());
  RIG_ASSIGN_OR_RETURN(SessionLock lock, SessionLock::Acquire(dir));
  SessionLayout layout{dir};
  if (fs::exists(layout.journal()) || fs::exists(layout.config()))
    return MakeError(ErrorCode::kInvalidInput, dir.string(),
                     "already holds a session; use 'rig resume {}' or choose another folder",
                     dir.string());
  for (const fs::path& p : {layout.frames(), layout.hdr(), layout.calib(), layout.model()}) {
    fs::create_directories(p, ec);
    if (ec) return MakeError(ErrorCode::kIo, p.string(), "cannot create folder: {}", ec.message());
  }
  std::string header = "# The resolved configuration of this session (never edited afterwards).\n"
                       "# Read from: " + config.source + "\n\n";
  RIG_TRY(WriteFileAtomic(layout.config(), header + ToToml(config), /*overwrite=*/false));
  RIG_ASSIGN_OR_RETURN(Journal journal, Journal::Open(layout.journal()));
  if (!AddLogFile(layout.log().string()))
    Log("session")->warn("cannot open {}; logging to the console only", layout.log().string());
  return Session(layout, config, std::move(lock), std::move(journal), JournalContents{});
}

Result<Session> Session::OpenExisting(const fs::path& dir) {
  SessionLayout layout{dir};
  if (!fs::exists(layout.config()))
    return MakeError(ErrorCode::kNotFound, dir.string(), "not a session (no session.toml)");
  RIG_ASSIGN_OR_RETURN(SessionLock lock, SessionLock::Acquire(dir));
  ConfigResult cr = LoadConfig(layout.config().string());
  if (!cr.ok()) return cr.AsError();
  JournalContents history;
  if (fs::exists(layout.journal())) {
    RIG_ASSIGN_OR_RETURN(history, Journal::Read(layout.journal()));
  }
  RIG_ASSIGN_OR_RETURN(Journal journal, Journal::Open(layout.journal()));
  if (!AddLogFile(layout.log().string()))
    Log("session")->warn("cannot open {}; logging to the console only", layout.log().string());
  // Temporaries of writers that were killed (".<name>.tmp..."): never anything's only copy —
  // a file exists under its own name only once complete — and nobody else writes here while
  // the lock is held.
  int stale = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() > 1 && name[0] == '.' && name.find(".tmp") != std::string::npos &&
        it->is_regular_file(ec)) {
      std::error_code rm;
      if (fs::remove(it->path(), rm)) ++stale;
    }
  }
  if (stale > 0) Log("session")->info("removed {} unfinished temporary file(s) of an interrupted run", stale);
  return Session(layout, cr.config, std::move(lock), std::move(journal), std::move(history));
}

Result<nlohmann::json> Session::StoreFrame(const std::string& pose, int index, double exposure_s,
                                           const std::string& ext, std::span<const uint8_t> bytes,
                                           nlohmann::json extra) {
  fs::path path = layout_.Frame(pose, index, exposure_s, ext);
  RIG_TRY(WriteFileAtomic(path, bytes, /*overwrite=*/false));
  nlohmann::json rec = extra.is_object() ? std::move(extra) : nlohmann::json::object();
  rec["event"] = "frame";
  rec["pose"] = pose;
  rec["index"] = index;
  rec["exposure_s"] = exposure_s;
  rec["file"] = fs::relative(path, layout_.root).string();
  rec["bytes"] = bytes.size();
  rec["crc32"] = Crc32(bytes);
  RIG_TRY(journal_.Append(rec));
  return rec;
}

}  // namespace rig
