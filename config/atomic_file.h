// The one writer of every file the project creates (issue 30, items 8-9).
//
// A file is written as a temporary with a fresh random name in the target's own folder,
// created with O_CREAT|O_EXCL|O_NOFOLLOW (mode 0644, less the umask: a link or a file already
// at that name is never opened), written, fsync'd, then renamed over the target: a reader
// sees the old file or the new one, never part of one, and a symbolic link at the target is
// replaced, never followed. With overwrite off, the temporary is link()ed to the target,
// which fails when anything is there (nothing is ever replaced). On failure the temporary is
// removed. Temporaries are named ".<name>.tmp<pid>.<16 hex digits>".
//
// Folders written whole (models, viewer pages): AtomicFolder writes into a fresh sibling
// ".<name>.XXXXXX" (mkdtemp) and moves it into place at the end — exchanged with the folder
// already there (renameat2 RENAME_EXCHANGE), which is then removed — so a reader sees the
// old folder or the new one.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "config/result.h"

namespace rig {

// Writes `bytes` to `path` as above; the folder is created when missing. With `overwrite`
// false an existing file (or link) is never replaced: kIo "refusing to overwrite". With `sync`
// false the file and its folder are not fsync'd (thousands of deep-zoom tiles, which the
// folder written whole around them publishes): still never through a link, never half seen.
Status WriteFileAtomic(const std::filesystem::path& path, std::span<const uint8_t> bytes,
                       bool overwrite = true, bool sync = true);
Status WriteFileAtomic(const std::filesystem::path& path, std::string_view text,
                       bool overwrite = true, bool sync = true);
// The same into the open folder `dir_fd` (shown in errors as `dir`), `name` a plain name.
Status WriteFileAtomicAt(int dir_fd, const std::filesystem::path& dir, const std::string& name,
                         std::span<const uint8_t> bytes, bool overwrite, bool sync = true);
Status FsyncDirectory(const std::filesystem::path& dir);

// True for the name of a writer's temporary (".<x>.tmp<digits>.<hex>", and the older
// ".<x>.tmp" forms): never anything's only copy.
bool IsWriterTemporaryName(std::string_view name);

// The streaming form, for files written in pieces (EXR, the session's model stream).
// Create() makes the temporary; Write() appends (buffered), Seek()/Tell() move within it
// (OpenEXR writes its offset table last); Commit() flushes, fsyncs and moves it into place.
// Destroyed uncommitted, the temporary is removed.
class AtomicFile {
 public:
  static Result<AtomicFile> Create(const std::filesystem::path& path, bool overwrite = true);
  AtomicFile(AtomicFile&& o) noexcept;
  AtomicFile& operator=(AtomicFile&& o) noexcept;
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  Status Write(const void* data, size_t n);
  Status Write(std::string_view text) { return Write(text.data(), text.size()); }
  Status Seek(uint64_t offset);
  uint64_t Tell() const { return offset_ + buffer_.size(); }
  // Moves the file into place; *sync_s (when given) receives the fsync's time in seconds.
  Status Commit(double* sync_s = nullptr);
  // Removes the temporary now (what the destructor does).
  void Abandon();

  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path temp_path() const { return path_.parent_path() / temp_; }

 private:
  AtomicFile() = default;
  Status Flush();

  std::filesystem::path path_;
  std::string temp_;
  int dir_fd_ = -1;
  int fd_ = -1;
  bool overwrite_ = true;
  uint64_t offset_ = 0;  // where buffer_ goes in the file
  std::vector<char> buffer_;
};

// A folder written whole. Begin() refuses a `target` that is a symbolic link or not a folder
// and, when `replaceable` is given, a folder holding any entry it rejects (kInvalidInput naming
// the entry: someone else's files are never removed); it removes stale ".<name>.XXXXXX"
// folders of killed writers (none a live writer holds an flock on) and makes a fresh one.
// Every file goes into dir(); Commit() moves it into place (exchanged with the old folder,
// which is then removed). Destroyed uncommitted, the temporary folder is removed.
class AtomicFolder {
 public:
  using EntryFilter = std::function<bool(const std::string& name)>;
  static Result<AtomicFolder> Begin(const std::filesystem::path& target,
                                    const EntryFilter& replaceable = nullptr);
  AtomicFolder(AtomicFolder&& o) noexcept;
  AtomicFolder& operator=(AtomicFolder&& o) noexcept;
  AtomicFolder(const AtomicFolder&) = delete;
  AtomicFolder& operator=(const AtomicFolder&) = delete;
  ~AtomicFolder();

  const std::filesystem::path& dir() const { return temp_; }
  const std::filesystem::path& target() const { return target_; }
  Status Commit();

 private:
  AtomicFolder() = default;
  void Release();
  std::filesystem::path target_, temp_;
  int lock_fd_ = -1;  // flock on temp_ while it is written: not stale to another writer
};

// Copies the regular file `from` to `to` (WriteFileAtomic, overwrite off): `from` is opened
// with O_NOFOLLOW, so a link there is refused (kInvalidInput naming it), as is anything not a
// plain file or larger than `limit` bytes. For publishing a model's files.
Status CopyFileNoFollow(const std::filesystem::path& from, const std::filesystem::path& to,
                        uint64_t limit = uint64_t{1} << 32);

// For a library that opens its output by name (OpenCV's VideoWriter): a fresh private folder
// (mkdtemp, 0700) beside `path`, where nobody else can plant a link; the library writes file();
// Publish() renames it over `path` (a link there is replaced, never followed). Destroyed
// unpublished, the folder and what is in it are removed.
class StagedFile {
 public:
  static Result<StagedFile> Begin(const std::filesystem::path& path);
  StagedFile(StagedFile&& o) noexcept;
  StagedFile& operator=(StagedFile&&) = delete;
  StagedFile(const StagedFile&) = delete;
  StagedFile& operator=(const StagedFile&) = delete;
  ~StagedFile();
  std::filesystem::path file() const { return dir_ / path_.filename(); }
  Status Publish();

 private:
  StagedFile() = default;
  std::filesystem::path path_, dir_;
};

// True for a writer's temporary folder name of `name` (".<name>.XXXXXX").
bool IsTemporaryFolderOf(std::string_view entry, std::string_view name);

}  // namespace rig
