#include "config/atomic_file.h"

#include <fcntl.h>
#include <stdio.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <random>

#include <fmt/format.h>

namespace rig {
namespace {

namespace fs = std::filesystem;

constexpr size_t kBufferBytes = size_t{1} << 20;

Error Errno(const fs::path& where, const char* what) {
  return MakeError(ErrorCode::kIo, where.string(), "{}: {}", what, std::strerror(errno));
}

Status WriteAllAt(int fd, const char* p, size_t n, uint64_t offset, const fs::path& where) {
  while (n > 0) {
    ssize_t w = ::pwrite(fd, p, n, static_cast<off_t>(offset));
    if (w < 0) {
      if (errno == EINTR) continue;
      return Errno(where, "write failed");
    }
    p += w;
    n -= static_cast<size_t>(w);
    offset += static_cast<uint64_t>(w);
  }
  return Ok();
}

// A fresh temporary beside `name` in `dir_fd`: O_EXCL|O_NOFOLLOW, another name when one is
// taken. The process id is in the name (a forked child inherits the generator's state).
Result<int> CreateTemporary(int dir_fd, const fs::path& dir, const std::string& name,
                            std::string* tmp) {
  static thread_local std::mt19937_64 rng{std::random_device{}()};
  int fd = -1;
  for (int attempt = 0; attempt < 16 && fd < 0; ++attempt) {
    *tmp = fmt::format(".{}.tmp{}.{:016x}", name, ::getpid(), rng());
    fd = ::openat(dir_fd, tmp->c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC,
                  0644);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) return Errno(dir / *tmp, "cannot create temporary file");
  return fd;
}

// The target checked before anything is written: a folder is never replaced by a file, and
// with overwrite off anything there is refused.
Status CheckTarget(int dir_fd, const fs::path& path, const std::string& name, bool overwrite) {
  struct stat st {};
  if (::fstatat(dir_fd, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) return Ok();
  if (!overwrite)
    return MakeError(ErrorCode::kIo, path.string(), "refusing to overwrite an existing file");
  if (S_ISDIR(st.st_mode))
    return MakeError(ErrorCode::kInvalidInput, path.string(), "is a folder, not a file");
  return Ok();
}

// The written temporary `tmp` moved to `name`: rename (replacing a file or link, never
// following it), or with overwrite off link() (fails when anything is there). Then the folder
// is synced. The temporary is gone afterwards either way.
Status Publish(int dir_fd, const fs::path& dir, const std::string& tmp, const std::string& name,
               bool overwrite, bool sync = true) {
  const fs::path path = dir / name;
  if (overwrite) {
    if (::renameat(dir_fd, tmp.c_str(), dir_fd, name.c_str()) != 0) {
      Error e = errno == EISDIR ? MakeError(ErrorCode::kInvalidInput, path.string(),
                                            "is a folder, not a file")
                                : Errno(path, "rename failed");
      ::unlinkat(dir_fd, tmp.c_str(), 0);
      return e;
    }
  } else {
    if (::linkat(dir_fd, tmp.c_str(), dir_fd, name.c_str(), 0) != 0) {
      Error e = errno == EEXIST ? MakeError(ErrorCode::kIo, path.string(),
                                            "refusing to overwrite an existing file")
                                : Errno(path, "link failed");
      ::unlinkat(dir_fd, tmp.c_str(), 0);
      return e;
    }
    ::unlinkat(dir_fd, tmp.c_str(), 0);
  }
  if (sync && ::fsync(dir_fd) != 0) return Errno(dir, "fsync of folder failed");
  return Ok();
}

// The folder of `path` (made when missing), opened.
Result<int> OpenParent(const fs::path& path, fs::path* dir) {
  *dir = path.parent_path().empty() ? fs::path(".") : path.parent_path();
  std::error_code ec;
  fs::create_directories(*dir, ec);
  if (ec)
    return MakeError(ErrorCode::kIo, path.string(), "cannot create folder {}: {}", dir->string(),
                     ec.message());
  int fd = ::open(dir->c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0)
    return MakeError(ErrorCode::kIo, path.string(), "cannot open folder {}: {}", dir->string(),
                     std::strerror(errno));
  return fd;
}

Status CheckName(const fs::path& path, const std::string& name) {
  if (name.empty() || name == "." || name == "..")
    return MakeError(ErrorCode::kInvalidInput, path.string(), "not a file name");
  return Ok();
}

}  // namespace

bool IsWriterTemporaryName(std::string_view name) {
  return name.size() > 1 && name[0] == '.' && name.find(".tmp") != std::string_view::npos;
}

Status FsyncDirectory(const fs::path& dir) {
  int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return Errno(dir, "cannot open folder to sync");
  int rc = ::fsync(fd);
  ::close(fd);
  if (rc != 0) return Errno(dir, "fsync of folder failed");
  return Ok();
}

Status WriteFileAtomicAt(int dir_fd, const fs::path& dir, const std::string& name,
                         std::span<const uint8_t> bytes, bool overwrite, bool sync) {
  const fs::path path = dir / name;
  RIG_TRY(CheckName(path, name));
  RIG_TRY(CheckTarget(dir_fd, path, name, overwrite));
  std::string tmp;
  RIG_ASSIGN_OR_RETURN(int fd, CreateTemporary(dir_fd, dir, name, &tmp));
  Status status = WriteAllAt(fd, reinterpret_cast<const char*>(bytes.data()), bytes.size(), 0,
                             dir / tmp);
  if (status.ok() && sync && ::fsync(fd) != 0) status = Errno(dir / tmp, "fsync failed");
  if (::close(fd) != 0 && status.ok()) status = Errno(dir / tmp, "close failed");
  if (!status.ok()) {
    ::unlinkat(dir_fd, tmp.c_str(), 0);
    return status;
  }
  return Publish(dir_fd, dir, tmp, name, overwrite, sync);
}

Status WriteFileAtomic(const fs::path& path, std::span<const uint8_t> bytes, bool overwrite,
                       bool sync) {
  fs::path dir;
  RIG_ASSIGN_OR_RETURN(int dir_fd, OpenParent(path, &dir));
  Status st = WriteFileAtomicAt(dir_fd, dir, path.filename().string(), bytes, overwrite, sync);
  ::close(dir_fd);
  return st;
}

Status WriteFileAtomic(const fs::path& path, std::string_view text, bool overwrite, bool sync) {
  return WriteFileAtomic(
      path, std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(text.data()), text.size()),
      overwrite, sync);
}

Status CopyFileNoFollow(const fs::path& from, const fs::path& to, uint64_t limit) {
  int fd = ::open(from.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    if (errno == ELOOP)
      return MakeError(ErrorCode::kInvalidInput, from.string(),
                       "is a symbolic link: refusing to publish what it points to (copy the file itself there)");
    return MakeError(ErrorCode::kNotFound, from.string(), "cannot open: {}", std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || static_cast<uint64_t>(st.st_size) > limit) {
    ::close(fd);
    return MakeError(ErrorCode::kInvalidInput, from.string(), "not a plain file of at most {} bytes", limit);
  }
  std::vector<uint8_t> bytes(static_cast<size_t>(st.st_size));
  size_t got = 0;
  while (got < bytes.size()) {
    ssize_t n = ::read(fd, bytes.data() + got, bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      Error e = n < 0 ? Errno(from, "read failed")
                      : MakeError(ErrorCode::kIo, from.string(), "shrank while it was read");
      ::close(fd);
      return e;
    }
    got += static_cast<size_t>(n);
  }
  ::close(fd);
  return WriteFileAtomic(to, std::span<const uint8_t>(bytes.data(), bytes.size()), /*overwrite=*/false);
}

// ---- AtomicFile ---------------------------------------------------------------------------

Result<AtomicFile> AtomicFile::Create(const fs::path& path, bool overwrite) {
  AtomicFile f;
  f.path_ = path;
  f.overwrite_ = overwrite;
  fs::path dir;
  RIG_ASSIGN_OR_RETURN(f.dir_fd_, OpenParent(path, &dir));
  const std::string name = path.filename().string();
  RIG_TRY(CheckName(path, name));
  RIG_TRY(CheckTarget(f.dir_fd_, path, name, overwrite));
  RIG_ASSIGN_OR_RETURN(f.fd_, CreateTemporary(f.dir_fd_, dir, name, &f.temp_));
  f.buffer_.reserve(kBufferBytes);
  return f;
}

AtomicFile::AtomicFile(AtomicFile&& o) noexcept { *this = std::move(o); }

AtomicFile& AtomicFile::operator=(AtomicFile&& o) noexcept {
  if (this != &o) {
    Abandon();
    path_ = std::move(o.path_);
    temp_ = std::move(o.temp_);
    dir_fd_ = o.dir_fd_;
    fd_ = o.fd_;
    overwrite_ = o.overwrite_;
    offset_ = o.offset_;
    buffer_ = std::move(o.buffer_);
    o.dir_fd_ = o.fd_ = -1;
  }
  return *this;
}

AtomicFile::~AtomicFile() { Abandon(); }

void AtomicFile::Abandon() {
  if (fd_ >= 0) {
    ::close(fd_);
    ::unlinkat(dir_fd_, temp_.c_str(), 0);
    fd_ = -1;
  }
  if (dir_fd_ >= 0) ::close(dir_fd_);
  dir_fd_ = -1;
}

Status AtomicFile::Flush() {
  if (buffer_.empty()) return Ok();
  RIG_TRY(WriteAllAt(fd_, buffer_.data(), buffer_.size(), offset_, temp_path()));
  offset_ += buffer_.size();
  buffer_.clear();
  return Ok();
}

Status AtomicFile::Write(const void* data, size_t n) {
  if (fd_ < 0) return MakeError(ErrorCode::kInternal, path_.string(), "write after commit");
  const char* p = static_cast<const char*>(data);
  if (buffer_.size() + n > kBufferBytes) RIG_TRY(Flush());
  if (n >= kBufferBytes) {
    RIG_TRY(WriteAllAt(fd_, p, n, offset_, temp_path()));
    offset_ += n;
    return Ok();
  }
  buffer_.insert(buffer_.end(), p, p + n);
  return Ok();
}

Status AtomicFile::Seek(uint64_t offset) {
  if (fd_ < 0) return MakeError(ErrorCode::kInternal, path_.string(), "seek after commit");
  RIG_TRY(Flush());
  offset_ = offset;
  return Ok();
}

Status AtomicFile::Commit(double* sync_s) {
  if (fd_ < 0) return MakeError(ErrorCode::kInternal, path_.string(), "committed twice");
  Status st = Flush();
  const auto t0 = std::chrono::steady_clock::now();
  if (st.ok() && ::fsync(fd_) != 0) st = Errno(temp_path(), "fsync failed");
  if (sync_s) *sync_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (::close(fd_) != 0 && st.ok()) st = Errno(temp_path(), "close failed");
  fd_ = -1;
  if (!st.ok()) {
    ::unlinkat(dir_fd_, temp_.c_str(), 0);
  } else {
    const fs::path dir = path_.parent_path().empty() ? fs::path(".") : path_.parent_path();
    st = Publish(dir_fd_, dir, temp_, path_.filename().string(), overwrite_);
  }
  ::close(dir_fd_);
  dir_fd_ = -1;
  return st;
}

// ---- StagedFile ---------------------------------------------------------------------------

Result<StagedFile> StagedFile::Begin(const fs::path& path) {
  fs::path dir;
  RIG_ASSIGN_OR_RETURN(int dir_fd, OpenParent(path, &dir));
  const std::string name = path.filename().string();
  Status st = CheckName(path, name);
  if (st.ok()) st = CheckTarget(dir_fd, path, name, /*overwrite=*/true);
  ::close(dir_fd);
  RIG_TRY(st);
  std::string tmpl = (dir / ("." + name + ".XXXXXX")).string();
  if (::mkdtemp(tmpl.data()) == nullptr) return Errno(tmpl, "cannot create temporary folder");
  StagedFile f;
  f.path_ = path;
  f.dir_ = tmpl;
  return f;
}

StagedFile::StagedFile(StagedFile&& o) noexcept : path_(std::move(o.path_)), dir_(std::move(o.dir_)) {
  o.dir_.clear();
}

StagedFile::~StagedFile() {
  if (dir_.empty()) return;
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

Status StagedFile::Publish() {
  if (dir_.empty()) return MakeError(ErrorCode::kInternal, path_.string(), "published twice");
  const fs::path written = file();
  struct stat st {};
  if (::lstat(written.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
    return MakeError(ErrorCode::kIo, path_.string(), "nothing was written");
  int fd = ::open(written.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0 || ::fsync(fd) != 0) {
    Error e = Errno(written, "fsync failed");
    if (fd >= 0) ::close(fd);
    return e;
  }
  ::close(fd);
  if (::rename(written.c_str(), path_.c_str()) != 0) return Errno(path_, "cannot move the written file into place");
  std::error_code ec;
  fs::remove_all(dir_, ec);
  dir_.clear();
  const fs::path parent = path_.parent_path().empty() ? fs::path(".") : path_.parent_path();
  return FsyncDirectory(parent);
}

// ---- AtomicFolder -------------------------------------------------------------------------

bool IsTemporaryFolderOf(std::string_view entry, std::string_view name) {
  if (entry.size() != name.size() + 8 || entry[0] != '.') return false;
  if (entry.substr(1, name.size()) != name || entry[name.size() + 1] != '.') return false;
  for (char c : entry.substr(name.size() + 2))
    if (!std::isalnum(static_cast<unsigned char>(c))) return false;
  return true;
}

namespace {

// What is at `target` when it may be replaced: absent, or a folder (not a link) whose every
// entry is a plain file `replaceable` accepts (or a writer's temporary).
Result<bool> CheckReplaceable(const fs::path& target, const AtomicFolder::EntryFilter& replaceable) {
  struct stat st {};
  if (::lstat(target.c_str(), &st) != 0) {
    if (errno == ENOENT) return false;
    return Errno(target, "cannot inspect");
  }
  if (S_ISLNK(st.st_mode))
    return MakeError(ErrorCode::kInvalidInput, target.string(),
                     "is a symbolic link: refusing to replace it (give the folder itself)");
  if (!S_ISDIR(st.st_mode))
    return MakeError(ErrorCode::kInvalidInput, target.string(), "exists and is not a folder");
  std::error_code ec;
  for (auto it = fs::directory_iterator(target, ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const bool plain = it->symlink_status(ec).type() == fs::file_type::regular;
    if (plain && (IsWriterTemporaryName(name) || (replaceable && replaceable(name)))) continue;
    return MakeError(ErrorCode::kInvalidInput, target.string(),
                     "holds {} '{}', which this command did not write: refusing to replace the "
                     "folder (give an empty or new folder)",
                     plain ? "the file" : "the entry", name);
  }
  if (ec) return MakeError(ErrorCode::kIo, target.string(), "cannot list: {}", ec.message());
  return true;
}

// Stale temporary folders of killed writers of `target`, removed.
void RemoveStaleTemporaries(const fs::path& target) {
  const fs::path parent = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  const std::string name = target.filename().string();
  std::error_code ec;
  for (auto it = fs::directory_iterator(parent, ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    const std::string entry = it->path().filename().string();
    if (!IsTemporaryFolderOf(entry, name)) continue;
    std::error_code ec2;
    if (it->symlink_status(ec2).type() != fs::file_type::directory) continue;
    // A live writer holds an flock on its folder; a killed one's lock went with it.
    int fd = ::open(it->path().c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0) continue;
    const bool stale = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
    if (stale) fs::remove_all(it->path(), ec2);
    ::close(fd);
  }
}

}  // namespace

Result<AtomicFolder> AtomicFolder::Begin(const fs::path& target_in, const EntryFilter& replaceable) {
  fs::path target = target_in;
  while (!target.empty() && target.filename().empty()) target = target.parent_path();  // "DIR/"
  const std::string name = target.filename().string();
  if (name.empty() || name == "." || name == "..")
    return MakeError(ErrorCode::kInvalidInput, target_in.string(),
                     "give the folder by its name (not . or ..)");
  if (auto replace = CheckReplaceable(target, replaceable); !replace.ok()) return replace.error();
  const fs::path parent = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  std::error_code ec;
  fs::create_directories(parent, ec);
  if (ec) return MakeError(ErrorCode::kIo, parent.string(), "cannot create folder: {}", ec.message());
  RemoveStaleTemporaries(target);
  std::string tmpl = (parent / ("." + name + ".XXXXXX")).string();
  if (::mkdtemp(tmpl.data()) == nullptr) return Errno(tmpl, "cannot create temporary folder");
  // mkdtemp makes it 0700; the folder published is as any other the user creates.
  const mode_t mask = ::umask(0);
  ::umask(mask);
  ::chmod(tmpl.c_str(), 0755 & ~mask);
  AtomicFolder f;
  f.target_ = target;
  f.temp_ = tmpl;
  f.lock_fd_ = ::open(tmpl.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (f.lock_fd_ < 0 || ::flock(f.lock_fd_, LOCK_EX | LOCK_NB) != 0)
    return Errno(tmpl, "cannot lock the temporary folder");
  return f;
}

AtomicFolder::AtomicFolder(AtomicFolder&& o) noexcept { *this = std::move(o); }

AtomicFolder& AtomicFolder::operator=(AtomicFolder&& o) noexcept {
  if (this != &o) {
    Release();
    target_ = std::move(o.target_);
    temp_ = std::move(o.temp_);
    lock_fd_ = o.lock_fd_;
    o.temp_.clear();
    o.lock_fd_ = -1;
  }
  return *this;
}

void AtomicFolder::Release() {
  if (!temp_.empty()) {
    std::error_code ec;
    fs::remove_all(temp_, ec);
    temp_.clear();
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);
  lock_fd_ = -1;
}

AtomicFolder::~AtomicFolder() { Release(); }

Status AtomicFolder::Commit() {
  if (temp_.empty()) return MakeError(ErrorCode::kInternal, target_.string(), "committed twice");
  RIG_TRY(FsyncDirectory(temp_));
  // Looked at again: a link or a file may have been put there while this one was written.
  struct stat st {};
  bool exists = true;
  if (::lstat(target_.c_str(), &st) != 0) {
    if (errno != ENOENT) return Errno(target_, "cannot inspect");
    exists = false;
  } else if (!S_ISDIR(st.st_mode)) {
    return MakeError(ErrorCode::kInvalidInput, target_.string(),
                     "is no longer a folder (a link or a file was put there): refusing to replace it");
  }
  if (!exists) {
    if (::renameat2(AT_FDCWD, temp_.c_str(), AT_FDCWD, target_.c_str(), RENAME_NOREPLACE) != 0)
      return Errno(target_, "cannot move the written folder into place");
  } else {
    if (::renameat2(AT_FDCWD, temp_.c_str(), AT_FDCWD, target_.c_str(), RENAME_EXCHANGE) != 0)
      return Errno(target_, "cannot exchange the written folder with the old one");
  }
  // temp_ now names the old folder (or nothing); the lock goes with it.
  Release();
  const fs::path parent = target_.parent_path().empty() ? fs::path(".") : target_.parent_path();
  return FsyncDirectory(parent);
}

}  // namespace rig
