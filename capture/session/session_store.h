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

#include "config/atomic_file.h"
#include "config/config.h"
#include "config/settings.h"
#include "capture/session/journal_reader.h"
#include "config/result.h"

namespace rig {

namespace fs = std::filesystem;

// CRC-32 (zlib) of a byte string: the journal's checksum of every stored file.
uint32_t Crc32(std::span<const uint8_t> bytes);

// WriteFileAtomic and FsyncDirectory: config/atomic_file.h, the project's one writer.
Result<std::vector<uint8_t>> ReadFileBytes(const fs::path& path);

// The same inside a session folder, never through a symbolic link: `rel` (checked by
// SessionRelativePathProblem) is walked from `root` with openat(O_NOFOLLOW) component by
// component; missing folders are created (mkdirat) on the way. A link anywhere below `root`
// is refused (kInvalidInput), so nothing is written outside the session.
Status WriteSessionFile(const fs::path& root, const std::string& rel,
                        std::span<const uint8_t> bytes, bool overwrite = true);
Result<std::vector<uint8_t>> ReadSessionFile(const fs::path& root, const std::string& rel);
// Creates (or checks) the folder `rel` below `root` the same way; returns its path.
Result<fs::path> EnsureSessionFolder(const fs::path& root, const std::string& rel);
// The session's own names (.lock, journal.jsonl, log.txt, session.toml, frames/, hdr/,
// calib/, model/, truth/, render/ and every frames/<pose>/): refused when any is a symbolic
// link or not of its kind.
Status CheckSessionTree(const fs::path& root);

// Append-only JSON-lines journal. Every Append() is written and fsync'd before it returns.
class Journal {
 public:
  // Opens for appending (O_NOFOLLOW: a link is refused); a torn last line (from a crash) is
  // cut off first, and said so. `contents`, when given, receives what was read.
  static Result<Journal> Open(const fs::path& path, JournalContents* contents = nullptr);
  // Reads every intact record through ParseJournal (each record validated); a torn last
  // line is reported, not an error. A damaged line in the middle is an error naming its
  // line number. A symbolic link is refused.
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
  // Opens SESSION/.lock with O_NOFOLLOW (a link there is refused, never truncated).
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

  // Refuses (kInvalidInput, naming the settings) a session.toml that differs from the
  // configuration the journal recorded (its "config" record or the last "settings_changed").
  Status CheckStoredConfig() const;
  // Changes device settings ("camera.port=usb:001,004"; DeviceSettingKeys() only): validated,
  // journaled as "settings_changed" with old and new values and the new digest, then
  // session.toml rewritten atomically. Returns the changes.
  Result<std::vector<SettingChange>> ChangeDeviceSettings(const std::vector<std::string>& assignments);

  // After a first run that stored nothing (no camera found, a wrong port): removes what
  // Create() made — never a frame, never a folder that held anything before. Returns
  // whether the session folder itself is gone. Only for a session made by Create().
  bool RemoveIfNothingStored();
  // Whether this object made the session folder (Create) rather than opened one.
  bool created() const { return created_root_ || created_session_; }

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
  bool created_session_ = false;  // Create() wrote session.toml here
  bool created_root_ = false;     // ... and made the folder itself
};

}  // namespace rig
