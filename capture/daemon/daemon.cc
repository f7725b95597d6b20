// The capture daemon: the acquisition protocol as named steps over one run's state.
#include "capture/daemon/daemon.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <optional>
#include <set>

#include <fmt/ranges.h>

#include "capture/daemon/adaptive_grid.h"
#include "capture/daemon/metering.h"
#include "capture/plan/adaptive_bracket.h"
#include "capture/plan/bracket.h"
#include "process/io/image_io.h"
#include "process/io/raw_io.h"
#include "config/log.h"
#include "capture/daemon/progress.h"
#include "capture/devices/signals.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

bool Retryable(const Error& e) {
  return e.code == ErrorCode::kDevice || e.code == ErrorCode::kTimeout ||
         e.code == ErrorCode::kBusy || e.code == ErrorCode::kIo;
}

// Stored frames known to the journal, verified against their files.
struct StoredFrame {
  nlohmann::json record;
  bool verified = false;
};

// Moves a file out of the way without losing it: <dir>/.<reason>/<name>.<n>
Status MoveAside(const fs::path& file, const std::string& reason) {
  fs::path dir = file.parent_path() / ("." + reason);
  std::error_code ec;
  fs::create_directories(dir, ec);
  for (int n = 1; n < 10000; ++n) {
    fs::path dest = dir / fmt::format("{}.{}", file.filename().string(), n);
    if (fs::exists(dest)) continue;
    fs::rename(file, dest, ec);
    if (ec) return MakeError(ErrorCode::kIo, file.string(), "cannot move aside: {}", ec.message());
    Log("session")->warn("moved {} aside to {} ({})", file.string(), dest.string(), reason);
    return FsyncDirectory(file.parent_path());
  }
  return MakeError(ErrorCode::kIo, file.string(), "cannot move aside: too many copies");
}

std::string ExtensionOf(const nlohmann::json& rec) {
  std::string e = fs::path(rec.value("file", "")).extension().string();
  return e.empty() ? "" : e.substr(1);
}

// The extensions the processor merges (RAW files are stored, not merged).
bool IsImage(const std::string& ext) { return ext == "jpg" || ext == "png" || ext == "tif"; }

// The files of a frame processing reads: the RAW file where the session processes RAW, the
// camera's rendered image otherwise.
bool IsProcessed(const CameraConfig& camera, const std::string& ext) {
  return ProcessesRaw(camera) ? IsRawPath("x." + ext) : IsImage(ext);
}

}  // namespace

std::string CaptureSummary::ToString() const {
  double accounted =
      open_s + motion_s + settle_s + lamp_s + camera_s + storage_s + queue_wait_s + processing_tail_s;
  // The shutter is part of the camera's time only when the body waited it out; a simulated
  // camera renders at once, and its frames' exposures add up to more than its time.
  std::string shutter =
      exposure_s <= camera_s + 1e-9
          ? fmt::format(" (of which shutter {:.2f} s)", exposure_s)
          : fmt::format(" (the frames' exposures add up to {:.2f} s, not waited for: a simulated "
                        "camera)",
                        exposure_s);
  std::string s = fmt::format(
      "poses {}  frames {} (captured now {}, verified from before {}, redone {})  retries {}  "
      "faults {}\n"
      "time {:.2f} s: opening the devices {:.2f} s, motion {:.2f} s, settle {:.2f} s, lamp {:.2f} s, camera {:.2f} s{}, "
      "storage {:.2f} s, waiting on processing {:.2f} s, own overhead {:.2f} s",
      poses, frames, frames_captured, frames_verified, frames_redone, retries, faults, total_s,
      open_s, motion_s, settle_s, lamp_s, camera_s, shutter, storage_s, queue_wait_s,
      std::max(0.0, total_s - accounted));
  s += fmt::format(
      "\nprocessing: {} radiance maps, {} failed; decode {:.2f} s, response {:.2f} s, merge "
      "{:.2f} s, write {:.2f} s; {:.2f} s after the last frame",
      processing.merged, processing.failed.size(), processing.decode_s, processing.recover_s,
      processing.merge_s, processing.write_s, processing_tail_s);
  for (const auto& [pose, err] : processing.failed) s += fmt::format("\n  failed pose {}: {}", pose, err);
  if (!storage_error.empty()) s += fmt::format("\nstorage failed: {}", storage_error);
  return s;
}

// One run's state. The processor is declared before the progress bar, so that on an early
// return the bar is closed before the processing tail is waited for.
struct CaptureDaemon::RunState {
  CaptureSummary& sum;
  Clock::time_point t_start = Clock::now();
  std::vector<Pose> poses;                    // the grid, in visiting order
  std::string current_pose = "-";             // named by messages and fault records
  // What the journal says is stored: pose -> bracket index -> files (JPEG, RAW ...).
  std::map<std::string, std::map<int, std::vector<StoredFrame>>> stored;
  std::optional<nlohmann::json> plan_record;  // the plan of an earlier run (resume)
  bool was_done = false;                      // an earlier run journaled "capture_done"
  bool lamp_open = false, motor_open = false;  // what Park() must switch off and stop
  std::vector<double> exposures;              // the session's bracket, seconds
  int n_exp = 0;                              // exposures.size()
  bool adaptive = false;                      // bracket.mode = "adaptive"
  std::vector<Seconds> offered;               // the body's shutter speeds (adaptive plans)
  // Adaptive: each pose's journaled plan (bracket index -> exposure, seconds). A pose with a
  // plan keeps it for good; a pose without one is metered first.
  std::map<std::string, std::vector<double>> pose_plans;
  // grid.mode = "adaptive": the grid is the poses allowed; `chosen` the poses the journal's
  // "pose_chosen" records took, in order (a resume takes them again first), `grid_done` an
  // earlier run journaled the choice's end; `working` the processed file and bytes of the
  // frame the choice reads (the bracket's centre exposure) of the pose just visited.
  bool adaptive_grid = false;
  std::vector<std::string> chosen;
  bool grid_done = false;
  std::string working_pose;
  std::map<int, std::pair<std::string, std::vector<uint8_t>>> working;  // index -> file, bytes
  int working_factor = 0;  // the working images' shrink factor, from the first frame read
  int already = 0;                            // frames stored and verified before this run
  std::optional<BracketProcessor> processor;
  std::optional<Progress> progress;

  // Every file of bracket `index` at `pose` is stored and verified.
  bool IndexDone(const std::string& pose, int index) const {
    auto p = stored.find(pose);
    if (p == stored.end()) return false;
    auto i = p->second.find(index);
    if (i == p->second.end() || i->second.empty()) return false;
    for (const auto& f : i->second)
      if (!f.verified) return false;
    return true;
  }

  // The exposures of `pose`, by bracket index: its journaled plan (adaptive), the session's
  // bracket (fixed), or nothing yet (adaptive, not yet metered).
  const std::vector<double>* ExposuresOf(const std::string& pose) const {
    if (!adaptive) return &exposures;
    auto p = pose_plans.find(pose);
    return p == pose_plans.end() ? nullptr : &p->second;
  }
  // Every frame of `pose` is stored and verified (an unplanned adaptive pose is not).
  bool PoseDone(const std::string& pose) const {
    const std::vector<double>* e = ExposuresOf(pose);
    if (!e) return false;
    for (int i = 0; i < static_cast<int>(e->size()); ++i)
      if (!IndexDone(pose, i)) return false;
    return true;
  }
  // The bracket index and exposure of an adaptive pose's metering frame: index 0, the fixed
  // bracket's centre exposure.
  double MeteringExposure() const {
    std::vector<double> e = exposures;
    std::sort(e.begin(), e.end());
    return e[e.size() / 2];
  }
};

CaptureDaemon::CaptureDaemon(Session& session, Camera& camera, Motor& motor, Lamp& lamp,
                             CaptureOptions options)
    : session_(session), camera_(camera), motor_(motor), lamp_(lamp), options_(options) {}

// The acquisition protocol as its named steps: verify what is stored, plan, home, visit
// every pose, finish.
Status CaptureDaemon::Run(CaptureSummary* summary) {
  RunState run{*summary};
  Status st = [&]() -> Status {
    run.poses = PlanGrid(session_.config().grid);
    run.adaptive_grid = session_.config().grid.mode == "adaptive";
    RIG_TRY(VerifyStored(run));
    RIG_TRY(session_.journal().Append(
        {{"event", run.plan_record ? "resume" : "start"}, {"pid", ::getpid()}}));
    RIG_TRY(OpenDevices(run));
    RIG_TRY(Plan(run));
    StartProcessing(run);
    RIG_TRY(Home(run));
    run.progress.emplace(options_.progress ? run.sum.frames : 0, run.already);
    if (run.adaptive_grid) {
      RIG_TRY(VisitAdaptiveGrid(run));
    } else {
      for (const Pose& pose : run.poses) RIG_TRY(VisitPose(run, pose));
    }
    return Finish(run);
  }();
  if (!st.ok()) {
    // A fault, a stop or a full disk: the summary still tells what this run did, what processing
    // did and what failed (never "0 failed" below failed writes), and how long it took.
    if (run.progress) run.progress->Finish();
    if (run.processor && !run.sum.processing_collected) {
      auto t_tail = Clock::now();
      run.sum.processing = run.processor->Finish();
      run.sum.processing_tail_s = Since(t_tail);
      run.sum.processing_collected = true;
    }
    run.sum.total_s = Since(run.t_start);
  }
  return st;
}

// ---- Verify what is stored (resume) ---------------------------------------------------------

// Checks every stored frame against its journal record; damaged frames and files the
// journal never heard of are moved aside, to be captured again.
Status CaptureDaemon::VerifyStored(RunState& run) {
  ReadJournal(run);
  std::set<fs::path> known_files;
  for (auto& [pose, by_index] : run.stored)
    for (const auto& entry : by_index) RIG_TRY(VerifyIndex(run, pose, entry.first, known_files));
  return MoveAsideUnjournaled(run, known_files);
}

// Reads the earlier runs' plan, frames and "capture_done" from the journal.
void CaptureDaemon::ReadJournal(RunState& run) {
  for (const auto& r : session_.history().records) {
    std::string ev = r.value("event", "");
    if (ev == "plan") run.plan_record = r;
    if (ev == "capture_done") run.was_done = true;
    if (ev == "pose_chosen") run.chosen.push_back(r.at("pose").get<std::string>());
    if (ev == "grid_done") run.grid_done = true;
    // The first plan journaled for a pose stands (a pose is never planned twice).
    if (ev == "pose_plan")
      run.pose_plans.emplace(r.at("pose").get<std::string>(),
                             r.at("exposures_s").get<std::vector<double>>());
    if (ev != "frame") continue;
    auto& files = run.stored[r.at("pose").get<std::string>()][r.at("index").get<int>()];
    // A later record for the same file supersedes an earlier one (a redone frame).
    std::erase_if(files,
                  [&](const StoredFrame& f) { return ExtensionOf(f.record) == ExtensionOf(r); });
    files.push_back({r, false});
  }
}

// Verifies the files of one bracket index (size and CRC); one bad file redoes the index.
Status CaptureDaemon::VerifyIndex(RunState& run, const std::string& pose, int index,
                                  std::set<fs::path>& known_files) {
  const SessionLayout& layout = session_.layout();
  std::vector<StoredFrame>& files = run.stored.at(pose).at(index);
  bool all_ok = true;
  for (auto& f : files) {
    // The journal's reader confined "file" to frames/ (relative, no ".."); it is read
    // without following a link.
    const std::string rel = f.record.at("file").get<std::string>();
    fs::path p = layout.root / rel;
    auto bytes = ReadSessionFile(layout.root, rel);
    f.verified = bytes.ok() && bytes->size() == f.record.at("bytes").get<size_t>() &&
                 Crc32(*bytes) == f.record.at("crc32").get<uint32_t>();
    if (!f.verified) {
      all_ok = false;
      Log("session")->warn("pose={} frame {} ({}) is missing or damaged; it will be captured again",
                           pose, index, p.string());
      std::error_code ec;
      if (fs::exists(fs::symlink_status(p, ec))) RIG_TRY(MoveAside(p, "damaged"));
      RIG_TRY(session_.journal().Append({{"event", "frame_damaged"}, {"pose", pose},
                                         {"index", index}, {"file", f.record.at("file")}}));
    } else {
      known_files.insert(p);
    }
  }
  if (all_ok) return Ok();
  // The bracket index is redone whole (JPEG and RAW together): move the good half aside too.
  for (auto& f : files) {
    fs::path p = layout.root / f.record.at("file").get<std::string>();
    std::error_code ec;
    if (f.verified && fs::exists(fs::symlink_status(p, ec))) RIG_TRY(MoveAside(p, "superseded"));
    known_files.erase(p);
    f.verified = false;
  }
  ++run.sum.frames_redone;
  return Ok();
}

// Moves aside files that reached their final name but not the journal (a crash in between).
Status CaptureDaemon::MoveAsideUnjournaled(RunState& run, const std::set<fs::path>& known_files) {
  const SessionLayout& layout = session_.layout();
  if (!fs::exists(layout.frames())) return Ok();
  for (const auto& e : fs::recursive_directory_iterator(layout.frames())) {
    if (!e.is_regular_file() && !e.is_symlink()) continue;
    if (e.path().filename().string()[0] == '.') continue;
    if (e.path().parent_path().filename().string()[0] == '.') continue;
    if (known_files.count(e.path())) continue;
    RIG_TRY(MoveAside(e.path(), "unjournaled"));
    ++run.sum.frames_redone;
  }
  return Ok();
}

// ---- Devices and the plan -------------------------------------------------------------------

// Opens camera, motor and lamp (camera and motor with retries) and configures the camera.
Status CaptureDaemon::OpenDevices(RunState& run) {
  const CameraConfig& cc = session_.config().camera;
  const MotorConfig& mc = session_.config().motor;
  auto t_open = Clock::now();
  Status st = WithRetries(
      run, cc.retries, cc.retry_backoff_s, [&] { return camera_.Open(); }, nullptr);
  if (!st.ok()) return Fault(run, st.error(), camera_.Describe());
  // GRBL's Open() waits out the board's reset and banner (up to grbl.banner_timeout_s).
  st = WithRetries(run, mc.retries, mc.retry_backoff_s, [&] { return motor_.Open(); }, nullptr);
  if (!st.ok()) return Fault(run, st.error(), motor_.Describe());
  run.motor_open = true;
  // The grid against the controller's own travel, read at open: refused before anything moves.
  st = motor_.CheckReach(run.poses);
  if (!st.ok()) {
    Status f = Fault(run, st.error(), motor_.Describe());
    return Error{ErrorCode::kInvalidInput, f.error().message, f.error().context};
  }
  st = lamp_.Open();
  run.sum.open_s += Since(t_open);
  if (!st.ok()) return Fault(run, st.error(), lamp_.Describe());
  run.lamp_open = true;

  CameraSettings wanted_settings{cc.iso, cc.aperture, cc.white_balance, cc.capture_target,
                                 CapturesRaw(cc)};
  auto applied = camera_.Configure(wanted_settings);
  if (!applied.ok()) return Fault(run, applied.error(), camera_.Describe());
  return Ok();
}

// The plan: poses × exposures snapped to the body's shutter speeds; journaled on a first run,
// checked against the journal's on resume (the session's bracket stands).
Status CaptureDaemon::Plan(RunState& run) {
  auto speeds = camera_.ShutterSpeeds();
  if (!speeds.ok()) return Fault(run, speeds.error(), camera_.Describe());
  auto snapped = SnapToShutterSpeeds(WantedExposures(session_.config().bracket), *speeds);
  if (!snapped.ok()) return snapped.error().Within(camera_.Describe());
  for (Seconds s : *snapped) run.exposures.push_back(s.count());
  std::vector<std::string> pose_names;
  for (const auto& p : run.poses) pose_names.push_back(p.Name());
  // Two poses under one name would share frames and a radiance map.
  if (std::set<std::string>(pose_names.begin(), pose_names.end()).size() != pose_names.size())
    return MakeError(ErrorCode::kInvalidInput, "grid",
                     "two poses of the grid have the same name; use a coarser step");
  const std::string& mode = session_.config().bracket.mode;
  run.adaptive = mode == "adaptive";
  run.offered = *speeds;
  if (run.plan_record) {
    RIG_TRY(CheckPlan(run, pose_names));
  } else {
    // Adaptive: "exposures_s" is the fixed bracket the metering and the plans' longest
    // exposure derive from; each pose's own exposures follow in its "pose_plan" record.
    RIG_TRY(session_.journal().Append({{"event", "plan"}, {"poses", pose_names},
                                       {"exposures_s", run.exposures},
                                       {"bracket_mode", mode},
                                       {"grid_mode", session_.config().grid.mode},
                                       {"max_poses", AdaptiveMaxPoses(session_.config().grid,
                                                                      static_cast<int>(run.poses.size()))},
                                       {"camera", camera_.Describe()},
                                       {"motor", motor_.Describe()}, {"lamp", lamp_.Describe()}}));
  }
  run.n_exp = static_cast<int>(run.exposures.size());
  RIG_TRY(CheckStoredAgainstPlans(run));
  run.sum.poses = static_cast<int>(run.poses.size());
  // Adaptive: a pose not yet metered counts as the fixed bracket's length until its plan is
  // journaled. An adaptive grid plans its max_poses: the poses chosen so far, and the rest at
  // the fixed bracket's length.
  run.sum.frames = 0;
  std::vector<std::string> counted;
  if (run.adaptive_grid) {
    run.sum.poses = AdaptiveMaxPoses(session_.config().grid, static_cast<int>(run.poses.size()));
    counted = run.chosen;
    run.sum.frames += run.n_exp * std::max(0, run.sum.poses - static_cast<int>(counted.size()));
  } else {
    for (const auto& p : run.poses) counted.push_back(p.Name());
  }
  for (const auto& name : counted) {
    const std::vector<double>* e = run.ExposuresOf(name);
    const int n = e ? static_cast<int>(e->size()) : run.n_exp;
    run.sum.frames += n;
    for (int i = 0; i < (e ? n : 1); ++i) run.already += run.IndexDone(name, i) ? 1 : 0;
  }
  run.sum.frames_verified = run.already;
  Log("session")->info(
      "plan poses={} bracket={} exposures={} frames={} already_stored={} camera=\"{}\" "
      "motor=\"{}\"",
      run.poses.size(), mode, run.n_exp, run.sum.frames, run.already, camera_.Describe(),
      motor_.Describe());
  return Ok();
}

// Adaptive, on resume: every stored frame must be the one its pose's journaled plan asks for
// at its index (a pose not yet planned holds at most its metering frame). A frame that is not
// is refused, never redone over: the journal and the frames disagree, and nothing stored is
// touched until someone looks.
Status CaptureDaemon::CheckStoredAgainstPlans(RunState& run) {
  if (!run.adaptive) return Ok();
  const std::string journal = session_.layout().journal().string();
  for (const auto& [pose, by_index] : run.stored) {
    const std::vector<double>* plan = run.ExposuresOf(pose);
    for (const auto& [index, files] : by_index) {
      for (const auto& f : files) {
        const double t = f.record.at("exposure_s").get<double>();
        const std::string file = f.record.value("file", "");
        if (plan == nullptr && index != 0)
          return MakeError(ErrorCode::kInvalidInput, journal,
                           "pose {}: frame {} ({}) is stored, but the pose has no journaled plan",
                           pose, index, file);
        const double want = plan ? (index < static_cast<int>(plan->size())
                                        ? (*plan)[static_cast<size_t>(index)]
                                        : -1.0)
                                 : run.MeteringExposure();
        if (std::fabs(t - want) > 1e-9 * std::max(t, want))
          return MakeError(ErrorCode::kInvalidInput, journal,
                           "pose {}: frame {} ({}) was taken at {:.6g} s, but the pose's journaled "
                           "plan {}",
                           pose, index, file, t,
                           want < 0 ? fmt::format("has only {} frames", plan->size())
                                    : fmt::format("asks for {:.6g} s", want));
      }
    }
  }
  return Ok();
}

// On resume: the grid must be the journal's, and the bracket as long; the journal's stands.
Status CaptureDaemon::CheckPlan(RunState& run, const std::vector<std::string>& pose_names) {
  nlohmann::json& plan = *run.plan_record;  // non-const []: a missing key reads as null
  if (plan["poses"].get<std::vector<std::string>>() != pose_names)
    return MakeError(ErrorCode::kInvalidInput, session_.layout().journal().string(),
                     "the journal's plan has other poses than session.toml's grid");
  std::vector<double> before = plan["exposures_s"].get<std::vector<double>>();
  if (before.size() != run.exposures.size())
    return MakeError(ErrorCode::kInvalidInput, camera_.Describe(),
                     "the camera now offers a different bracket than the session started with");
  run.exposures = before;  // the session's bracket stands
  const std::string grid_mode =
      plan["grid_mode"].is_string() ? plan["grid_mode"].get<std::string>() : "full";
  if (grid_mode != session_.config().grid.mode)
    return MakeError(ErrorCode::kInvalidInput, session_.layout().journal().string(),
                     "the journal's plan has grid mode '{}', session.toml '{}'", grid_mode,
                     session_.config().grid.mode);
  const std::string mode = plan["bracket_mode"].is_string() ? plan["bracket_mode"].get<std::string>()
                                                             : std::string("fixed");
  if (mode != session_.config().bracket.mode)
    return MakeError(ErrorCode::kInvalidInput, session_.layout().journal().string(),
                     "the journal's plan has bracket mode '{}', session.toml '{}'", mode,
                     session_.config().bracket.mode);
  return Ok();
}

// Starts the processor (if asked) and hands it the complete poses from before whose
// radiance map is missing.
void CaptureDaemon::StartProcessing(RunState& run) {
  const SessionLayout& layout = session_.layout();
  if (options_.process) {
    const Config& config = session_.config();
    store_ = std::make_shared<MapStore>(
        config.process.hdr_pixel_type == "half" ? ExrPixelType::kHalf : ExrPixelType::kFloat,
        static_cast<size_t>(run.sum.poses), MapStore::DefaultMaxBytes());
    PlanSessionGram(*store_, config);
    run.processor.emplace(layout, config, store_.get());
  }
  for (const auto& p : run.poses) {
    if (!run.PoseDone(p.Name())) continue;
    if (fs::exists(layout.Hdr(p.Name()))) {
      // Merged before: read into the map store while the rig moves on.
      BracketJob job{p, {}, {}, {}};
      job.map_only = true;
      Submit(run, std::move(job));
      continue;
    }
    BracketJob job{p, {}, {}, {}};
    const int n = static_cast<int>(run.ExposuresOf(p.Name())->size());
    for (int i = 0; i < n; ++i) {
      for (const auto& f : run.stored[p.Name()][i]) {
        if (!IsProcessed(session_.config().camera, ExtensionOf(f.record))) continue;
        job.files.push_back(layout.root / f.record.at("file").get<std::string>());
        job.exposures_s.push_back(f.record.at("exposure_s").get<double>());
      }
    }
    Submit(run, std::move(job));
  }
}

// ---- Home, visit the poses --------------------------------------------------------------

// Homes the axes when anything is left to capture and motor.home_on_start says so, on start
// and on resume alike: a machine without limit switches cannot home, and must still resume.
Status CaptureDaemon::Home(RunState& run) {
  const MotorConfig& mc = session_.config().motor;
  bool all_done = true;
  for (const auto& p : run.poses) all_done = all_done && run.PoseDone(p.Name());
  // An adaptive grid: done when its choice ended and every pose it chose is stored.
  if (run.adaptive_grid) {
    all_done = run.grid_done;
    for (const auto& name : run.chosen) all_done = all_done && run.PoseDone(name);
  }
  if (all_done) return Ok();
  if (!mc.home_on_start) {
    if (run.plan_record)
      Log("session")->info("resume without homing (motor.home_on_start = false): the controller's "
                           "position is trusted");
    return Ok();
  }
  if (StopRequested()) return Interrupted(run);
  auto t0 = Clock::now();
  run.current_pose = "home";
  Status st = WithRetries(
      run, mc.retries, mc.retry_backoff_s, [&] { return motor_.Home(); },
      [&] { (void)motor_.Reconnect(); });
  run.sum.motion_s += Since(t0);
  if (!st.ok())
    return StopRequested() ? Interrupted(run) : Fault(run, st.error(), motor_.Describe());
  return session_.journal().Append({{"event", "homed"}});
}

// Visits one pose: move, settle, lamp on, the bracket's missing frames, lamp off, "pose_done",
// and the finished bracket to the processor. A pose stored whole is passed by.
Status CaptureDaemon::VisitPose(RunState& run, const Pose& pose) {
  const std::string name = pose.Name();
  run.current_pose = name;
  if (run.PoseDone(name)) return Ok();
  if (StopRequested()) return Interrupted(run);
  RIG_TRY(MoveTo(run, pose));
  RIG_TRY(Settle(run));
  RIG_TRY(LampOn(run));
  FreshImages fresh;
  // Adaptive, a pose without a journaled plan: meter it and journal its plan first.
  if (!run.ExposuresOf(name)) RIG_TRY(MeterAndPlan(run, pose, fresh));
  const std::vector<double> exposures = *run.ExposuresOf(name);
  for (int index = 0; index < static_cast<int>(exposures.size()); ++index) {
    if (run.IndexDone(name, index) || fresh.count(index)) continue;
    // A stop between frames: the frame in hand was finished and stored.
    if (StopRequested()) return Interrupted(run);
    RIG_TRY(CaptureFrame(run, pose, index, exposures[static_cast<size_t>(index)], fresh));
  }
  RIG_TRY(LampOff(run));
  RIG_TRY(session_.journal().Append({{"event", "pose_done"}, {"pose", name}}));
  if (options_.progress) run.progress->PoseDone(name);
  if (run.adaptive_grid) {
    // The frames the choice reads, before the bytes go to the processor.
    run.working_pose = name;
    run.working.clear();
    for (const auto& [index, f] : fresh) run.working[index] = {f.first.string(), f.second};
  }
  HandOff(run, pose, fresh);
  return Ok();
}

// ---- The adaptive grid ----------------------------------------------------------------------

// The bracket indices the choice reads: every frame of a fixed bracket (the same exposures at
// every pose), an adaptive bracket's metering frame (index 0: the centre exposure at every
// pose; the others differ from pose to pose).
std::vector<int> CaptureDaemon::WorkingIndices(const RunState& run) const {
  if (run.adaptive) return {0};
  std::vector<int> all;
  for (int i = 0; i < run.n_exp; ++i) all.push_back(i);
  return all;
}

// The working image of a visited pose (MeanOfFrames of WorkingIndices): the bytes just
// captured, or the stored files read back (a pose stored before a resume: the same bytes, so
// the same choice).
Result<cv::Mat> CaptureDaemon::WorkingFrame(RunState& run, const Pose& pose) {
  const std::string name = pose.Name();
  const int max_pixels = LightChoiceOptions{}.max_working_pixels;
  std::vector<cv::Mat> frames;
  for (int index : WorkingIndices(run)) {
    std::vector<uint8_t> bytes;
    std::string file;
    if (auto w = run.working.find(index); run.working_pose == name && w != run.working.end()) {
      file = w->second.first;
      bytes = w->second.second;
    } else {
      for (const auto& s : run.stored[name][index]) {
        if (!IsProcessed(session_.config().camera, ExtensionOf(s.record))) continue;
        const std::string rel = s.record.at("file").get<std::string>();
        auto read = ReadSessionFile(session_.layout().root, rel);
        if (!read.ok()) return read.error().Within("pose " + name);
        bytes = std::move(read).value();
        file = (session_.layout().root / rel).string();
      }
    }
    if (file.empty())
      return MakeError(ErrorCode::kInternal, "pose " + name,
                       "frame {} of the bracket is not stored", index);
    auto image = DecodeForChoice(bytes, file, max_pixels);
    if (!image.ok()) return image.error().Within("pose " + name);
    if (run.working_factor == 0) run.working_factor = WorkingFactorFor(*image, max_pixels);
    auto w = WorkingImage(*image, run.working_factor, file);
    if (!w.ok()) return w.error().Within("pose " + name);
    frames.push_back(std::move(w).value());
  }
  return MeanOfFrames(frames, "pose " + name);
}

// Takes the poses the journal chose (a resume), then each pose the choice proposes, journaling
// it with its reason before the arm moves, until the choice stops (max_poses, the target, every
// pose taken); its end is journaled once ("grid_done").
Status CaptureDaemon::VisitAdaptiveGrid(RunState& run) {
  const Config& config = session_.config();
  std::map<std::string, int> index_of;
  for (size_t i = 0; i < run.poses.size(); ++i) index_of[run.poses[i].Name()] = static_cast<int>(i);
  double pose_cost = AdaptivePoseCost(config, run.exposures);
  LightChooser chooser(AdaptiveGridDirections(config, run.poses),
                       AdaptiveGridOptions(config, run.poses, pose_cost));
  auto log = Log("session");
  for (size_t k = 0;; ++k) {
    LightChoiceStep step;
    if (k < run.chosen.size()) {
      auto it = index_of.find(run.chosen[k]);
      if (it == index_of.end())
        return MakeError(ErrorCode::kInvalidInput, session_.layout().journal().string(),
                         "choice {}: pose {} is not on the grid", k + 1, run.chosen[k]);
      step.light = it->second;
      step.reason = "journaled";
    } else if (run.grid_done) {
      return Ok();  // the journal says the choice ended here: no more, whatever a replay says
    } else {
      RIG_ASSIGN_OR_RETURN(LightChooser::Proposal next, chooser.Propose());
      if (next.stop) {
        if (k >= static_cast<size_t>(AdaptiveMaxPoses(config.grid, static_cast<int>(run.poses.size()))) &&
            k < run.poses.size())
          next.stop_reason = fmt::format("max_poses: {} of the grid's {} poses taken", k, run.poses.size());
        log->info("adaptive grid: done after {} poses: {}", k, next.stop_reason);
        if (!run.grid_done)
          RIG_TRY(session_.journal().Append(
              {{"event", "grid_done"}, {"poses", k}, {"reason", next.stop_reason}}));
        run.grid_done = true;
        return Ok();
      }
      step = next.step;
      const Pose& p = run.poses[static_cast<size_t>(step.light)];
      nlohmann::json rec = {{"event", "pose_chosen"}, {"pose", p.Name()},
                            {"choice", k + 1},        {"seed", step.seed},
                            {"gap_deg", step.gap_deg}, {"reason", step.reason}};
      if (!step.seed) {
        rec["predicted_rms"] = step.predicted_rms;
        rec["remaining_rms"] = step.remaining_rms;
        rec["region_rms"] = step.region_rms;
        rec["floor_rms"] = step.floor_rms;
      }
      RIG_TRY(session_.journal().Append(rec));
      run.chosen.push_back(p.Name());
      log->info("pose_chosen pose={} choice={} {}", p.Name(), k + 1, step.reason);
    }
    const Pose& pose = run.poses[static_cast<size_t>(step.light)];
    RIG_TRY(VisitPose(run, pose));
    RIG_ASSIGN_OR_RETURN(cv::Mat img, WorkingFrame(run, pose));
    RIG_TRY(chooser.Take(step.light, img, step));
  }
}

// Adaptive: takes (or reads back) the pose's metering frame, bracket index 0 at the fixed
// bracket's centre exposure, plans the pose's exposures from it, and journals the plan with
// the reason for each frame before any planned frame is taken.
Status CaptureDaemon::MeterAndPlan(RunState& run, const Pose& pose, FreshImages& fresh) {
  const std::string name = pose.Name();
  const CameraConfig& cc = session_.config().camera;
  const double t_m = run.MeteringExposure();
  if (!run.IndexDone(name, 0)) {
    if (StopRequested()) return Interrupted(run);
    RIG_TRY(CaptureFrame(run, pose, 0, t_m, fresh));
  }
  // The metering frame's processed file: the bytes in hand, or the stored file read back
  // (a resumed pose metered before the kill plans from the same bytes, so the same plan).
  std::vector<uint8_t> bytes;
  std::string file;
  if (auto f = fresh.find(0); f != fresh.end()) {
    bytes = f->second.second;
    file = f->second.first.string();
  } else {
    for (const auto& s : run.stored[name][0]) {
      if (!IsProcessed(cc, ExtensionOf(s.record))) continue;
      const std::string rel = s.record.at("file").get<std::string>();
      auto read = ReadSessionFile(session_.layout().root, rel);
      if (!read.ok()) return read.error().Within("pose " + name);
      bytes = std::move(read).value();
      file = (session_.layout().root / rel).string();
    }
  }
  if (file.empty())
    return MakeError(ErrorCode::kInternal, "pose " + name, "the metering frame has no image");
  auto image = DecodeImageBytes(bytes, file);
  if (!image.ok()) return image.error().Within("pose " + name);
  auto metered = MeterFrame(*image, t_m, cc.linear, file);
  if (!metered.ok()) return metered.error().Within("pose " + name);
  AdaptiveBracketOptions o = MeteringWindow(image->depth(), cc.linear);
  o.headroom_stops = 0;  // the pose itself was metered
  // Consecutive frames about 2.2 stops apart (a JPEG window of 7.2 stops, 5 overlapping) and
  // at least three: mid-tones recorded by two frames. With the window's overlap of 0.5 stops
  // that the planner's evaluation used (metered through the true response), two frames a pose
  // came out at 1.145x the fixed bracket's error through the nominal metering curve and a
  // recovered response; these give 1.03x at 43% of the frames (docs/adaptive-brackets.md).
  o.overlap_stops = std::log2(o.x_hi / o.x_lo) - 2.2;
  o.min_frames = 3;
  // Never longer than the fixed bracket's longest: darkness it leaves is not chased.
  o.max_exposure = Seconds(*std::max_element(run.exposures.begin(), run.exposures.end()));
  auto plan = PlanAdaptiveBracket(*metered, run.offered, o);
  if (!plan.ok()) return plan.error().Within("pose " + name);
  std::vector<double> exposures{t_m};
  std::vector<std::string> reasons{
      fmt::format("metering: the fixed bracket's centre exposure ({:.4g} s)", t_m)};
  for (const auto& f : plan->frames) {
    // A planned exposure the metering frame already holds is not taken twice.
    if (std::fabs(f.exposure.count() - t_m) <= 1e-9 * t_m) {
      reasons[0] += "; planned too: " + f.reason;
      continue;
    }
    exposures.push_back(f.exposure.count());
    reasons.push_back(f.reason);
  }
  RIG_TRY(session_.journal().Append(
      {{"event", "pose_plan"}, {"pose", name}, {"exposures_s", exposures}, {"reasons", reasons},
       {"metered_min", plan->e_min}, {"metered_max", plan->e_max},
       {"covered_min", plan->covered_min}, {"below_fraction", plan->below_fraction},
       {"above_fraction", plan->above_fraction}}));
  run.sum.frames += static_cast<int>(exposures.size()) - run.n_exp;  // the estimate, replaced
  Log("session")->info("pose_plan pose={} frames={} exposures_s=[{}] metered={:.4g}..{:.4g}", name,
                       exposures.size(), fmt::join(exposures, ", "), plan->e_min, plan->e_max);
  run.pose_plans[name] = std::move(exposures);
  return Ok();
}

// Moves the lamp to `pose`, reconnecting the controller between tries.
Status CaptureDaemon::MoveTo(RunState& run, const Pose& pose) {
  const MotorConfig& mc = session_.config().motor;
  auto t0 = Clock::now();
  Status st = WithRetries(
      run, mc.retries, mc.retry_backoff_s, [&] { return motor_.MoveTo(pose); },
      [&] {
        Status r = motor_.Reconnect();
        if (!r.ok()) Log("session")->warn("{}", r.error().ToString());
      });
  run.sum.motion_s += Since(t0);
  if (!st.ok())
    return StopRequested() ? Interrupted(run) : Fault(run, st.error(), motor_.Describe());
  return Ok();
}

// Waits for the arm to stop swinging (settle_time_s, scaled in a dry run).
Status CaptureDaemon::Settle(RunState& run) {
  const MotorConfig& mc = session_.config().motor;
  auto t0 = Clock::now();
  if (!SleepUnlessStopped(Seconds(mc.settle_time_s * options_.settle_scale)))
    return Interrupted(run);
  run.sum.settle_s += Since(t0);
  return Ok();
}

// Switches the lamp on (with the motor's retries).
Status CaptureDaemon::LampOn(RunState& run) {
  const MotorConfig& mc = session_.config().motor;
  auto t0 = Clock::now();
  Status st = WithRetries(
      run, mc.retries, mc.retry_backoff_s, [&] { return lamp_.On(); }, nullptr);
  run.sum.lamp_s += Since(t0);
  if (!st.ok())
    return StopRequested() ? Interrupted(run) : Fault(run, st.error(), lamp_.Describe());
  return Ok();
}

// Switches the lamp off (with the motor's retries); a failure is a fault even during a stop.
Status CaptureDaemon::LampOff(RunState& run) {
  const MotorConfig& mc = session_.config().motor;
  auto t0 = Clock::now();
  Status st = WithRetries(
      run, mc.retries, mc.retry_backoff_s, [&] { return lamp_.Off(); }, nullptr);
  run.sum.lamp_s += Since(t0);
  if (!st.ok()) return Fault(run, st.error(), lamp_.Describe());
  return Ok();
}

// ---- Capture a frame ------------------------------------------------------------------------

// Captures frame `index` of the bracket at `pose` (retrying; a body that dropped off the bus
// is opened again between tries) and stores its files.
Status CaptureDaemon::CaptureFrame(RunState& run, const Pose& pose, int index, double exposure,
                                   FreshImages& fresh) {
  const CameraConfig& cc = session_.config().camera;
  Result<CapturedFrame> frame = MakeError(ErrorCode::kInternal, "", "no capture");
  auto t0 = Clock::now();
  Status st = WithRetries(
      run, cc.retries, cc.retry_backoff_s,
      [&]() -> Status {
        frame = camera_.Capture(Seconds(exposure));
        if (!frame.ok()) return frame.error();
        return Ok();
      },
      [&] {
        camera_.Close();
        Status r = camera_.Open();
        if (!r.ok()) Log("session")->warn("{}", r.error().ToString());
      });
  run.sum.camera_s += Since(t0);
  if (!st.ok())
    return StopRequested() ? Interrupted(run) : Fault(run, st.error(), camera_.Describe());
  run.sum.exposure_s += frame->exposure.count();
  t0 = Clock::now();
  RIG_TRY(StoreFiles(run, pose, index, exposure, *frame, fresh));
  run.sum.storage_s += Since(t0);
  ++run.sum.frames_captured;
  if (options_.progress) {
    const std::vector<double>* e = run.ExposuresOf(pose.Name());
    run.progress->Frame(pose.Name(), index, e ? static_cast<int>(e->size()) : run.n_exp);
  }
  return Ok();
}

// Stores and journals each file of a captured frame; keeps the images' bytes for the hand-off.
// A storage failure parks the rig and ends the run (it is no device fault).
Status CaptureDaemon::StoreFiles(RunState& run, const Pose& pose, int index, double exposure_s,
                                 CapturedFrame& frame, FreshImages& fresh) {
  const std::string name = pose.Name();
  for (auto& file : frame.files) {
    nlohmann::json extra = {{"exposure_wanted_s", exposure_s}, {"ext", file.extension},
                            {"h_deg", pose.h_deg}, {"v_deg", pose.v_deg}};
    if (frame.exif_exposure) extra["exif_exposure_s"] = frame.exif_exposure->count();
    // The journal records the exposure the body applied; the file name carries it too.
    auto rec = session_.StoreFrame(name, index, exposure_s, file.extension, file.bytes, extra);
    if (!rec.ok()) {
      Park(run);
      run.sum.storage_error = rec.error().Within("pose " + name).ToString();
      return rec.error().Within("pose " + name);
    }
    if (IsProcessed(session_.config().camera, file.extension))
      fresh[index] = {session_.layout().root / (*rec)["file"].get<std::string>(),
                      std::move(file.bytes)};
  }
  return Ok();
}

// Hands the pose's finished bracket to the processor: fresh images with their bytes, frames
// stored earlier from their files.
void CaptureDaemon::HandOff(RunState& run, const Pose& pose, FreshImages& fresh) {
  const std::string name = pose.Name();
  BracketJob job{pose, {}, {}, {}};
  const std::vector<double>& exposures = *run.ExposuresOf(name);
  for (int i = 0; i < static_cast<int>(exposures.size()); ++i) {
    auto f = fresh.find(i);
    if (f != fresh.end()) {
      job.files.push_back(f->second.first);
      job.bytes.push_back(std::move(f->second.second));
    } else {
      for (const auto& s : run.stored[name][i]) {
        if (!IsProcessed(session_.config().camera, ExtensionOf(s.record))) continue;
        job.files.push_back(session_.layout().root / s.record.at("file").get<std::string>());
        job.bytes.emplace_back();
      }
    }
    job.exposures_s.push_back(exposures[static_cast<size_t>(i)]);
  }
  Submit(run, std::move(job));
}

// Queues a bracket for processing (if any); the time blocked on a full queue is counted.
void CaptureDaemon::Submit(RunState& run, BracketJob job) {
  if (!run.processor) return;
  auto t0 = Clock::now();
  run.processor->Submit(std::move(job));
  run.sum.queue_wait_s += Since(t0);
}

// ---- Finish -------------------------------------------------------------------------------

// Parks and closes the devices, journals "capture_done" (once per session), waits for the
// processing tail and closes the summary's clock.
Status CaptureDaemon::Finish(RunState& run) {
  run.progress->Finish();
  Park(run);
  lamp_.Close();
  motor_.Close();
  camera_.Close();
  if (!run.was_done) RIG_TRY(session_.journal().Append({{"event", "capture_done"}}));
  auto t_tail = Clock::now();
  if (run.processor) run.sum.processing = run.processor->Finish();
  run.sum.processing_collected = true;
  run.sum.processing_tail_s = Since(t_tail);
  run.sum.total_s = Since(run.t_start);
  return Ok();
}

// ---- Park, fault, interrupted, retries ------------------------------------------------------

// Leaves the rig safe: lamp off and motor stopped, where they were opened; errors only logged.
void CaptureDaemon::Park(RunState& run) {
  auto log = Log("session");
  if (run.lamp_open) {
    Status st = lamp_.Off();
    if (!st.ok()) log->error("lamp: cannot switch off: {}", st.error().ToString());
  }
  if (run.motor_open) {
    Status st = motor_.Stop();
    if (!st.ok()) log->error("motor: cannot stop: {}", st.error().ToString());
  }
}

// A device fault retries could not clear: park, journal a "fault" record, return kFault.
Status CaptureDaemon::Fault(RunState& run, const Error& e, const std::string& device) {
  auto log = Log("session");
  ++run.sum.faults;
  Park(run);
  // "pose P: <device>: message", each context once: of the inner context, the parts that
  // name this pose again or that the device's description already holds ("sim camera",
  // "/dev/ttyACM0") are left out.
  Error inner = e;
  const std::string pose = "pose " + run.current_pose;
  std::string kept;
  for (size_t start = 0; start <= inner.context.size();) {
    const size_t end = inner.context.find(": ", start);
    const std::string part = inner.context.substr(start, end == std::string::npos ? end : end - start);
    if (!part.empty() && part != pose && device.find(part) == std::string::npos)
      kept += (kept.empty() ? "" : ": ") + part;
    if (end == std::string::npos) break;
    start = end + 2;
  }
  inner.context = kept;
  Error err = inner.Within(device).Within(pose);
  log->error("fault: {}", err.ToString());
  Status st = session_.journal().Append({{"event", "fault"}, {"device", device},
                                         {"pose", run.current_pose}, {"error", err.ToString()}});
  if (!st.ok()) log->error("{}", st.error().ToString());
  return Error{ErrorCode::kFault, err.message, err.context};
}

// A stop (SIGINT/SIGTERM): park, journal an "interrupted" record, return kInterrupted.
Status CaptureDaemon::Interrupted(RunState& run) {
  auto log = Log("session");
  const std::string root = session_.layout().root.string();
  Park(run);
  int sig = StopSignal();
  log->warn("stopped by signal {} at pose {}; 'rig resume {}' continues", sig, run.current_pose,
            root);
  Status st = session_.journal().Append(
      {{"event", "interrupted"}, {"signal", sig}, {"pose", run.current_pose}});
  if (!st.ok()) log->error("{}", st.error().ToString());
  return MakeError(ErrorCode::kInterrupted, root, "interrupted by signal {}", sig);
}

// Runs `op`, retrying transient errors with doubling back-off; `recover` runs between tries.
Status CaptureDaemon::WithRetries(RunState& run, int retries, double backoff_s,
                                  const std::function<Status()>& op,
                                  const std::function<void()>& recover) {
  auto log = Log("session");
  for (int attempt = 0;; ++attempt) {
    Status st = op();
    if (st.ok()) {
      if (attempt > 0)
        log->warn("pose={} succeeded after {} retr{}", run.current_pose, attempt,
                  attempt == 1 ? "y" : "ies");
      return st;
    }
    if (!Retryable(st.error()) || attempt >= retries || StopRequested()) return st;
    ++run.sum.retries;
    log->warn("pose={} {} (retry {}/{} in {:.2f} s)", run.current_pose, st.error().ToString(),
              attempt + 1, retries, backoff_s * (1 << attempt));
    if (!SleepUnlessStopped(Seconds(backoff_s * (1 << attempt)))) return st;
    if (recover) recover();
  }
}

}  // namespace rig
