// Following a session's journal as it grows.
#include "capture/service/journal_tail.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <map>
#include <set>
#include <string>
#include <string_view>

#include "capture/session/journal_reader.h"
#include "config/log.h"

namespace rig {

void JournalTail::Update() {
  int fd = ::open(path_.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;  // not created yet
  struct stat st {};
  if (::fstat(fd, &st) == 0 && static_cast<uint64_t>(st.st_size) < offset_) {
    offset_ = 0;
    records_.clear();
    skipped_ = 0;
  }
  std::string buf;
  char chunk[65536];
  for (;;) {
    ssize_t n = ::pread(fd, chunk, sizeof chunk, static_cast<off_t>(offset_ + buf.size()));
    if (n <= 0) break;
    buf.append(chunk, static_cast<size_t>(n));
  }
  ::close(fd);
  size_t start = 0;
  for (size_t nl; (nl = buf.find('\n', start)) != std::string::npos; start = nl + 1) {
    // Each line through the journal's validated reader: a record the rest of the status code
    // reads with at()/get<>() is of the types it expects. A damaged or unexpected record is
    // the session validator's business (rig resume says which); the status counts it, passes
    // it by and goes on.
    const std::string_view line(buf.data() + start, nl + 1 - start);
    if (line.size() == 1) continue;
    auto parsed = ParseJournal(line, path_.string());
    if (!parsed.ok() || parsed->records.size() != 1) {
      if (skipped_ == 0)
        Log("session")->warn("daemon: {}: record skipped by the status: {}", path_.string(),
                             parsed.ok() ? "damaged" : parsed.error().ToString());
      ++skipped_;
      continue;
    }
    records_.push_back(std::move(parsed->records.front()));
  }
  offset_ += start;
}

JournalProgress JournalTail::Progress() const {
  JournalProgress p;
  std::map<std::string, int> pose_frames;  // pose -> its own bracket's length (adaptive)
  std::set<std::string> pose_done;         // "pose_done" records
  for (size_t i = 0; i < records_.size(); ++i) {
    const auto& r = records_[i];
    const std::string ev = r.value("event", "");
    if (ev == "start" || ev == "resume") {
      ++p.runs;
      p.last_run_record = i;
      p.capture_done = false;  // of this run
    } else if (ev == "plan" && r.contains("poses") && r["poses"].is_array()) {
      p.poses.clear();
      for (const auto& n : r["poses"])
        if (n.is_string()) p.poses.push_back(n.get<std::string>());
      p.exposures = r.contains("exposures_s") && r["exposures_s"].is_array()
                        ? static_cast<int>(r["exposures_s"].size())
                        : 0;
      p.adaptive_grid = r.value("grid_mode", "full") == "adaptive";
      p.max_poses = r.contains("max_poses") && r["max_poses"].is_number_integer()
                        ? r["max_poses"].get<int>()
                        : 0;
    } else if (ev == "pose_plan" && r.contains("pose") && r["pose"].is_string() &&
               r.contains("exposures_s") && r["exposures_s"].is_array()) {
      // An adaptive bracket: the pose's own frames (its first plan stands).
      pose_frames.emplace(r["pose"].get<std::string>(), static_cast<int>(r["exposures_s"].size()));
    } else if (ev == "pose_done" && r.contains("pose") && r["pose"].is_string()) {
      pose_done.insert(r["pose"].get<std::string>());
    } else if (ev == "pose_chosen" && r.contains("pose") && r["pose"].is_string()) {
      p.chosen.push_back(r["pose"].get<std::string>());
      p.last_choice = r;
    } else if (ev == "grid_done") {
      p.grid_done = r;
    } else if ((ev == "frame" || ev == "frame_damaged") && r.contains("pose") &&
               r["pose"].is_string() && r.contains("index") && r["index"].is_number_integer()) {
      auto key = std::make_pair(r["pose"].get<std::string>(), r["index"].get<int>());
      if (ev == "frame_damaged") {
        p.stored.erase(key);
        pose_done.erase(key.first);  // to be taken again
        continue;
      }
      p.stored.insert(key);
      const std::string file = r.value("file", "");
      const std::string ext = std::filesystem::path(file).extension().string();
      if (ext == ".jpg" || ext == ".png" || ext == ".tif" || ext == ".tiff" || ext == ".jpeg") {
        p.last_frame_file = file;
        p.last_frame_pose = key.first;
      }
    } else if (ev == "fault") {
      p.last_fault = r;
    } else if (ev == "interrupted") {
      p.last_interrupted = r;
    } else if (ev == "capture_done") {
      p.capture_done = true;
    }
  }
  // The poses in the order they are visited: the plan's, or an adaptive grid's chosen ones
  // (a pose is chosen before the arm moves to it).
  const std::vector<std::string>& order = p.adaptive_grid ? p.chosen : p.poses;
  for (size_t i = 0; i < order.size(); ++i) {
    auto own = pose_frames.find(order[i]);
    const int frames = own != pose_frames.end() ? own->second : p.exposures;
    bool whole = pose_done.count(order[i]) > 0 || frames > 0;
    for (int k = 0; k < frames && whole && !pose_done.count(order[i]); ++k)
      whole = p.stored.count({order[i], k}) > 0;
    if (whole) {
      p.poses_done.insert(order[i]);
    } else if (p.next_pose_index < 0) {
      p.next_pose_index = static_cast<int>(i);
      p.next_pose = order[i];
    }
  }
  return p;
}

}  // namespace rig
