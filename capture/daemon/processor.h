// Session processing: finished brackets become radiance maps (hdr/<pose>.exr) through one
// response curve per session (calib/response.csv), while capture goes on.
//
// The response is recovered once, jointly from the first `process.response_poses` brackets
// (or loaded from calib/ when a previous run stored it; linear frames skip recovery); every
// pose is then merged with it. The same code serves the capture daemon (a worker thread fed
// through a bounded queue) and `rig process` (stored brackets).
#pragma once

#include <functional>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "config/config.h"
#include "process/hdr/hdr.h"
#include "process/model/session/map_store.h"
#include "capture/plan/pose.h"
#include "capture/session/session_store.h"

namespace rig {

// One finished bracket: the stored frames of a pose.
struct BracketJob {
  Pose pose;
  std::vector<fs::path> files;          // absolute paths, in exposure order
  std::vector<double> exposures_s;      // applied exposures, ascending
  // Size and CRC-32 of each file as journaled when it was stored (empty: not known); a file
  // that no longer matches is refused as damaged, never merged.
  std::vector<std::pair<uint64_t, uint32_t>> journaled;
  // The bytes as captured, when at hand (saves reading them back); else read from files.
  std::vector<std::vector<uint8_t>> bytes;
  // The pose's radiance map is stored already (a resume): it is only read into the map
  // store, for the model fitted at the last frame.
  bool map_only = false;
};

struct ProcessingSummary {
  int merged = 0;                        // radiance maps written
  int skipped_up_to_date = 0;
  std::map<std::string, std::string> failed;  // pose -> error
  std::string response_id;
  double decode_s = 0, recover_s = 0, merge_s = 0, write_s = 0;
  int saturated_pixels = 0, black_pixels = 0;  // flagged, summed over poses
};

// The brackets a session's journal says are complete (every planned exposure stored),
// in capture order, with their files. Frames whose files are missing are left out.
Result<std::vector<BracketJob>> CompleteBrackets(const Session& session);

// Merges brackets into radiance maps. Not thread-safe by itself; BracketProcessor wraps it.
// Plans `store` to accumulate the session model's Gram matrix as the maps arrive
// (MapStore::PlanSelectionGram) for the poses of the configuration's grid, its light frame,
// lamp radiance and fit space, so that the model is fitted straight after the last map. Not
// when the lamp radiance comes from a reference patch (known only from every map).
void PlanSessionGram(MapStore& store, const Config& config);

class HdrStage {
 public:
  HdrStage(SessionLayout layout, Config config);
  // Feeds one bracket: buffered until the response exists, then merged.
  void Add(BracketJob job);
  // Recovers the response from what is buffered if not done yet, merges everything pending.
  void Flush();
  // Skips poses whose radiance map is newer than their frames and the response.
  void set_skip_up_to_date(bool skip) { skip_up_to_date_ = skip; }
  // Called after each pose is merged, skipped or failed (for a progress bar).
  void set_on_pose(std::function<void(const std::string& pose)> f) { on_pose_ = std::move(f); }
  // Every map written or found up to date is also kept in `store` (not owned; may be null).
  void set_map_store(MapStore* store) { store_ = store; }
  const ProcessingSummary& summary() const { return summary_; }

 private:
  bool EnsureResponse(bool force);
  void Merge(BracketJob& job);
  void MergeOne(BracketJob& job);
  void KeepStored(const std::string& pose, const fs::path& map);
  Result<Bracket> Decode(BracketJob& job);

  SessionLayout layout_;
  Config config_;
  std::optional<ResponseCurve> response_;
  std::vector<BracketJob> pending_;
  bool skip_up_to_date_ = false;
  bool recovery_failed_ = false;
  ProcessingSummary summary_;
  std::function<void(const std::string& pose)> on_pose_;
  MapStore* store_ = nullptr;
};

// A worker thread with a bounded queue in front of an HdrStage.
class BracketProcessor {
 public:
  // `store` (not owned; may be null) receives every radiance map (HdrStage::set_map_store).
  BracketProcessor(SessionLayout layout, Config config, MapStore* store = nullptr);
  ~BracketProcessor();
  // Blocks only while the queue is full: capture waits on processing then, and only then.
  void Submit(BracketJob job);
  // Drains the queue, flushes the stage, joins the worker.
  ProcessingSummary Finish();
  // How long Submit() has blocked in total (capture waiting on processing).
  double blocked_s() const { return blocked_s_; }

 private:
  void Run();
  HdrStage stage_;
  size_t capacity_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<BracketJob> queue_;
  bool closing_ = false;
  bool finished_ = false;
  double blocked_s_ = 0;
  std::thread worker_;
};

}  // namespace rig
