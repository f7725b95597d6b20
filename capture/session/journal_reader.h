// The guarded reader of journal.jsonl: every record is checked field by field before
// anything uses it, so that the rest of the program can read records with at()/get<>()
// without a library exception. Callable on bytes (the fuzz harnesses do).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "config/result.h"

namespace rig {

// Limits (docs/robustness.md).
inline constexpr size_t kMaxJournalBytes = size_t{1} << 30;     // a whole journal
inline constexpr size_t kMaxJournalLineBytes = size_t{16} << 20;  // one record (a plan)
inline constexpr int kMaxBracketIndex = 1024;

// What was read back from a journal.
struct JournalContents {
  std::vector<nlohmann::json> records;
  bool torn_tail = false;     // the last line was cut by a crash (ignored)
  size_t valid_bytes = 0;     // length of the intact prefix
  std::vector<std::string> warnings;
};

// Parses journal text. `path` names the file in messages ("journal.jsonl:LINE: what").
// A torn last line (no newline, or damaged JSON on the last line) is reported in
// `warnings`, not an error; any other unreadable or invalid record is a kCorrupt error.
// Records of events this version does not know are kept as they are (objects with a string
// "event"); the events it uses (plan, frame, frame_damaged, pose_done, capture_done,
// config, settings_changed, start, resume, fault, interrupted, homed) are validated field
// by field.
Result<JournalContents> ParseJournal(std::string_view text, const std::string& path);

// A path taken from a record, relative to the session: not empty, not absolute, no "..",
// "." or empty component, no backslash or NUL; at most 4096 bytes. Empty string when
// acceptable, else why not.
std::string SessionRelativePathProblem(std::string_view path);

// A pose name as a folder name: made of [hm0-9._v] as Pose::Name() writes them, parseable.
std::string PoseNameProblem(std::string_view name);

}  // namespace rig
