// The capture daemon.
#include "capture/daemon/daemon.h"

#include <chrono>
#include <functional>
#include <map>
#include <set>

#include "capture/plan/bracket.h"
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

}  // namespace

std::string CaptureSummary::ToString() const {
  double accounted = motion_s + settle_s + lamp_s + camera_s + storage_s + queue_wait_s;
  std::string s = fmt::format(
      "poses {}  frames {} (captured now {}, verified from before {}, redone {})  retries {}  "
      "faults {}\n"
      "time {:.2f} s: motion {:.2f}, settle {:.2f}, lamp {:.2f}, camera {:.2f} (of which "
      "shutter time {:.2f}), storage {:.2f}, waiting on processing {:.2f}, own overhead {:.2f}",
      poses, frames, frames_captured, frames_verified, frames_redone, retries, faults, total_s,
      motion_s, settle_s, lamp_s, camera_s, exposure_s, storage_s, queue_wait_s,
      std::max(0.0, total_s - accounted));
  s += fmt::format(
      "\nprocessing: {} radiance maps, {} failed; decode {:.2f} s, response {:.2f} s, merge "
      "{:.2f} s, write {:.2f} s; {:.2f} s after the last frame",
      processing.merged, processing.failed.size(), processing.decode_s, processing.recover_s,
      processing.merge_s, processing.write_s, processing_tail_s);
  for (const auto& [pose, err] : processing.failed) s += fmt::format("\n  failed pose {}: {}", pose, err);
  return s;
}

CaptureDaemon::CaptureDaemon(Session& session, Camera& camera, Motor& motor, Lamp& lamp,
                             CaptureOptions options)
    : session_(session), camera_(camera), motor_(motor), lamp_(lamp), options_(options) {}

Status CaptureDaemon::Run(CaptureSummary* summary) {
  auto log = Log("session");
  const Config& cfg = session_.config();
  const SessionLayout& layout = session_.layout();
  Journal& journal = session_.journal();
  CaptureSummary& sum = *summary;
  auto t_start = Clock::now();
  const std::vector<Pose> poses = PlanGrid(cfg.grid);
  std::string current_pose = "-";

  // ---- What is already stored (resume) --------------------------------------------------
  std::map<std::string, std::map<int, std::vector<StoredFrame>>> stored;  // pose->index->files
  std::optional<nlohmann::json> plan_record;
  bool was_done = false;
  for (const auto& r : session_.history().records) {
    std::string ev = r.value("event", "");
    if (ev == "plan") plan_record = r;
    if (ev == "capture_done") was_done = true;
    if (ev != "frame") continue;
    auto& files = stored[r.at("pose").get<std::string>()][r.at("index").get<int>()];
    // A later record for the same file supersedes an earlier one (a redone frame).
    std::erase_if(files, [&](const StoredFrame& f) { return ExtensionOf(f.record) == ExtensionOf(r); });
    files.push_back({r, false});
  }
  std::set<fs::path> known_files;
  for (auto& [pose, by_index] : stored) {
    for (auto& [index, files] : by_index) {
      bool all_ok = true;
      for (auto& f : files) {
        fs::path p = layout.root / f.record.at("file").get<std::string>();
        auto bytes = ReadFileBytes(p);
        f.verified = bytes.ok() && bytes->size() == f.record.at("bytes").get<size_t>() &&
                     Crc32(*bytes) == f.record.at("crc32").get<uint32_t>();
        if (!f.verified) {
          all_ok = false;
          log->warn("pose={} frame {} ({}) is missing or damaged; it will be captured again", pose,
                    index, p.string());
          if (fs::exists(p)) RIG_TRY(MoveAside(p, "damaged"));
          RIG_TRY(journal.Append({{"event", "frame_damaged"}, {"pose", pose}, {"index", index},
                                  {"file", f.record.at("file")}}));
        } else {
          known_files.insert(p);
        }
      }
      if (!all_ok) {
        // The bracket index is redone whole (JPEG and RAW together): move the good half aside too.
        for (auto& f : files) {
          fs::path p = layout.root / f.record.at("file").get<std::string>();
          if (f.verified && fs::exists(p)) RIG_TRY(MoveAside(p, "superseded"));
          known_files.erase(p);
          f.verified = false;
        }
        ++sum.frames_redone;
      }
    }
  }
  // Files that reached their final name but not the journal (a crash in between).
  if (fs::exists(layout.frames())) {
    for (const auto& e : fs::recursive_directory_iterator(layout.frames())) {
      if (!e.is_regular_file()) continue;
      if (e.path().filename().string()[0] == '.') continue;
      if (e.path().parent_path().filename().string()[0] == '.') continue;
      if (known_files.count(e.path())) continue;
      RIG_TRY(MoveAside(e.path(), "unjournaled"));
      ++sum.frames_redone;
    }
  }
  auto index_done = [&](const std::string& pose, int index) {
    auto p = stored.find(pose);
    if (p == stored.end()) return false;
    auto i = p->second.find(index);
    if (i == p->second.end() || i->second.empty()) return false;
    for (const auto& f : i->second)
      if (!f.verified) return false;
    return true;
  };

  RIG_TRY(journal.Append({{"event", plan_record ? "resume" : "start"}, {"pid", ::getpid()}}));

  // ---- Parking and fault handling ---------------------------------------------------------
  bool lamp_open = false, motor_open = false, camera_open = false;
  auto park = [&] {
    if (lamp_open) {
      Status st = lamp_.Off();
      if (!st.ok()) log->error("lamp: cannot switch off: {}", st.error().ToString());
    }
    if (motor_open) {
      Status st = motor_.Stop();
      if (!st.ok()) log->error("motor: cannot stop: {}", st.error().ToString());
    }
  };
  auto fault = [&](const Error& e, const std::string& device) -> Status {
    ++sum.faults;
    park();
    // "pose P: <device>: message" — the device's own context ("sim camera", "/dev/ttyACM0")
    // only when its description does not already name it.
    Error inner = e;
    if (!inner.context.empty() && device.find(inner.context) != std::string::npos) inner.context.clear();
    Error err = inner.Within(device).Within("pose " + current_pose);
    log->error("fault: {}", err.ToString());
    Status st = journal.Append({{"event", "fault"}, {"device", device}, {"pose", current_pose},
                                {"error", err.ToString()}});
    if (!st.ok()) log->error("{}", st.error().ToString());
    return Error{ErrorCode::kFault, err.message, err.context};
  };
  auto interrupted = [&]() -> Status {
    park();
    int sig = StopSignal();
    log->warn("stopped by signal {} at pose {}; 'rig resume {}' continues", sig, current_pose,
              layout.root.string());
    Status st = journal.Append({{"event", "interrupted"}, {"signal", sig}, {"pose", current_pose}});
    if (!st.ok()) log->error("{}", st.error().ToString());
    return MakeError(ErrorCode::kInterrupted, layout.root.string(), "interrupted by signal {}", sig);
  };
  // Runs `op`, retrying transient errors with doubling back-off; `recover` runs between tries.
  auto with_retries = [&](int retries, double backoff_s, const std::function<Status()>& op,
                          const std::function<void()>& recover) -> Status {
    for (int attempt = 0;; ++attempt) {
      Status st = op();
      if (st.ok()) {
        if (attempt > 0) log->warn("pose={} succeeded after {} retr{}", current_pose, attempt, attempt == 1 ? "y" : "ies");
        return st;
      }
      if (!Retryable(st.error()) || attempt >= retries || StopRequested()) return st;
      ++sum.retries;
      log->warn("pose={} {} (retry {}/{} in {:.2f} s)", current_pose, st.error().ToString(), attempt + 1,
                retries, backoff_s * (1 << attempt));
      if (!SleepUnlessStopped(Seconds(backoff_s * (1 << attempt)))) return st;
      if (recover) recover();
    }
  };

  // ---- Devices ----------------------------------------------------------------------------
  const auto& cc = cfg.camera;
  const auto& mc = cfg.motor;
  Status st = with_retries(cc.retries, cc.retry_backoff_s, [&] { return camera_.Open(); }, nullptr);
  if (!st.ok()) return fault(st.error(), camera_.Describe());
  camera_open = true;
  st = with_retries(mc.retries, mc.retry_backoff_s, [&] { return motor_.Open(); }, nullptr);
  if (!st.ok()) return fault(st.error(), motor_.Describe());
  motor_open = true;
  st = lamp_.Open();
  if (!st.ok()) return fault(st.error(), lamp_.Describe());
  lamp_open = true;
  (void)camera_open;

  CameraSettings wanted_settings{cc.iso, cc.aperture, cc.white_balance, cc.capture_target, cc.capture_raw};
  auto applied = camera_.Configure(wanted_settings);
  if (!applied.ok()) return fault(applied.error(), camera_.Describe());

  // ---- The plan: poses × exposures snapped to the body's shutter speeds -------------------
  auto speeds = camera_.ShutterSpeeds();
  if (!speeds.ok()) return fault(speeds.error(), camera_.Describe());
  auto snapped = SnapToShutterSpeeds(WantedExposures(cfg.bracket), *speeds);
  if (!snapped.ok()) return snapped.error().Within(camera_.Describe());
  std::vector<double> exposures;
  for (Seconds s : *snapped) exposures.push_back(s.count());
  std::vector<std::string> pose_names;
  for (const auto& p : poses) pose_names.push_back(p.Name());
  if (plan_record) {
    if ((*plan_record)["poses"].get<std::vector<std::string>>() != pose_names)
      return MakeError(ErrorCode::kInvalidInput, layout.journal().string(),
                       "the journal's plan has other poses than session.toml's grid");
    std::vector<double> before = (*plan_record)["exposures_s"].get<std::vector<double>>();
    if (before.size() != exposures.size())
      return MakeError(ErrorCode::kInvalidInput, camera_.Describe(),
                       "the camera now offers a different bracket than the session started with");
    exposures = before;  // the session's bracket stands
  } else {
    RIG_TRY(journal.Append({{"event", "plan"}, {"poses", pose_names}, {"exposures_s", exposures},
                            {"camera", camera_.Describe()}, {"motor", motor_.Describe()},
                            {"lamp", lamp_.Describe()}}));
  }
  const int n_exp = static_cast<int>(exposures.size());
  sum.poses = static_cast<int>(poses.size());
  sum.frames = sum.poses * n_exp;
  int already = 0;
  for (const auto& p : poses)
    for (int i = 0; i < n_exp; ++i) already += index_done(p.Name(), i) ? 1 : 0;
  sum.frames_verified = already;
  log->info("plan poses={} exposures={} frames={} already_stored={} camera=\"{}\" motor=\"{}\"",
            poses.size(), n_exp, sum.frames, already, camera_.Describe(), motor_.Describe());

  std::optional<BracketProcessor> processor;
  if (options_.process) processor.emplace(layout, cfg);
  auto submit = [&](BracketJob job) {
    if (!processor) return;
    auto t0 = Clock::now();
    processor->Submit(std::move(job));
    sum.queue_wait_s += Since(t0);
  };
  // Complete poses from before: processed again only where their radiance map is missing.
  for (const auto& p : poses) {
    bool complete = true;
    for (int i = 0; i < n_exp; ++i) complete = complete && index_done(p.Name(), i);
    if (!complete || fs::exists(layout.Hdr(p.Name()))) continue;
    BracketJob job{p, {}, {}, {}};
    for (int i = 0; i < n_exp; ++i) {
      for (const auto& f : stored[p.Name()][i]) {
        std::string ext = ExtensionOf(f.record);
        if (ext == "jpg" || ext == "png" || ext == "tif") {
          job.files.push_back(layout.root / f.record.at("file").get<std::string>());
          job.exposures_s.push_back(f.record.at("exposure_s").get<double>());
        }
      }
    }
    submit(std::move(job));
  }

  // ---- Homing -------------------------------------------------------------------------------
  if (already < sum.frames && (mc.home_on_start || plan_record)) {
    if (StopRequested()) return interrupted();
    auto t0 = Clock::now();
    current_pose = "home";
    st = with_retries(mc.retries, mc.retry_backoff_s, [&] { return motor_.Home(); },
                      [&] { (void)motor_.Reconnect(); });
    sum.motion_s += Since(t0);
    if (!st.ok()) return StopRequested() ? interrupted() : fault(st.error(), motor_.Describe());
    RIG_TRY(journal.Append({{"event", "homed"}}));
  }

  // ---- The poses ----------------------------------------------------------------------------
  Progress progress(options_.progress ? sum.frames : 0, already);
  for (const auto& pose : poses) {
    const std::string name = pose.Name();
    current_pose = name;
    std::vector<int> missing;
    for (int i = 0; i < n_exp; ++i)
      if (!index_done(name, i)) missing.push_back(i);
    if (missing.empty()) continue;
    if (StopRequested()) return interrupted();

    auto t0 = Clock::now();
    st = with_retries(mc.retries, mc.retry_backoff_s, [&] { return motor_.MoveTo(pose); },
                      [&] {
                        Status r = motor_.Reconnect();
                        if (!r.ok()) log->warn("{}", r.error().ToString());
                      });
    sum.motion_s += Since(t0);
    if (!st.ok()) return StopRequested() ? interrupted() : fault(st.error(), motor_.Describe());
    t0 = Clock::now();
    if (!SleepUnlessStopped(Seconds(mc.settle_time_s * options_.settle_scale))) return interrupted();
    sum.settle_s += Since(t0);

    t0 = Clock::now();
    st = with_retries(mc.retries, mc.retry_backoff_s, [&] { return lamp_.On(); }, nullptr);
    sum.lamp_s += Since(t0);
    if (!st.ok()) return StopRequested() ? interrupted() : fault(st.error(), lamp_.Describe());

    BracketJob job{pose, {}, {}, {}};
    std::map<int, std::pair<fs::path, std::vector<uint8_t>>> fresh;  // index -> (file, bytes)
    for (int index : missing) {
      // A stop between frames: the frame in hand was finished and stored.
      if (StopRequested()) return interrupted();
      const double exposure = exposures[static_cast<size_t>(index)];
      Result<CapturedFrame> frame = MakeError(ErrorCode::kInternal, "", "no capture");
      t0 = Clock::now();
      st = with_retries(
          cc.retries, cc.retry_backoff_s,
          [&]() -> Status {
            frame = camera_.Capture(Seconds(exposure));
            if (!frame.ok()) return frame.error();
            return Ok();
          },
          [&] {
            // A body that dropped off the bus is opened again before the next try.
            camera_.Close();
            Status r = camera_.Open();
            if (!r.ok()) log->warn("{}", r.error().ToString());
          });
      sum.camera_s += Since(t0);
      if (!st.ok()) return StopRequested() ? interrupted() : fault(st.error(), camera_.Describe());
      sum.exposure_s += frame->exposure.count();
      t0 = Clock::now();
      for (auto& file : frame->files) {
        nlohmann::json extra = {{"exposure_wanted_s", exposure}, {"ext", file.extension},
                                {"h_deg", pose.h_deg}, {"v_deg", pose.v_deg}};
        if (frame->exif_exposure) extra["exif_exposure_s"] = frame->exif_exposure->count();
        // The journal records the exposure the body applied; the file name carries it too.
        auto rec = session_.StoreFrame(name, index, exposure, file.extension, file.bytes, extra);
        if (!rec.ok()) {
          park();
          return rec.error().Within("pose " + name);
        }
        if (file.extension == "jpg" || file.extension == "png" || file.extension == "tif")
          fresh[index] = {layout.root / (*rec)["file"].get<std::string>(), std::move(file.bytes)};
      }
      sum.storage_s += Since(t0);
      ++sum.frames_captured;
      if (options_.progress) progress.Frame(name, index, n_exp);
    }

    t0 = Clock::now();
    st = with_retries(mc.retries, mc.retry_backoff_s, [&] { return lamp_.Off(); }, nullptr);
    sum.lamp_s += Since(t0);
    if (!st.ok()) return fault(st.error(), lamp_.Describe());
    RIG_TRY(journal.Append({{"event", "pose_done"}, {"pose", name}}));
    if (options_.progress) progress.PoseDone(name);

    // Hand the finished bracket over (frames stored earlier come from their files).
    for (int i = 0; i < n_exp; ++i) {
      auto f = fresh.find(i);
      if (f != fresh.end()) {
        job.files.push_back(f->second.first);
        job.bytes.push_back(std::move(f->second.second));
      } else {
        for (const auto& s : stored[name][i]) {
          std::string ext = ExtensionOf(s.record);
          if (ext == "jpg" || ext == "png" || ext == "tif") {
            job.files.push_back(layout.root / s.record.at("file").get<std::string>());
            job.bytes.emplace_back();
          }
        }
      }
      job.exposures_s.push_back(exposures[static_cast<size_t>(i)]);
    }
    submit(std::move(job));
  }
  progress.Finish();
  park();
  lamp_.Close();
  motor_.Close();
  camera_.Close();
  if (!was_done) RIG_TRY(journal.Append({{"event", "capture_done"}}));
  auto t_tail = Clock::now();
  if (processor) sum.processing = processor->Finish();
  sum.processing_tail_s = Since(t_tail);
  sum.total_s = Since(t_start);
  return Ok();
}

}  // namespace rig
