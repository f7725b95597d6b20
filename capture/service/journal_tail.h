// A session's journal followed as it grows: the records appended since the last look, read
// without taking the session's lock (the writer fsyncs whole lines; a line not yet ended is
// left for the next look), each checked by the journal's validated reader (ParseJournal), and
// what they say about the session's progress.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace rig {

// What a journal says about its session.
struct JournalProgress {
  std::vector<std::string> poses;       // the plan's, in visiting order (empty before "plan")
  int exposures = 0;                    // bracket length of the plan
  std::set<std::pair<std::string, int>> stored;  // (pose, bracket index) stored, not damaged
  std::set<std::string> poses_done;     // poses whose every frame is stored
  std::string next_pose;                // the first pose of the plan with a frame missing
  int next_pose_index = -1;             // its index in `poses`
  std::string last_frame_file;          // relative to the session (of an image, not RAW)
  std::string last_frame_pose;
  std::optional<nlohmann::json> last_fault;        // the last "fault" record
  std::optional<nlohmann::json> last_interrupted;  // the last "interrupted" record
  bool capture_done = false;           // "capture_done" since the last start/resume
  size_t runs = 0;                      // "start" and "resume" records
  size_t last_run_record = 0;           // index of the last of them
  // An adaptive grid (the plan's grid_mode "adaptive"): `poses` are the poses allowed; the
  // poses taken are `chosen`, in the order chosen ("pose_chosen"), at most `max_poses`.
  bool adaptive_grid = false;
  int max_poses = 0;
  std::vector<std::string> chosen;
  std::optional<nlohmann::json> last_choice;  // the last "pose_chosen" record
  std::optional<nlohmann::json> grid_done;    // the "grid_done" record: why the choice stopped
};

class JournalTail {
 public:
  explicit JournalTail(std::filesystem::path path) : path_(std::move(path)) {}
  // Reads the lines appended since the last call. A journal that shrank (a torn tail cut off
  // by a resume) is read again from the start.
  void Update();
  const std::vector<nlohmann::json>& records() const { return records_; }
  const std::filesystem::path& path() const { return path_; }
  JournalProgress Progress() const;
  // Lines refused by the journal's validated reader (damaged, or a record of an unexpected
  // type): not in records().
  size_t skipped() const { return skipped_; }

 private:
  std::filesystem::path path_;
  uint64_t offset_ = 0;  // bytes of whole lines consumed
  std::vector<nlohmann::json> records_;
  size_t skipped_ = 0;
};

}  // namespace rig
