// Session processing: response once per session, then a radiance map per pose.
#include "capture/daemon/processor.h"
#include "process/io/raw_io.h"

#include <algorithm>
#include <chrono>

#include <opencv2/imgcodecs.hpp>

#include "config/log.h"
#include "process/io/exr_io.h"
#include "process/io/image_io.h"
#include "process/model/harmonic/fit.h"

namespace rig {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

fs::path ResponsePath(const SessionLayout& l) { return l.calib() / "response.csv"; }

bool IsImageExtension(const std::string& ext) {
  return ext == "jpg" || ext == "jpeg" || ext == "png" || ext == "tif" || ext == "tiff";
}

}  // namespace

Result<std::vector<BracketJob>> CompleteBrackets(const Session& session) {
  const auto& records = session.history().records;
  std::vector<double> plan_exposures;
  bool adaptive = false;
  // Adaptive sessions: each pose's own exposures (its first "pose_plan" record stands).
  std::map<std::string, size_t> pose_plan_sizes;
  std::vector<std::string> order;
  // pose -> index -> latest frame record (a redone frame supersedes the earlier record)
  std::map<std::string, std::map<int, nlohmann::json>> frames;
  for (const auto& r : records) {
    std::string ev = r.value("event", "");
    if (ev == "plan") {
      plan_exposures = r.at("exposures_s").get<std::vector<double>>();
      adaptive = r.value("bracket_mode", std::string("fixed")) == "adaptive";
    } else if (ev == "pose_plan") {
      pose_plan_sizes.emplace(r.at("pose").get<std::string>(), r.at("exposures_s").size());
    } else if (ev == "frame") {
      const std::string file_ext = fs::path(r.value("file", "")).extension().string();
      std::string ext = r.value("ext", file_ext.empty() ? std::string() : file_ext.substr(1));
      // The files processing reads: RAW where the session processes RAW, else the rendered
      // image (RAW files travel beside their JPEG).
      if (ProcessesRaw(session.config().camera) ? !IsRawPath("x." + ext) : !IsImageExtension(ext))
        continue;
      std::string pose = r.at("pose").get<std::string>();
      if (frames.find(pose) == frames.end()) order.push_back(pose);
      frames[pose][r.at("index").get<int>()] = r;
    }
  }
  if (plan_exposures.empty())
    return MakeError(ErrorCode::kInvalidInput, session.layout().journal().string(),
                     "the journal has no plan record: no capture ever started here");
  std::vector<BracketJob> jobs;
  for (const auto& pose : order) {
    const auto& f = frames[pose];
    // The exposures the pose was planned with: its own plan (adaptive), else the session's.
    auto own = pose_plan_sizes.find(pose);
    if (adaptive && own == pose_plan_sizes.end()) continue;  // metered, never planned
    if (f.size() != (adaptive ? own->second : plan_exposures.size())) continue;
    RIG_ASSIGN_OR_RETURN(Pose p, ParsePoseName(pose));
    BracketJob job{p, {}, {}, {}, {}};
    bool ok = true;
    for (const auto& [index, rec] : f) {
      fs::path file = session.layout().root / rec.at("file").get<std::string>();
      if (!fs::exists(file)) {
        ok = false;
        break;
      }
      job.files.push_back(file);
      job.exposures_s.push_back(rec.at("exposure_s").get<double>());
      job.journaled.push_back({rec.value("bytes", uint64_t{0}), rec.value("crc32", uint32_t{0})});
    }
    if (ok) jobs.push_back(std::move(job));
  }
  return jobs;
}

// ---- HdrStage --------------------------------------------------------------------------

HdrStage::HdrStage(SessionLayout layout, Config config)
    : layout_(std::move(layout)), config_(std::move(config)) {}

Result<Bracket> HdrStage::Decode(BracketJob& job) {
  auto t0 = std::chrono::steady_clock::now();
  Bracket bracket(job.files.size());
  std::vector<std::optional<Error>> errors(job.files.size());
  // Decode on every configured thread: JPEG decoding dominates small-frame processing.
  cv::parallel_for_(cv::Range(0, static_cast<int>(job.files.size())), [&](const cv::Range& r) {
    for (int i = r.start; i < r.end; ++i) {
      const std::string name = job.files[i].string();
      std::vector<uint8_t> read;
      const bool in_memory = static_cast<size_t>(i) < job.bytes.size() && !job.bytes[i].empty();
      if (!in_memory) {
        auto bytes = ReadFileBytes(job.files[i]);
        if (!bytes.ok()) {
          errors[i] = bytes.error();
          continue;
        }
        read = std::move(bytes).value();
        if (static_cast<size_t>(i) < job.journaled.size() && job.journaled[i].first > 0) {
          const auto [size, crc] = job.journaled[i];
          if (read.size() != size || Crc32(read) != crc) {
            errors[i] = MakeError(ErrorCode::kCorrupt, name,
                                  "damaged since capture: {} bytes, CRC-32 {:08x}; the journal "
                                  "recorded {} bytes, CRC-32 {:08x}",
                                  read.size(), Crc32(read), size, crc);
            continue;
          }
        }
      }
      auto decoded = DecodeImageBytes(in_memory ? job.bytes[i] : read, name);
      if (!decoded.ok()) {
        errors[i] = decoded.error();
        continue;
      }
      cv::Mat img = std::move(decoded).value();
      bracket[i] = LdrFrame{img, Seconds(job.exposures_s[i]), job.files[i].string()};
    }
  });
  summary_.decode_s += SecondsSince(t0);
  for (auto& e : errors)
    if (e) return *e;
  job.bytes.clear();  // decoded: free the captured bytes
  return bracket;
}

bool HdrStage::EnsureResponse(bool force) {
  if (response_) return true;
  if (recovery_failed_) return false;
  auto log = Log("process");
  if (ProcessesRaw(config_.camera)) {
    response_ = LinearResponse(65536);  // LibRaw's linear 16-bit values
    summary_.response_id = response_->id;
    log->info("RAW frames are linear: no response recovery");
    return true;
  }
  if (config_.camera.linear) {
    response_ = LinearResponse(256);
    summary_.response_id = response_->id;
    log->info("frames are linear: no response recovery");
    return true;
  }
  if (fs::exists(ResponsePath(layout_))) {
    auto r = LoadResponse(ResponsePath(layout_).string());
    if (r.ok()) {
      response_ = std::move(r).value();
      summary_.response_id = response_->id;
      log->info("response loaded file={} id={}", ResponsePath(layout_).string(), response_->id);
      return true;
    }
    log->warn("{}; recovering it again", r.error().ToString());
  }
  size_t want = static_cast<size_t>(std::max(1, config_.process.response_poses));
  if (pending_.size() < want && !force) return false;
  if (pending_.empty()) return false;
  // Recover from brackets spread over what is pending (different lamp positions light
  // different parts of the scene: more of the response is seen).
  std::vector<Bracket> brackets;
  size_t n = std::min(want, pending_.size());
  for (size_t k = 0; k < n; ++k) {
    size_t i = k * pending_.size() / n;
    auto b = Decode(pending_[i]);
    if (!b.ok()) {
      log->error("{}", b.error().ToString());
      continue;
    }
    brackets.push_back(std::move(b).value());
  }
  auto t0 = std::chrono::steady_clock::now();
  ResponseOptions opt;
  opt.lambda = config_.process.response_lambda;
  opt.samples = config_.process.response_samples;
  opt.threads = config_.process.threads;
  auto r = brackets.empty() ? Result<ResponseCurve>(MakeError(ErrorCode::kInvalidInput, "calib", "no decodable bracket"))
                            : RecoverResponse(brackets, opt);
  summary_.recover_s += SecondsSince(t0);
  if (!r.ok()) {
    log->error("response recovery failed: {}", r.error().ToString());
    recovery_failed_ = true;
    for (auto& job : pending_) summary_.failed[job.pose.Name()] = "no response curve: " + r.error().ToString();
    pending_.clear();
    return false;
  }
  response_ = std::move(r).value();
  summary_.response_id = response_->id;
  Status st = SaveResponse(*response_, ResponsePath(layout_).string());
  if (!st.ok()) log->error("{}", st.error().ToString());
  log->info("response recovered brackets={} id={} time_s={:.3f}", brackets.size(), response_->id,
            summary_.recover_s);
  return true;
}

void HdrStage::Merge(BracketJob& job) {
  MergeOne(job);
  if (on_pose_) on_pose_(job.pose.Name());
}

void HdrStage::MergeOne(BracketJob& job) {
  std::string name = job.pose.Name();
  fs::path out = layout_.Hdr(name);
  if (skip_up_to_date_ && fs::exists(out)) {
    auto t_out = fs::last_write_time(out);
    bool fresh = !fs::exists(ResponsePath(layout_)) || fs::last_write_time(ResponsePath(layout_)) <= t_out;
    for (const auto& f : job.files) fresh = fresh && fs::exists(f) && fs::last_write_time(f) <= t_out;
    // A map merged with another weighting (or before the weighting was recorded) is stale.
    if (fresh) {
      auto attributes = ReadExrAttributes(out.string());
      fresh = attributes.ok() && attributes->count("merge_weighting_option") &&
              attributes->at("merge_weighting_option") == config_.process.merge_weighting;
    }
    if (fresh) {
      ++summary_.skipped_up_to_date;
      KeepStored(name, out);
      return;
    }
  }
  if (store_) store_->Drop(name);
  auto bracket = Decode(job);
  if (!bracket.ok()) {
    summary_.failed[name] = bracket.error().ToString();
    Log("process")->error("pose={} {}", name, bracket.error().ToString());
    return;
  }
  auto t0 = std::chrono::steady_clock::now();
  MergeOptions mo;
  mo.threads = config_.process.threads;
  mo.weighting = *ParseMergeWeighting(config_.process.merge_weighting);  // validated on load
  auto map = MergeBracket(*bracket, *response_, mo);
  summary_.merge_s += SecondsSince(t0);
  if (!map.ok()) {
    summary_.failed[name] = map.error().ToString();
    Log("process")->error("pose={} {}", name, map.error().ToString());
    return;
  }
  map->attributes["pose"] = name;
  map->attributes["h_deg"] = fmt::format("{}", job.pose.h_deg);
  map->attributes["v_deg"] = fmt::format("{}", job.pose.v_deg);
  summary_.saturated_pixels += map->saturated_pixels;
  summary_.black_pixels += map->black_pixels;
  t0 = std::chrono::steady_clock::now();
  Status st = WriteRadianceMap(out.string(), *map,
                               config_.process.hdr_pixel_type == "half" ? ExrPixelType::kHalf
                                                                        : ExrPixelType::kFloat,
                               config_.process.threads,
                               *ParseExrCompression(config_.process.hdr_compression));
  summary_.write_s += SecondsSince(t0);
  if (!st.ok()) {
    summary_.failed[name] = st.error().ToString();
    Log("process")->error("pose={} {}", name, st.error().ToString());
    return;
  }
  ++summary_.merged;
  if (store_) {
    // The values the file holds, for the model fitted at the last frame.
    Status kept = store_->Add(name, map->radiance, map->flags);
    if (!kept.ok()) Log("process")->warn("pose={} not kept for the model: {}", name, kept.error().ToString());
  }
  Log("process")->debug("merged pose={} saturated={} black={}", name, map->saturated_pixels,
                        map->black_pixels);
}

void HdrStage::KeepStored(const std::string& pose, const fs::path& map) {
  if (!store_ || store_->off()) return;
  Status st = store_->AddFile(pose, map.string());
  if (!st.ok()) {
    store_->Drop(pose);
    Log("process")->warn("pose={} radiance map not kept for the model: {}", pose, st.error().ToString());
  }
}

void HdrStage::Add(BracketJob job) {
  if (job.map_only) {
    KeepStored(job.pose.Name(), layout_.Hdr(job.pose.Name()));
    return;
  }
  summary_.failed.erase(job.pose.Name());
  // Shortest exposure first, whatever the bracket indices' order (an adaptive pose's metering
  // frame is index 0 at the centre exposure).
  std::vector<size_t> order(job.files.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return job.exposures_s[a] < job.exposures_s[b]; });
  auto permute = [&](auto& v) {
    if (v.size() != order.size()) return;
    std::remove_reference_t<decltype(v)> sorted;
    for (size_t i : order) sorted.push_back(std::move(v[i]));
    v = std::move(sorted);
  };
  permute(job.files);
  permute(job.exposures_s);
  permute(job.journaled);
  permute(job.bytes);
  pending_.push_back(std::move(job));
  if (!EnsureResponse(false)) return;
  for (auto& j : pending_) Merge(j);
  pending_.clear();
}

void HdrStage::Flush() {
  if (pending_.empty()) return;
  if (!EnsureResponse(true)) return;
  for (auto& j : pending_) Merge(j);
  pending_.clear();
}

// ---- BracketProcessor ------------------------------------------------------------------

void PlanSessionGram(MapStore& store, const Config& config) {
  const auto& patch = config.process.reference_patch_px;
  if (patch[2] > 0 && patch[3] > 0) return;
  auto options = FitOptionsFromConfig(config.process);
  if (!options.ok()) return;
  std::map<std::string, Vec3> directions;
  for (const Pose& p : PlanGrid(config.grid))
    directions[p.Name()] = LightDirection(p.h_deg, p.v_deg, config.light_frame);
  store.PlanSelectionGram(std::move(directions), config.lamp.radiance_rgb, options->transform,
                          config.light_frame);
}

BracketProcessor::BracketProcessor(SessionLayout layout, Config config, MapStore* store)
    : stage_(std::move(layout), config),
      capacity_(static_cast<size_t>(std::max(1, config.process.queue_depth))),
      worker_([this, store] {
        stage_.set_map_store(store);
        Run();
      }) {}

BracketProcessor::~BracketProcessor() { Finish(); }

void BracketProcessor::Submit(BracketJob job) {
  std::unique_lock lock(mu_);
  auto t0 = std::chrono::steady_clock::now();
  cv_.wait(lock, [&] { return queue_.size() < capacity_; });
  blocked_s_ += SecondsSince(t0);
  queue_.push_back(std::move(job));
  cv_.notify_all();
}

void BracketProcessor::Run() {
  for (;;) {
    BracketJob job;
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return !queue_.empty() || closing_; });
      if (queue_.empty()) return;
      job = std::move(queue_.front());
      queue_.pop_front();
      cv_.notify_all();
    }
    stage_.Add(std::move(job));
  }
}

ProcessingSummary BracketProcessor::Finish() {
  {
    std::lock_guard lock(mu_);
    if (finished_) return stage_.summary();
    closing_ = true;
    cv_.notify_all();
  }
  if (worker_.joinable()) worker_.join();
  stage_.Flush();
  std::lock_guard lock(mu_);
  finished_ = true;
  return stage_.summary();
}

}  // namespace rig
