// The journal's guarded reader: JSON lines, then each record's fields.
#include "capture/session/journal_reader.h"

#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "capture/plan/pose.h"

namespace rig {
namespace {

using json = nlohmann::json;

// Field checks of one record; the first problem found is kept.
class RecordCheck {
 public:
  explicit RecordCheck(const json& r) : r_(r) {}
  const std::string& problem() const { return problem_; }
  bool ok() const { return problem_.empty(); }

  // A string (optional or required).
  void String(const char* key, bool required = true) {
    const json* v = Get(key, required);
    if (v && !v->is_string()) Fail(key, "must be a string");
  }
  // An integer in [lo, hi].
  void Integer(const char* key, int64_t lo, int64_t hi, bool required = true) {
    const json* v = Get(key, required);
    if (!v) return;
    if (!v->is_number_integer()) return Fail(key, "must be an integer");
    if (v->is_number_unsigned()) {
      const uint64_t u = v->get<uint64_t>();
      if (u > static_cast<uint64_t>(hi)) return Fail(key, fmt::format("{} is out of range [{}, {}]", u, lo, hi));
      return;
    }
    const int64_t i = v->get<int64_t>();
    if (i < lo || i > hi) Fail(key, fmt::format("{} is out of range [{}, {}]", i, lo, hi));
  }
  // A finite number in [lo, hi] (lo exclusive when `lo_open`).
  void Number(const char* key, double lo, double hi, bool required = true, bool lo_open = false) {
    const json* v = Get(key, required);
    if (!v) return;
    if (!v->is_number()) return Fail(key, "must be a number");
    const double d = v->get<double>();
    if (!std::isfinite(d) || d < lo || d > hi || (lo_open && d == lo))
      Fail(key, fmt::format("{} is out of range {}{}, {}]", d, lo_open ? "(" : "[", lo, hi));
  }
  void Pose(const char* key, bool required = true) {
    const json* v = Get(key, required);
    if (!v) return;
    if (!v->is_string()) return Fail(key, "must be a string");
    const std::string p = PoseNameProblem(v->get_ref<const std::string&>());
    if (!p.empty()) Fail(key, p);
  }
  void File(const char* key) {
    const json* v = Get(key, true);
    if (!v) return;
    if (!v->is_string()) return Fail(key, "must be a string");
    const std::string& f = v->get_ref<const std::string&>();
    std::string p = SessionRelativePathProblem(f);
    if (p.empty() && f.rfind("frames/", 0) != 0) p = "is not inside the session's frames/";
    if (!p.empty()) Fail(key, fmt::format("'{}' {}", f.substr(0, 200), p));
  }
  void PoseList(const char* key) {
    const json* v = Get(key, true);
    if (!v) return;
    if (!v->is_array()) return Fail(key, "must be an array of pose names");
    if (v->size() > 1000000) return Fail(key, "has too many poses");
    for (const auto& e : *v) {
      if (!e.is_string()) return Fail(key, "must be an array of pose names");
      const std::string p = PoseNameProblem(e.get_ref<const std::string&>());
      if (!p.empty()) return Fail(key, p);
    }
  }
  void ExposureList(const char* key) {
    const json* v = Get(key, true);
    if (!v) return;
    if (!v->is_array() || v->empty() || v->size() > static_cast<size_t>(kMaxBracketIndex))
      return Fail(key, fmt::format("must be an array of 1 to {} exposure times", kMaxBracketIndex));
    for (const auto& e : *v) {
      if (!e.is_number()) return Fail(key, "must be an array of numbers");
      const double d = e.get<double>();
      if (!std::isfinite(d) || d <= 0 || d > 1e6) return Fail(key, fmt::format("holds {}, not an exposure time", d));
    }
  }
  void Object(const char* key, bool required = true) {
    const json* v = Get(key, required);
    if (v && !v->is_object()) Fail(key, "must be an object");
  }
  void StringMap(const char* key) {
    const json* v = Get(key, true);
    if (!v) return;
    if (!v->is_object()) return Fail(key, "must be an object of strings");
    for (const auto& [k, e] : v->items())
      if (!e.is_string()) return Fail(key, fmt::format("'{}' must be a string", k.substr(0, 100)));
  }
  void Changes(const char* key) {
    const json* v = Get(key, true);
    if (!v) return;
    if (!v->is_array()) return Fail(key, "must be an array");
    for (const auto& c : *v) {
      if (!c.is_object() || !c.contains("key") || !c["key"].is_string() || !c.contains("old") ||
          !c["old"].is_string() || !c.contains("new") || !c["new"].is_string())
        return Fail(key, "each change must be {\"key\", \"old\", \"new\"} strings");
    }
  }

 private:
  const json* Get(const char* key, bool required) {
    if (!ok()) return nullptr;
    auto it = r_.find(key);
    if (it == r_.end()) {
      if (required) Fail(key, "is missing");
      return nullptr;
    }
    return &*it;
  }
  void Fail(const char* key, const std::string& what) {
    if (problem_.empty()) problem_ = fmt::format("'{}' {}", key, what);
  }
  const json& r_;
  std::string problem_;
};

// Why `r` is not a valid record, or "".
std::string RecordProblem(const json& r) {
  if (!r.is_object()) return "a record must be a JSON object";
  auto ev = r.find("event");
  if (ev == r.end()) return "record has no 'event'";
  if (!ev->is_string()) return "'event' must be a string";
  const std::string& e = ev->get_ref<const std::string&>();
  RecordCheck c(r);
  c.String("t", false);
  constexpr int64_t kMaxInt = std::numeric_limits<int32_t>::max();
  if (e == "frame") {
    c.Pose("pose");
    c.Integer("index", 0, kMaxBracketIndex - 1);
    c.Number("exposure_s", 0, 1e6, true, true);
    c.File("file");
    c.Integer("bytes", 0, int64_t{1} << 40);
    c.Integer("crc32", 0, 0xffffffffLL);
    c.String("ext", false);
    c.Number("exposure_wanted_s", 0, 1e6, false);
    c.Number("exif_exposure_s", 0, 1e6, false);
    c.Number("h_deg", -1e6, 1e6, false);
    c.Number("v_deg", -1e6, 1e6, false);
  } else if (e == "plan") {
    c.PoseList("poses");
    c.ExposureList("exposures_s");
    c.String("camera", false);
    c.String("motor", false);
    c.String("lamp", false);
  } else if (e == "pose_plan") {
    c.Pose("pose");
    c.ExposureList("exposures_s");
  } else if (e == "pose_chosen") {
    c.Pose("pose");
    c.Integer("choice", 1, 1000000);
    c.String("reason", false);
    for (const char* k : {"gap_deg", "predicted_rms", "remaining_rms", "region_rms", "floor_rms"})
      c.Number(k, -1, 1e6, false);
  } else if (e == "grid_done") {
    c.Integer("poses", 0, 1000000);
    c.String("reason", false);
  } else if (e == "frame_damaged") {
    c.Pose("pose");
    c.Integer("index", 0, kMaxBracketIndex - 1);
    c.File("file");
  } else if (e == "pose_done") {
    c.Pose("pose");
  } else if (e == "config" || e == "settings_changed") {
    c.String("digest");
    c.StringMap("settings");
    if (e == "settings_changed") c.Changes("changes");
  } else if (e == "start" || e == "resume") {
    c.Integer("pid", 0, kMaxInt, false);
  } else if (e == "fault") {
    c.String("device", false);
    c.String("pose", false);
    c.String("error", false);
  } else if (e == "interrupted") {
    c.Integer("signal", 0, 1024, false);
    c.String("pose", false);
  }
  return c.problem();
}

}  // namespace

std::string SessionRelativePathProblem(std::string_view path) {
  if (path.empty()) return "is empty";
  if (path.size() > 4096) return "is too long";
  if (path.front() == '/') return "is an absolute path (a session holds only relative paths)";
  if (path.find('\0') != std::string_view::npos || path.find('\\') != std::string_view::npos)
    return "holds a NUL or backslash";
  size_t start = 0;
  while (start <= path.size()) {
    size_t slash = path.find('/', start);
    if (slash == std::string_view::npos) slash = path.size();
    const std::string_view part = path.substr(start, slash - start);
    if (part.empty()) return "has an empty component";
    if (part == "." || part == "..") return "leaves or re-enters a folder ('.' or '..')";
    start = slash + 1;
  }
  return "";
}

std::string PoseNameProblem(std::string_view name) {
  if (name.empty() || name.size() > 64) return "is not a pose name (1 to 64 characters)";
  for (char ch : name) {
    const bool ok = (ch >= '0' && ch <= '9') || ch == 'h' || ch == 'v' || ch == 'm' ||
                    ch == '.' || ch == '_';
    if (!ok) return fmt::format("'{}' is not a pose name (expected e.g. h030_v10)", name);
  }
  if (name == "." || name == "..") return "is not a pose name";
  auto p = ParsePoseName(std::string(name));
  if (!p.ok() || !std::isfinite(p->h_deg) || !std::isfinite(p->v_deg))
    return fmt::format("'{}' is not a pose name (expected e.g. h030_v10)", name);
  return "";
}

Result<JournalContents> ParseJournal(std::string_view text, const std::string& path) {
  JournalContents out;
  if (text.size() > kMaxJournalBytes)
    return MakeError(ErrorCode::kCorrupt, path, "{} bytes: a journal is at most {} bytes",
                     text.size(), kMaxJournalBytes);
  size_t pos = 0;
  int line_no = 0;
  try {
    while (pos < text.size()) {
      size_t nl = text.find('\n', pos);
      ++line_no;
      const std::string where = fmt::format("{}:{}", path, line_no);
      if (nl == std::string_view::npos) {
        // No newline: the write of this record never completed.
        out.torn_tail = true;
        out.warnings.push_back(fmt::format("{}: last record is incomplete (cut by a crash); ignored", where));
        break;
      }
      const std::string_view line = text.substr(pos, nl - pos);
      if (line.size() > kMaxJournalLineBytes)
        return MakeError(ErrorCode::kCorrupt, where, "a record of {} bytes (at most {})",
                         line.size(), kMaxJournalLineBytes);
      if (!line.empty()) {
        json j = json::parse(line.begin(), line.end(), nullptr, /*allow_exceptions=*/false);
        if (j.is_discarded()) {
          if (nl + 1 == text.size()) {
            out.torn_tail = true;
            out.warnings.push_back(fmt::format("{}: last record is damaged; ignored", where));
            break;
          }
          return MakeError(ErrorCode::kCorrupt, where, "journal record is not valid JSON");
        }
        const std::string problem = RecordProblem(j);
        if (!problem.empty()) {
          std::string ev = j.is_object() && j.contains("event") && j["event"].is_string()
                               ? j["event"].get<std::string>().substr(0, 40) + " record: "
                               : "";
          return MakeError(ErrorCode::kCorrupt, where, "{}{}", ev, problem);
        }
        out.records.push_back(std::move(j));
      }
      pos = nl + 1;
      out.valid_bytes = pos;
    }
  } catch (const std::exception& e) {  // nlohmann::json::exception, std::bad_alloc
    return MakeError(ErrorCode::kCorrupt, fmt::format("{}:{}", path, line_no),
                     "unreadable journal record: {}", e.what());
  }
  return out;
}

}  // namespace rig
