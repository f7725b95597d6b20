// The session on disk (design.md): layout, atomic file writes, the append-only journal,
// and the lock that keeps a second process out.
//
//   SESSION/session.toml    resolved configuration (written once)
//   SESSION/journal.jsonl   one JSON record per event, each fsync'd before the next step
//   SESSION/frames/<pose>/<i>_<exposure>.<ext>
//   SESSION/hdr/<pose>.exr, calib/, model/, truth/, render/, log.txt
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/config.h"
#include "config/result.h"

namespace rig {

namespace fs = std::filesystem;

// CRC-32 (zlib) of a byte string: the journal's checksum of every stored file.
uint32_t Crc32(std::span<const uint8_t> bytes);

// Writes `bytes` to `path` so that the final name only ever shows a complete file:
// temporary file in the same folder, write, fsync, rename, fsync of the folder.
// With `overwrite` false an existing file is never replaced (kIo error instead).
Status WriteFileAtomic(const fs::path& path, std::span<const uint8_t> bytes,
                       bool overwrite = true);
Status WriteFileAtomic(const fs::path& path, const std::string& text, bool overwrite = true);
Status FsyncDirectory(const fs::path& dir);
Result<std::vector<uint8_t>> ReadFileBytes(const fs::path& path);

// What was read back from a journal.
struct JournalContents {
  std::vector<nlohmann::json> records;
  bool torn_tail = false;     // the last line was cut by a crash (ignored)
  size_t valid_bytes = 0;     // length of the intact prefix
  std::vector<std::string> warnings;
};

// Append-only JSON-lines journal. Every Append() is written and fsync'd before it returns.
class Journal {
 public:
  // Opens for appending; a torn last line (from a crash) is cut off first, and said so.
  static Result<Journal> Open(const fs::path& path);
  // Reads every intact record; a torn last line is reported, not an error. A damaged line
  // in the middle is an error naming its line number.
  static Result<JournalContents> Read(const fs::path& path);

  Journal(Journal&&) noexcept;
  Journal& operator=(Journal&&) noexcept;
  Journal(const Journal&) = delete;
  ~Journal();

  // Adds "t" (UTC ISO time) and writes one line, then fsyncs.
  Status Append(nlohmann::json record);
  const fs::path& path() const { return path_; }

 private:
  Journal(fs::path path, int fd) : path_(std::move(path)), fd_(fd) {}
  fs::path path_;
  int fd_ = -1;
};

// An exclusive lock on a session folder (flock on SESSION/.lock). The kernel frees it
// when the holder dies, however it dies.
class SessionLock {
 public:
  static Result<SessionLock> Acquire(const fs::path& session_dir);
  SessionLock(SessionLock&&) noexcept;
  SessionLock& operator=(SessionLock&&) noexcept;
  SessionLock(const SessionLock&) = delete;
  ~SessionLock();

 private:
  explicit SessionLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

// Paths of a session's parts.
struct SessionLayout {
  fs::path root;
  fs::path config() const { return root / "session.toml"; }
  fs::path journal() const { return root / "journal.jsonl"; }
  fs::path log() const { return root / "log.txt"; }
  fs::path frames() const { return root / "frames"; }
  fs::path hdr() const { return root / "hdr"; }
  fs::path calib() const { return root / "calib"; }
  fs::path model() const { return root / "model"; }
  fs::path truth() const { return root / "truth"; }
  fs::path render() const { return root / "render"; }
  // frames/<pose>/<index>_<exposure>.<ext>, exposure as e.g. "0.01000".
  fs::path Frame(const std::string& pose, int index, double exposure_s,
                 const std::string& ext) const;
  fs::path Hdr(const std::string& pose) const { return hdr() / (pose + ".exr"); }
};

// An open, locked session.
class Session {
 public:
  // Creates a new session folder (refused if it already holds a session) and writes the
  // resolved configuration.
  static Result<Session> Create(const fs::path& dir, const Config& config);
  // Opens an existing session (for resume or processing): lock, configuration, journal.
  static Result<Session> OpenExisting(const fs::path& dir);

  const SessionLayout& layout() const { return layout_; }
  const Config& config() const { return config_; }
  Journal& journal() { return journal_; }
  // The records present when the session was opened.
  const JournalContents& history() const { return history_; }

  // Stores one camera file byte for byte (atomically, never overwriting) and journals
  // it with its size and CRC. Returns the record written.
  Result<nlohmann::json> StoreFrame(const std::string& pose, int index, double exposure_s,
                                    const std::string& ext, std::span<const uint8_t> bytes,
                                    nlohmann::json extra = {});

 private:
  Session(SessionLayout layout, Config config, SessionLock lock, Journal journal,
          JournalContents history)
      : layout_(std::move(layout)), config_(std::move(config)), lock_(std::move(lock)),
        journal_(std::move(journal)), history_(std::move(history)) {}
  SessionLayout layout_;
  Config config_;
  SessionLock lock_;
  Journal journal_;
  JournalContents history_;
};

}  // namespace rig
