// The capture service: the job queue, the worker that runs one session at a time, and the
// status read from the running job and the session's journal.
#include "capture/service/service.h"

#include <signal.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "capture/daemon/daemon.h"
#include "capture/daemon/processor.h"
#include "capture/devices/signals.h"
#include "capture/service/request_checks.h"
#include "capture/service/service_paths.h"
#include "config/log.h"
#include "process/io/exr_io.h"
#include "process/render/tonemap.h"

namespace rig {
namespace {

double Seconds3(double s) { return std::round(s * 1000.0) / 1000.0; }

Result<JobKind> ParseKind(const std::string& k) {
  if (k == "capture") return JobKind::kCapture;
  if (k == "resume") return JobKind::kResume;
  if (k == "process") return JobKind::kProcess;
  return MakeError(ErrorCode::kInvalidInput, "kind",
                   "unknown job kind '{}' (capture, resume or process)", k);
}

// A string member of the request, or an error naming it.
Result<std::string> StringField(const nlohmann::json& r, const char* key, bool required) {
  if (!r.contains(key) || r[key].is_null()) {
    if (required) return MakeError(ErrorCode::kInvalidInput, key, "missing");
    return std::string();
  }
  if (!r[key].is_string()) return MakeError(ErrorCode::kInvalidInput, key, "must be a string");
  return r[key].get<std::string>();
}

Result<bool> BoolField(const nlohmann::json& r, const char* key, bool fallback) {
  if (!r.contains(key) || r[key].is_null()) return fallback;
  if (!r[key].is_boolean()) return MakeError(ErrorCode::kInvalidInput, key, "must be true or false");
  return r[key].get<bool>();
}

std::string Diagnostics(const ConfigResult& cr) {
  std::string s;
  for (const auto& d : cr.diagnostics) s += (s.empty() ? "" : "\n") + d.ToString();
  return s;
}

// Where the problems of a configuration file are, without their messages (which quote keys
// and values of the file).
std::string Positions(const ConfigResult& cr) {
  std::string s = fmt::format("{} problem(s) in the configuration; check it with `rig "
                              "check-config`:", cr.diagnostics.size());
  for (const auto& d : cr.diagnostics) s += fmt::format(" line {} column {};", d.line, d.column);
  return s;
}

std::vector<uint8_t> EncodeJpeg(const cv::Mat& bgr8, int quality = 85) {
  std::vector<uint8_t> out;
  cv::imencode(".jpg", bgr8, out, {cv::IMWRITE_JPEG_QUALITY, quality});
  return out;
}

}  // namespace

const char* JobKindName(JobKind kind) {
  switch (kind) {
    case JobKind::kCapture: return "capture";
    case JobKind::kResume: return "resume";
    case JobKind::kProcess: return "process";
  }
  return "?";
}

nlohmann::json JobInfo::ToJson() const {
  nlohmann::json j = {{"id", id},          {"kind", JobKindName(kind)},
                      {"session", session.string()}, {"state", state},
                      {"queued_s", Seconds3(queued_s)}};
  if (kind == JobKind::kCapture) {
    j["config"] = config;
    j["dry_run"] = dry_run;
  }
  if (kind != JobKind::kProcess) j["process"] = process;
  if (kind == JobKind::kProcess) j["force"] = force;
  j["started_s"] = started_s < 0 ? nlohmann::json(nullptr) : nlohmann::json(Seconds3(started_s));
  j["finished_s"] = finished_s < 0 ? nlohmann::json(nullptr) : nlohmann::json(Seconds3(finished_s));
  j["exit_code"] = exit_code < 0 ? nlohmann::json(nullptr) : nlohmann::json(exit_code);
  if (!error.empty()) j["error"] = error;
  if (!summary.empty()) j["summary"] = summary;
  if (!timing.is_null()) j["timing"] = timing;
  return j;
}

Result<JobInfo> ParseJobRequest(const nlohmann::json& r, const ServiceOptions& options) {
  if (!r.is_object())
    return MakeError(ErrorCode::kInvalidInput, "request", "the job must be a JSON object");
  JobInfo job;
  RIG_ASSIGN_OR_RETURN(std::string kind, StringField(r, "kind", true));
  RIG_ASSIGN_OR_RETURN(job.kind, ParseKind(kind));
  RIG_ASSIGN_OR_RETURN(std::string session, StringField(r, "session", true));
  // Under the sessions root only (relative paths are taken from it), resolved through links.
  RIG_ASSIGN_OR_RETURN(job.session, ResolveUnderRoot(session, options.sessions_root, "session"));
  RIG_ASSIGN_OR_RETURN(job.process, BoolField(r, "process", true));
  RIG_ASSIGN_OR_RETURN(job.force, BoolField(r, "force", false));
  RIG_ASSIGN_OR_RETURN(job.dry_run, BoolField(r, "dry_run", false));
  const bool has_session = fs::exists(job.session / "session.toml");
  if (job.kind != JobKind::kCapture) {
    if (!has_session)
      return MakeError(ErrorCode::kNotFound, job.session.string(), "holds no session (no session.toml)");
    return job;
  }
  if (has_session)
    return MakeError(ErrorCode::kInvalidInput, job.session.string(),
                     "already holds a session; resume it (kind \"resume\") instead");
  RIG_ASSIGN_OR_RETURN(std::string config_name, StringField(r, "config", false));
  RIG_ASSIGN_OR_RETURN(std::string config_toml, StringField(r, "config_toml", false));
  if (std::string problem = ClientPathProblem(config_name); !problem.empty())
    return MakeError(ErrorCode::kInvalidInput, "config", "the name holds {}: refused", problem);
  ConfigResult cr;
  if (!config_toml.empty()) {
    if (config_toml.size() > kMaxJobConfigBytes)
      return MakeError(ErrorCode::kInvalidInput, "config_toml", "{} bytes: at most {}",
                       config_toml.size(), kMaxJobConfigBytes);
    job.config = config_name.empty() ? "request.config_toml" : config_name;
    cr = ParseConfig(config_toml, job.config);
    // The client's own text: its diagnostics in full.
    if (!cr.ok()) return MakeError(ErrorCode::kInvalidInput, job.config, "{}", Diagnostics(cr));
  } else if (!config_name.empty()) {
    // A file of the daemon's host, under the sessions root: where its problems are, never
    // what it holds (the answer goes to whoever asked).
    RIG_ASSIGN_OR_RETURN(std::string text, ReadJobConfigFile(config_name, options.sessions_root));
    job.config = config_name;
    cr = ParseConfig(text, config_name);
    if (!cr.ok()) return MakeError(ErrorCode::kInvalidInput, job.config, "{}", Positions(cr));
  } else {
    if (!options.default_config)
      return MakeError(ErrorCode::kInvalidInput, "config",
                       "a capture needs a configuration: \"config_toml\", \"config\" (a file "
                       "under the sessions root) or the daemon's --config");
    job.config = options.default_config->string();
    cr = LoadConfig(job.config);
    if (!cr.ok()) return MakeError(ErrorCode::kInvalidInput, job.config, "{}", Diagnostics(cr));
  }
  Config config = cr.config;
  if (job.dry_run) {
    // What `rig capture --dry-run` does: every device simulated.
    config.camera.backend = "sim";
    config.motor.backend = "sim";
    config.lamp.backend = "sim";
  }
  job.loaded = std::make_shared<const Config>(std::move(config));
  return job;
}

// The session the status follows: its journal, grid and when the job watching it started.
struct CaptureService::Watched {
  fs::path root;
  Config config;
  std::vector<Pose> grid;
  JournalTail tail;
  size_t records_at_start = 0;
  double started_s = 0;
};

CaptureService::CaptureService(ServiceHooks hooks, ServiceOptions options)
    : hooks_(std::move(hooks)), options_(std::move(options)) {
  RIG_CHECK(static_cast<bool>(hooks_.make_devices), "the service needs a device factory");
}

CaptureService::~CaptureService() { Shutdown(); }

void CaptureService::Start() {
  std::lock_guard lock(mu_);
  if (worker_.joinable() || shutdown_) return;
  worker_ = std::thread([this] { Worker(); });
}

void CaptureService::Shutdown() {
  {
    std::lock_guard lock(mu_);
    if (!shutdown_) {
      shutdown_ = true;
      if (running_ && (phase_ == "capturing" || phase_ == "starting")) {
        stopping_ = true;
        RequestStop(SIGTERM);
      }
    }
  }
  cv_.notify_all();
  if (worker_.joinable() && worker_.get_id() != std::this_thread::get_id()) worker_.join();
}

bool CaptureService::shutting_down() const {
  std::lock_guard lock(mu_);
  return shutdown_;
}

double CaptureService::Now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
}

JobInfo* CaptureService::Running() { return running_ ? &jobs_[static_cast<size_t>(running_ - 1)] : nullptr; }

Result<JobInfo> CaptureService::Submit(const nlohmann::json& request) {
  Result<JobInfo> parsed = ParseJobRequest(request, options_);
  std::lock_guard lock(mu_);
  if (shutdown_) return MakeError(ErrorCode::kBusy, "daemon", "shutting down; no new jobs");
  // A session a job is queued or running on is busy, whatever else the request says: checked
  // before the request's own refusals, which depend on how far that job has got (once it has
  // written session.toml, a capture would be "already holds a session").
  fs::path session;
  if (parsed.ok()) {
    session = parsed->session;
  } else if (request.is_object() && request.contains("session") && request["session"].is_string()) {
    auto resolved = ResolveUnderRoot(request["session"].get<std::string>(), options_.sessions_root, "session");
    if (resolved.ok()) session = *resolved;
  }
  if (!session.empty()) {
    for (int id : queue_)
      if (jobs_[static_cast<size_t>(id - 1)].session == session)
        return MakeError(ErrorCode::kBusy, session.string(), "already queued as job {}", id);
    if (JobInfo* r = Running(); r && r->session == session)
      return MakeError(ErrorCode::kBusy, session.string(), "job {} is running on it", r->id);
  }
  if (!parsed.ok()) return parsed.error();
  JobInfo job = std::move(*parsed);
  job.id = static_cast<int>(jobs_.size()) + 1;
  job.queued_s = Now();
  jobs_.push_back(job);
  queue_.push_back(job.id);
  Log("session")->info("daemon job={} kind={} session={} queued", job.id, JobKindName(job.kind),
                       job.session.string());
  cv_.notify_all();
  return job;
}

nlohmann::json CaptureService::Stop() {
  std::lock_guard lock(mu_);
  JobInfo* r = Running();
  if (!r) return {{"stopping", false}, {"reason", "nothing is running"}};
  // Before the devices are open ("starting"), the stop is taken when the capture begins.
  if (r->kind == JobKind::kProcess || (phase_ != "capturing" && phase_ != "starting"))
    return {{"stopping", false},
            {"job", r->id},
            {"reason", "the running job is processing; no device is in use"}};
  held_ = true;
  if (!stopping_) {
    stopping_ = true;
    // The daemon's own stop path: finish the frame in hand, lamp off, motor stopped,
    // "interrupted" journaled; a stop asked over the API is handled (and journaled) as SIGTERM.
    RequestStop(SIGTERM);
    Log("session")->warn("daemon job={} stop requested over the API", r->id);
  }
  return {{"stopping", true}, {"job", r->id}, {"held", true}};
}

Result<nlohmann::json> CaptureService::Resume(const std::optional<fs::path>& session, bool process) {
  std::unique_lock lock(mu_);
  if (shutdown_) return MakeError(ErrorCode::kBusy, "daemon", "shutting down; no new jobs");
  fs::path target;
  if (session) {
    target = *session;
  } else {
    for (auto it = jobs_.rbegin(); it != jobs_.rend(); ++it) {
      if (it->state == "queued" || it->state == "running") continue;
      if (it->kind != JobKind::kProcess && (it->state == "stopped" || it->state == "fault"))
        target = it->session;
      break;  // only the last finished job counts
    }
  }
  held_ = false;
  nlohmann::json out = {{"released", true}, {"job", nullptr}};
  if (target.empty()) {
    cv_.notify_all();
    return out;
  }
  lock.unlock();
  RIG_ASSIGN_OR_RETURN(JobInfo job,
                       ParseJobRequest({{"kind", "resume"}, {"session", target.string()}, {"process", process}},
                                       options_));
  lock.lock();
  for (int id : queue_)
    if (jobs_[static_cast<size_t>(id - 1)].session == job.session)
      return MakeError(ErrorCode::kBusy, job.session.string(), "already queued as job {}", id);
  if (JobInfo* r = Running(); r && r->session == job.session)
    return MakeError(ErrorCode::kBusy, job.session.string(), "job {} is running on it", r->id);
  job.id = static_cast<int>(jobs_.size()) + 1;
  job.queued_s = Now();
  jobs_.push_back(job);
  queue_.push_front(job.id);
  out["job"] = job.ToJson();
  cv_.notify_all();
  return out;
}

std::vector<JobInfo> CaptureService::Jobs() {
  std::lock_guard lock(mu_);
  return jobs_;
}

std::optional<JobInfo> CaptureService::Job(int id) {
  std::lock_guard lock(mu_);
  if (id < 1 || id > static_cast<int>(jobs_.size())) return std::nullopt;
  return jobs_[static_cast<size_t>(id - 1)];
}

// ---- The worker -------------------------------------------------------------------------

void CaptureService::Worker() {
  for (;;) {
    JobInfo job;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return shutdown_ || (!queue_.empty() && !held_); });
      if (shutdown_) {
        for (int id : queue_) jobs_[static_cast<size_t>(id - 1)].state = "cancelled";
        queue_.clear();
        return;
      }
      running_ = queue_.front();
      queue_.pop_front();
      JobInfo& j = jobs_[static_cast<size_t>(running_ - 1)];
      j.state = "running";
      j.started_s = Now();
      phase_ = "starting";
      stopping_ = false;
      job = j;
    }
    ClearRequestedStop();
    RunJob(job);
    {
      std::lock_guard lock(mu_);
      job.finished_s = Now();
      jobs_[static_cast<size_t>(job.id - 1)] = job;
      if (job.state == "fault") {
        last_fault_ = job.error;
        last_fault_job_ = job.id;
      }
      running_ = 0;
      phase_ = "idle";
      stopping_ = false;
      Log("session")->info("daemon job={} {} exit_code={}", job.id, job.state, job.exit_code);
    }
    // A stop asked for this job must not stop the next one; a caught signal stays.
    ClearRequestedStop();
    if (CaughtSignal() != 0) {
      // SIGINT/SIGTERM to the daemon: the capture parked; no further job starts.
      std::lock_guard lock(mu_);
      shutdown_ = true;
      for (int id : queue_) jobs_[static_cast<size_t>(id - 1)].state = "cancelled";
      queue_.clear();
      return;
    }
  }
}

void CaptureService::RunJob(JobInfo& job) {
  Result<Session> session = job.kind == JobKind::kCapture
                                ? Session::Create(job.session, *job.loaded)
                                : Session::OpenExisting(job.session);
  if (!session.ok()) {
    job.state = "failed";
    job.error = session.error().ToString();
    job.exit_code = session.error().ExitCode();
    return;
  }
  {
    std::lock_guard lock(mu_);
    watched_ = std::make_unique<Watched>(Watched{session->layout().root, session->config(),
                                                 PlanGrid(session->config().grid),
                                                 JournalTail(session->layout().journal()), 0,
                                                 Now()});
    watched_->tail.Update();
    watched_->records_at_start = watched_->tail.records().size();
  }
  if (job.kind == JobKind::kProcess)
    RunProcess(job, *session);
  else
    RunCapture(job, *session);
}

void CaptureService::RunCapture(JobInfo& job, Session& session) {
  auto log = Log("session");
  auto devices = hooks_.make_devices(session.config());
  if (!devices.ok()) {
    job.state = "failed";
    job.error = devices.error().ToString();
    job.exit_code = devices.error().ExitCode();
    return;
  }
  const SessionLayout& layout = session.layout();
  if (devices->write_truth && !fs::exists(layout.truth() / "scene.json")) {
    Status st = devices->write_truth(layout.truth());
    if (!st.ok()) {
      job.state = "failed";
      job.error = st.error().Within("truth").ToString();
      job.exit_code = 1;
      return;
    }
  }
  CaptureOptions options;
  options.settle_scale = devices->settle_scale;
  options.process = job.process;
  options.progress = false;  // the status page is the progress
  CaptureDaemon daemon(session, *devices->camera, *devices->motor, *devices->lamp, options);
  {
    std::lock_guard lock(mu_);
    phase_ = "capturing";
    // A stop asked while the job was starting.
    if (stopping_ || shutdown_) RequestStop(SIGTERM);
  }
  CaptureSummary summary;
  Status st = daemon.Run(&summary);
  {
    std::lock_guard lock(mu_);
    phase_ = "processing";
  }
  job.summary = summary.ToString();
  job.timing = {{"poses", summary.poses},         {"frames", summary.frames},
                {"frames_captured", summary.frames_captured},
                {"frames_verified", summary.frames_verified},
                {"retries", summary.retries},     {"faults", summary.faults},
                {"total_s", summary.total_s},     {"open_s", summary.open_s},
                {"motion_s", summary.motion_s},
                {"settle_s", summary.settle_s},   {"lamp_s", summary.lamp_s},
                {"camera_s", summary.camera_s},   {"exposure_s", summary.exposure_s},
                {"storage_s", summary.storage_s}, {"queue_wait_s", summary.queue_wait_s}};
  if (!st.ok()) {
    const Error& e = st.error();
    job.error = e.ToString();
    if (e.code == ErrorCode::kInterrupted) {
      job.state = "stopped";
      job.exit_code = 128 + (StopSignal() ? StopSignal() : SIGTERM);
    } else if (e.code == ErrorCode::kFault) {
      job.state = "fault";
      job.exit_code = 1;
    } else {
      job.state = "failed";
      job.exit_code = e.ExitCode();
    }
    return;
  }
  if (!summary.processing.failed.empty()) {
    job.state = "failed";
    job.error = fmt::format("{} radiance map(s) failed", summary.processing.failed.size());
    job.exit_code = 1;
    return;
  }
  job.state = "done";
  job.exit_code = 0;
  if (job.process) Fit(job, session, daemon.map_store().get());
}

void CaptureService::RunProcess(JobInfo& job, Session& session) {
  {
    std::lock_guard lock(mu_);
    phase_ = "merging";
  }
  auto brackets = CompleteBrackets(session);
  if (!brackets.ok() || brackets->empty()) {
    job.state = "failed";
    job.error = brackets.ok() ? session.layout().root.string() + ": no complete bracket to process"
                              : brackets.error().ToString();
    job.exit_code = 2;
    return;
  }
  HdrStage stage(session.layout(), session.config());
  MapStore maps(session.config().process.hdr_pixel_type == "half" ? ExrPixelType::kHalf
                                                                  : ExrPixelType::kFloat,
                brackets->size(), MapStore::DefaultMaxBytes());
  if (hooks_.fit_model) {
    PlanSessionGram(maps, session.config());
    stage.set_map_store(&maps);
  }
  stage.set_skip_up_to_date(!job.force);
  for (auto& b : *brackets) stage.Add(std::move(b));
  stage.Flush();
  const ProcessingSummary& s = stage.summary();
  job.summary = fmt::format("radiance maps: {} merged, {} up to date, {} failed", s.merged,
                            s.skipped_up_to_date, s.failed.size());
  job.state = s.failed.empty() ? "done" : "failed";
  job.exit_code = s.failed.empty() ? 0 : 1;
  if (!s.failed.empty()) job.error = fmt::format("{} radiance map(s) failed", s.failed.size());
  Fit(job, session, &maps);
}

void CaptureService::Fit(JobInfo& job, Session& session, const MapStore* maps) {
  if (!hooks_.fit_model) return;
  {
    std::lock_guard lock(mu_);
    phase_ = "fitting";
    if (watched_) watched_->started_s = Now();
  }
  Status st = hooks_.fit_model(session, maps);
  if (!st.ok()) {
    job.state = "failed";
    job.error = st.error().Within("model").ToString();
    job.exit_code = st.error().ExitCode();
  }
}

// ---- Status -----------------------------------------------------------------------------

namespace {

// The session's model: the harmonic model.exr, or a PCA session's folder ([process]
// model_family = "pca"), whichever is newer.
fs::path SessionModelFile(const fs::path& root) {
  fs::path model_file = SessionLayout{root}.model() / "model.exr";
  std::error_code ec;
  const fs::path pca = SessionLayout{root}.model() / "pca";
  const auto pca_time = fs::last_write_time(pca / "info.json", ec);
  if (!ec) {
    const auto exr_time = fs::last_write_time(model_file, ec);
    if (ec || pca_time > exr_time) model_file = pca;
  }
  return model_file;
}

}  // namespace

// An adaptive grid's choice as the status reports it: how many poses chosen of how many, the
// predicted RMS error (8-bit codes) over the grid's span when the last pose was chosen and what
// every allowed pose would leave, by the choice's per-pixel model, and why it stopped.
static nlohmann::json AdaptiveChoiceJson(const JournalProgress& p) {
  nlohmann::json c = {{"mode", "adaptive"},
                      {"max_poses", p.max_poses},
                      {"chosen", p.chosen.size()},
                      {"allowed", p.poses.size()},
                      {"predicted_rms", nullptr},
                      {"floor_rms", nullptr},
                      {"reason", nullptr},
                      {"stopped", nullptr}};
  // The predicted RMS error (8-bit codes) over the grid's span when the last pose was
  // chosen, and what every allowed pose would leave, by the choice's per-pixel model.
  if (p.last_choice) {
    for (const char* k : {"region_rms", "floor_rms"})
      if (p.last_choice->contains(k) && (*p.last_choice)[k].is_number() && (*p.last_choice)[k].get<double>() >= 0)
        c[std::string(k) == "region_rms" ? "predicted_rms" : k] = (*p.last_choice)[k];
    c["reason"] = p.last_choice->value("reason", "");
  }
  if (p.grid_done) c["stopped"] = p.grid_done->value("reason", "");
  return c;
}

nlohmann::json CaptureService::StatusJson() {
  std::lock_guard lock(mu_);
  nlohmann::json s;
  const JobInfo* running = Running();
  JournalProgress p;
  if (watched_) {
    watched_->tail.Update();
    p = watched_->tail.Progress();
  }
  // The state, as Moonraker reports Klipper's: one word a client can switch on.
  std::string state = "idle";
  if (running && stopping_) {
    state = "stopping";
  } else if (running) {
    state = (phase_ == "capturing" && !p.capture_done) || phase_ == "starting" ? "capturing"
                                                                                : "processing";
  } else if (!jobs_.empty() && last_fault_job_ != 0) {
    // A fault stays the state until another job ran after it.
    bool later = false;
    for (const auto& j : jobs_) later = later || (j.id > last_fault_job_ && j.started_s >= 0);
    if (!later) state = "fault";
  }
  s["state"] = state;
  s["held"] = held_;
  s["job"] = running ? running->ToJson() : nlohmann::json(nullptr);
  const JobInfo* last = nullptr;
  for (const auto& j : jobs_)
    if (j.finished_s >= 0 && (!last || j.finished_s >= last->finished_s)) last = &j;
  s["last_job"] = last ? last->ToJson() : nlohmann::json(nullptr);
  nlohmann::json queue = nlohmann::json::array();
  for (int id : queue_) queue.push_back(jobs_[static_cast<size_t>(id - 1)].ToJson());
  s["queue"] = queue;
  s["last_fault"] = nullptr;
  if (!last_fault_.empty()) s["last_fault"] = {{"job", last_fault_job_}, {"error", last_fault_}};
  s["session"] = nullptr;
  s["pose"] = nullptr;
  s["frames"] = nullptr;
  s["eta_s"] = nullptr;
  s["model"] = nullptr;
  s["grid"] = nlohmann::json::array();
  if (!watched_) return s;

  const Watched& w = *watched_;
  s["session"] = w.root.string();
  int total_poses = static_cast<int>(p.poses.empty() ? w.grid.size() : p.poses.size());
  // An adaptive grid takes at most max_poses of the poses allowed, and as many as it chose
  // once the choice stopped.
  if (p.adaptive_grid)
    total_poses = p.grid_done ? static_cast<int>(p.chosen.size())
                              : (p.max_poses > 0 ? std::min(p.max_poses, total_poses) : total_poses);
  const int total_frames = total_poses * std::max(p.exposures, w.config.bracket.count);
  const int stored = static_cast<int>(p.stored.size());
  int this_run = 0;
  for (size_t i = w.records_at_start; i < w.tail.records().size(); ++i)
    this_run += w.tail.records()[i].value("event", "") == "frame" ? 1 : 0;
  s["frames"] = {{"stored", stored}, {"total", total_frames}, {"this_job", this_run}};
  s["poses_done"] = p.poses_done.size();
  if (p.poses.empty() && !w.grid.empty() && w.config.grid.mode != "adaptive") {
    // No plan journaled yet: the capture begins at the grid's first pose.
    p.next_pose = w.grid.front().Name();
    p.next_pose_index = 0;
  }
  if (p.adaptive_grid) s["choice"] = AdaptiveChoiceJson(p);
  if (!p.next_pose.empty()) {
    nlohmann::json pose = {{"index", p.next_pose_index}, {"number", p.next_pose_index + 1},
                           {"name", p.next_pose}, {"total", total_poses}};
    for (const Pose& g : w.grid)
      if (g.Name() == p.next_pose) pose.update({{"h_deg", g.h_deg}, {"v_deg", g.v_deg}});
    s["pose"] = pose;
  }
  if (running && state == "capturing" && this_run > 0) {
    const double elapsed = Now() - w.started_s;
    s["eta_s"] = Seconds3(elapsed / this_run * std::max(0, total_frames - stored));
  }
  int maps = 0;
  for (const Pose& g : w.grid) maps += fs::exists(SessionLayout{w.root}.Hdr(g.Name())) ? 1 : 0;
  nlohmann::json model = {{"radiance_maps", maps}, {"poses", total_poses}};
  const fs::path model_file = SessionModelFile(w.root);
  if (running && phase_ == "fitting") {
    model["phase"] = "fitting";
    model["fitting_s"] = Seconds3(Now() - w.started_s);
  } else if (fs::exists(model_file)) {
    model["phase"] = "fitted";
    model["file"] = model_file.string();
  } else {
    model["phase"] = running ? "merging" : "none";
  }
  s["model"] = model;
  if (p.last_fault) s["journal_fault"] = *p.last_fault;
  if (p.last_interrupted) s["journal_interrupted"] = *p.last_interrupted;
  s["journal_records"] = w.tail.records().size();
  s["journal_skipped"] = w.tail.skipped();
  nlohmann::json grid = nlohmann::json::array();
  for (const Pose& g : w.grid) {
    const std::string n = g.Name();
    nlohmann::json e = {{"name", n}, {"h_deg", g.h_deg}, {"v_deg", g.v_deg},
                        {"state", p.poses_done.count(n) ? "done" : (n == p.next_pose ? "next" : "todo")}};
    if (p.adaptive_grid) {
      // "todo" on an adaptive grid: allowed, not chosen (yet, or ever once it stopped).
      const auto it = std::find(p.chosen.begin(), p.chosen.end(), n);
      if (it != p.chosen.end())
        e["choice"] = it - p.chosen.begin() + 1;
      else
        e["state"] = p.grid_done ? "skipped" : "allowed";
    }
    grid.push_back(e);
  }
  s["grid"] = grid;
  s["last_frame"] = p.last_frame_file.empty() ? nlohmann::json(nullptr)
                                              : nlohmann::json({{"file", p.last_frame_file},
                                                                {"pose", p.last_frame_pose}});
  return s;
}

nlohmann::json CaptureService::Journal(size_t since) {
  std::lock_guard lock(mu_);
  nlohmann::json out = {{"session", nullptr}, {"since", since}, {"next", since},
                        {"records", nlohmann::json::array()}};
  if (!watched_) return out;
  watched_->tail.Update();
  const auto& recs = watched_->tail.records();
  out["session"] = watched_->root.string();
  for (size_t i = since; i < recs.size(); ++i) out["records"].push_back(recs[i]);
  out["next"] = std::max(since, recs.size());
  return out;
}

std::vector<uint8_t> CaptureService::PreviewFrame() {
  fs::path root;
  std::string relative;
  {
    std::lock_guard lock(mu_);
    if (!watched_) return {};
    watched_->tail.Update();
    JournalProgress p = watched_->tail.Progress();
    if (p.last_frame_file.empty()) return {};
    root = watched_->root;
    relative = p.last_frame_file;
  }
  const fs::path file = root / relative;
  // Inside the session only: a planted link out of it is not followed.
  auto text = ReadSessionFile(root, relative, size_t{512} << 20);
  if (!text.ok()) {
    Log("session")->warn("daemon preview: {}", text.error().ToString());
    return {};
  }
  std::vector<uint8_t> bytes_v(text->begin(), text->end());
  auto* bytes = &bytes_v;
  if (file.extension() == ".jpg") return *bytes;
  cv::Mat img = cv::imdecode(*bytes, cv::IMREAD_COLOR);
  if (img.empty()) return {};
  if (img.depth() != CV_8U) img.convertTo(img, CV_8U, 1.0 / 256);
  return EncodeJpeg(img);
}

std::vector<uint8_t> CaptureService::PreviewRadiance() {
  fs::path newest;
  fs::file_time_type newest_t{};
  ProcessConfig process;
  {
    std::lock_guard lock(mu_);
    if (!watched_) return {};
    process = watched_->config.process;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(SessionLayout{watched_->root}.hdr(), ec)) {
      if (e.path().extension() != ".exr") continue;
      auto t = e.last_write_time(ec);
      if (!ec && (newest.empty() || t > newest_t)) {
        newest = e.path();
        newest_t = t;
      }
    }
    if (newest.empty()) return {};
    if (newest == radiance_path_ && newest_t == radiance_mtime_) return radiance_jpeg_;
  }
  // Read and tone-map outside the lock: status requests do not wait on it.
  auto radiance = ReadRgbExr(newest.string());
  if (!radiance.ok()) return {};
  auto mapped = ToneMap(*radiance, ToneMapOptionsFor(process));
  if (!mapped.ok()) return {};
  std::vector<uint8_t> jpeg = EncodeJpeg(*mapped);
  std::lock_guard lock(mu_);
  radiance_path_ = newest;
  radiance_mtime_ = newest_t;
  radiance_jpeg_ = jpeg;
  return jpeg;
}

}  // namespace rig
