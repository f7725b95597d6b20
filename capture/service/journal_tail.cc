// Following a session's journal as it grows.
#include "capture/service/journal_tail.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

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
    } else if ((ev == "frame" || ev == "frame_damaged") && r.contains("pose") &&
               r["pose"].is_string() && r.contains("index") && r["index"].is_number_integer()) {
      auto key = std::make_pair(r["pose"].get<std::string>(), r["index"].get<int>());
      if (ev == "frame_damaged") {
        p.stored.erase(key);
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
  for (size_t i = 0; i < p.poses.size(); ++i) {
    bool whole = p.exposures > 0;
    for (int k = 0; k < p.exposures && whole; ++k) whole = p.stored.count({p.poses[i], k}) > 0;
    if (whole) {
      p.poses_done.insert(p.poses[i]);
    } else if (p.next_pose_index < 0) {
      p.next_pose_index = static_cast<int>(i);
      p.next_pose = p.poses[i];
    }
  }
  return p;
}

}  // namespace rig
