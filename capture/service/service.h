// The capture service behind `rig daemon`: one process owns the devices and runs one session
// at a time from a queue of jobs (capture, resume, process); its status is read from the
// running job and from the session's own journal, tailed as it grows.
//
// Thread safety: every public member may be called from any thread (the HTTP server's
// threads call them concurrently); jobs run on one worker thread of the service's own.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "capture/devices/camera.h"
#include "capture/devices/lamp.h"
#include "capture/devices/motor.h"
#include "capture/plan/pose.h"
#include "capture/service/journal_tail.h"
#include "capture/session/session_store.h"
#include "config/config.h"

namespace rig {

// process/model/map_store.h (not included: it brings Eigen, which clashes with <resolv.h>'s
// _res macro in files that include cpp-httplib first).
class MapStore;

// The devices of one session, built by the executable (rig/backends.cc knows the backends;
// this library does not). `owner` keeps whatever the pointers point into alive.
struct ServiceDevices {
  Camera* camera = nullptr;
  Motor* motor = nullptr;
  Lamp* lamp = nullptr;
  double settle_scale = 1.0;  // the simulator's latency_scale in a dry run, else 1
  // Set when the camera is simulated: writes the ground truth into truth/.
  std::function<Status(const fs::path& truth_dir)> write_truth;
  std::shared_ptr<void> owner;
};

// What the service needs from the executable.
struct ServiceHooks {
  // Builds the devices a session's configuration names. Required.
  std::function<Result<ServiceDevices>(const Config&)> make_devices;
  // Fits the session's reflectance model from its radiance maps (after capture, process).
  // Optional: without it jobs stop at the radiance maps.
  // The maps in memory (may be null: read the files) from the run that merged them.
  std::function<Status(const Session&, const MapStore*)> fit_model;
};

struct ServiceOptions {
  // The configuration a capture job uses when it names none (`rig daemon --config`).
  std::optional<fs::path> default_config;
  // Every job's session lies under it, and a configuration named by path is a file there
  // (`rig daemon --sessions-root`; service_paths.h). Empty: every job naming a path is refused.
  fs::path sessions_root;
};

enum class JobKind { kCapture, kResume, kProcess };
const char* JobKindName(JobKind kind);

// One job of the queue, as the API shows it.
struct JobInfo {
  int id = 0;
  JobKind kind = JobKind::kCapture;
  fs::path session;       // absolute
  std::string config;     // capture: the configuration it was submitted with (path or name)
  std::shared_ptr<const Config> loaded;  // capture: that configuration, validated at submit
  bool dry_run = false;   // capture: every device simulated
  bool process = true;    // capture/resume: merge radiance maps and fit the model
  bool force = false;     // process: merge every pose again
  // queued | running | done | stopped (parked; resumable) | fault | failed | cancelled
  std::string state = "queued";
  std::string error;      // why it failed or faulted
  std::string summary;    // the capture summary, when it ran
  nlohmann::json timing;  // the capture summary's figures (seconds, counts), when it ran
  int exit_code = -1;     // what `rig capture`/`rig resume` would have returned
  double queued_s = 0, started_s = -1, finished_s = -1;  // seconds since the service started
  nlohmann::json ToJson() const;
};

// A job as submitted (POST /api/jobs): {"kind": "capture"|"resume"|"process",
// "session": DIR under the sessions root (absolute, or relative to it), "config_toml": TEXT
// with "config": ITS NAME (capture; or "config": a regular file under the sessions root of at
// most 1 MiB; default: the daemon's --config), "dry_run": bool, "process": bool, "force": bool}.
Result<JobInfo> ParseJobRequest(const nlohmann::json& request, const ServiceOptions& options);

class CaptureService {
 public:
  CaptureService(ServiceHooks hooks, ServiceOptions options = {});
  ~CaptureService();  // Shutdown()
  CaptureService(const CaptureService&) = delete;

  // Starts the worker thread.
  void Start();
  // Stops taking jobs, stops the running capture as SIGTERM does (parked, resumable), waits
  // for the worker. Idempotent.
  void Shutdown();

  // Validates and queues a job; returns it (with its id). Refused with kInvalidInput (bad
  // request, bad configuration: every diagnostic in the message) or kBusy (the session is
  // already queued or running).
  Result<JobInfo> Submit(const nlohmann::json& request);
  // Parks the rig as Ctrl-C does (the frame in hand finished, lamp off, motor stopped,
  // journal synced; journaled as SIGTERM) and holds the queue until Resume().
  // {"stopping": bool, "reason": ...}.
  nlohmann::json Stop();
  // Releases the queue and, when the last job was stopped or faulted (or `session` is given),
  // resumes that session first (at the head of the queue).
  // {"released": true, "job": the resume job or null}.
  Result<nlohmann::json> Resume(const std::optional<fs::path>& session, bool process = true);

  // GET /api/status: state (idle|capturing|processing|stopping|fault), the job, the session,
  // the pose (index, name, total), frames, ETA, model progress, last fault, queue, grid.
  nlohmann::json StatusJson();
  std::vector<JobInfo> Jobs();
  std::optional<JobInfo> Job(int id);
  // The journal of the current (else the last) session from record `since` on:
  // {"session", "since", "next", "records": [...]}.
  nlohmann::json Journal(size_t since);
  // The last stored frame as JPEG bytes (empty when there is none yet).
  std::vector<uint8_t> PreviewFrame();
  // The newest radiance map, tone-mapped (Ward) and JPEG-encoded (empty when none yet).
  std::vector<uint8_t> PreviewRadiance();
  // True once Shutdown() began (long-poll and event streams end then).
  bool shutting_down() const;

 private:
  struct Watched;  // the session whose journal the status follows
  void Worker();
  void RunJob(JobInfo& job);
  void RunCapture(JobInfo& job, Session& session);
  void RunProcess(JobInfo& job, Session& session);
  void Fit(JobInfo& job, Session& session, const MapStore* maps);
  void Watch(const fs::path& session);  // mu_ held
  double Now() const;
  JobInfo* Running();  // mu_ held

  ServiceHooks hooks_;
  ServiceOptions options_;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<int> queue_;          // ids of queued jobs, in order
  std::vector<JobInfo> jobs_;      // every job, by id - 1
  int running_ = 0;                // id of the running job, 0 when none
  std::string phase_ = "idle";     // capturing | processing | idle, of the running job
  bool stopping_ = false;          // a stop was asked for the running capture
  bool held_ = false;              // the queue waits for Resume() after a stop
  bool shutdown_ = false;
  std::string last_fault_;
  int last_fault_job_ = 0;
  std::unique_ptr<Watched> watched_;
  std::vector<uint8_t> radiance_jpeg_;   // cache of PreviewRadiance()
  fs::path radiance_path_;
  fs::file_time_type radiance_mtime_{};
  std::thread worker_;
};

}  // namespace rig
