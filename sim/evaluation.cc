// The `rig evaluate` harness (sim/evaluation.h): sessions, every model, every HDR method,
// findings and the report.
#include "sim/evaluation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "capture/daemon/processor.h"
#include "capture/plan/pose.h"
#include "capture/session/session_store.h"
#include "config/builtin_config.h"
#include "config/config.h"
#include "config/console.h"
#include "config/log.h"
#include "process/evaluate/evaluate.h"
#include "process/evaluate/plot.h"
#include "process/hdr/hdr.h"
#include "process/io/exr_io.h"
#include "process/io/image_io.h"
#include "sim/bracket_synth.h"
#include "sim/dry_session.h"
#include "sim/truth.h"

namespace rig {
namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

Status WriteText(const fs::path& path, const std::string& text) {
  std::vector<uint8_t> bytes(text.begin(), text.end());
  return WriteFileAtomic(path, bytes, /*overwrite=*/true);
}

Status WritePng(const fs::path& path, const cv::Mat& img) {
  try {
    RIG_TRY(WriteImageFile(path.string(), img));
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kIo, path.string(), "cannot write: {}", e.what());
  }
  return Ok();
}

// ---- Sessions -------------------------------------------------------------------------------

struct LoadedSession {
  Config config;
  MethodEvalInput input;
  std::shared_ptr<const SimTruth> truth;  // shared with input.truth_rho
  fs::path root;
};

Result<LoadedSession> LoadSession(const fs::path& dir) {
  LoadedSession s;
  s.root = dir;
  RIG_ASSIGN_OR_RETURN(s.config, LoadConfigOrError((dir / "session.toml").string()));
  for (const Pose& p : PlanGrid(s.config.grid)) {
    const fs::path hdr = dir / "hdr" / (p.Name() + ".exr");
    if (!fs::exists(hdr)) continue;
    RIG_ASSIGN_OR_RETURN(cv::Mat radiance, ReadRgbExr(hdr.string()));
    s.input.radiance.push_back(radiance);
    s.input.h_deg.push_back(p.h_deg);
    s.input.v_deg.push_back(p.v_deg);
  }
  if (s.input.radiance.size() < 4) {
    return MakeError(ErrorCode::kInvalidInput, (dir / "hdr").string(),
                     "{} radiance maps: run 'rig process {}' first", s.input.radiance.size(), dir.string());
  }
  s.input.lamp_radiance_rgb = s.config.lamp.radiance_rgb;
  s.input.light_frame = s.config.light_frame;
  RIG_ASSIGN_OR_RETURN(s.input.selection, FitOptionsFromConfig(s.config.process));
  s.input.selection.order = -1;
  s.input.bytes_per_coefficient = s.config.process.model_pixel_type == "float" ? 4 : 2;
  s.input.max_order = s.config.process.max_order;
  // The session's default as `rig process` chooses it: its family, budget and threads.
  s.input.model_family = s.config.process.model_family;
  s.input.pca.max_bytes_per_pixel = s.config.process.pca_max_bytes_per_pixel;
  s.input.pca.threads = s.config.process.threads;
  s.input.selection.threads = s.config.process.threads;
  if (fs::exists(dir / "truth" / "scene.json")) {
    RIG_ASSIGN_OR_RETURN(SimTruth truth, LoadTruth((dir / "truth").string()));
    auto shared = std::make_shared<const SimTruth>(std::move(truth));
    s.truth = shared;
    s.input.truth_rho = [shared](double h, double v) { return shared->BrdfAtAngles(h, v); };
    // Held out: the centres of the grid's cells; beyond: past the far corner of the region.
    const auto& g = s.config.grid;
    for (double v = g.v_min_deg + g.v_step_deg / 2; v < g.v_max_deg; v += g.v_step_deg)
      for (double h = g.h_min_deg + g.h_step_deg / 2; h < g.h_max_deg; h += g.h_step_deg)
        s.input.held_out.push_back({h, v});
    for (double d = 1; d <= 3; ++d)
      s.input.outside.push_back({g.h_max_deg + d * g.h_step_deg, g.v_max_deg + d * g.v_step_deg});
  }
  return s;
}

// ---- HDR methods ----------------------------------------------------------------------------

struct HdrTrial {
  std::string dataset, method;
  int exposures = 0;
  double noise = 1;       // multiple of the default sensor noise
  double time_s = 0;      // response recovery + merge
  double log_rms = 0;     // log-radiance RMS error on well-recorded pixels (offset removed)
  std::string failure;
};

std::vector<cv::Mat> Images(const Bracket& b) {
  std::vector<cv::Mat> v;
  for (const auto& f : b) v.push_back(f.image);
  return v;
}

cv::Mat Times(const Bracket& b) {
  cv::Mat t(static_cast<int>(b.size()), 1, CV_32F);
  for (size_t i = 0; i < b.size(); ++i) t.at<float>(static_cast<int>(i)) = static_cast<float>(b[i].exposure.count());
  return t;
}

// Ours, OpenCV Debevec, OpenCV Robertson on one bracket (each recovers its own response from
// this bracket, then merges it), against the true radiance.
std::vector<HdrTrial> CompareHdr(const std::string& dataset, const Bracket& b, const cv::Mat& truth,
                                 double noise, int runs) {
  runs = std::max(1, runs);
  // The median of `runs` timings of `step`; the first run's result is the one measured.
  auto timed = [runs](auto&& step) {
    std::vector<double> s;
    for (int run = 0; run < runs; ++run) {
      const auto t0 = Clock::now();
      step(run);
      s.push_back(Since(t0));
    }
    return MedianSeconds(s);
  };
  std::vector<HdrTrial> out;
  auto trial = [&](const std::string& method) {
    HdrTrial t;
    t.dataset = dataset;
    t.method = method;
    t.exposures = static_cast<int>(b.size());
    t.noise = noise;
    return t;
  };
  {
    // One recovered response, merged with each weighting: "ours" is the default (a noise model
    // fitted to the bracket), then the photon and hat weightings; each timed as recovery + merge.
    const Bracket one[1] = {b};
    ResponseOptions ro;
    Result<ResponseCurve> resp = MakeError(ErrorCode::kInternal, dataset, "not recovered");
    const double recovery_s = timed([&](int run) {
      auto r = RecoverResponse(one, ro);
      if (run == 0) resp = std::move(r);
    });
    for (auto [name, weighting] : {std::pair{"ours", MergeWeighting::kNoise},
                                   std::pair{"ours-photon", MergeWeighting::kPhoton},
                                   std::pair{"ours-hat", MergeWeighting::kHat}}) {
      HdrTrial t = trial(name);
      MergeOptions mo;
      mo.max_unrecorded_fraction = 1.0;
      mo.weighting = weighting;
      Result<RadianceMap> map = MakeError(ErrorCode::kInternal, dataset, "not merged");
      if (!resp.ok()) map = resp.error();
      if (resp.ok()) {
        t.time_s = recovery_s + timed([&](int run) {
          auto m = MergeBracket(b, *resp, mo);
          if (run == 0) map = std::move(m);
        });
      } else {
        t.time_s = recovery_s;
      }
      if (map.ok()) {
        t.log_rms = synth::LogRmsError(map->radiance, truth, b);
      } else {
        t.failure = map.error().message;
        t.log_rms = kNan;
      }
      out.push_back(t);
    }
  }
  try {
    HdrTrial t = trial("opencv-debevec");
    cv::Mat response, hdr;
    t.time_s = timed([&](int) {
      cv::createCalibrateDebevec()->process(Images(b), response, Times(b));
      cv::createMergeDebevec()->process(Images(b), hdr, Times(b), response);
    });
    t.log_rms = synth::LogRmsError(hdr, truth, b);
    out.push_back(t);
    t = trial("opencv-robertson");
    t.time_s = timed([&](int) {
      cv::createCalibrateRobertson()->process(Images(b), response, Times(b));
      cv::createMergeRobertson()->process(Images(b), hdr, Times(b), response);
    });
    t.log_rms = synth::LogRmsError(hdr, truth, b);
    out.push_back(t);
  } catch (const cv::Exception& e) {
    HdrTrial t = trial("opencv");
    t.failure = e.what();
    out.push_back(t);
  }
  return out;
}

// A real HDR image as ground truth: scaled, clipped at 0, reduced to at most `max_width`.
Result<cv::Mat> LoadHdrTruth(const fs::path& path, int max_width) {
  cv::Mat e;
  if (path.extension() == ".exr") {
    RIG_ASSIGN_OR_RETURN(e, ReadRgbExr(path.string()));
  } else {
    try {
      e = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& ex) {
      return MakeError(ErrorCode::kInvalidInput, path.string(), "{}", ex.what());
    }
    if (e.empty()) return MakeError(ErrorCode::kInvalidInput, path.string(), "cannot read");
    e.convertTo(e, CV_32FC3);
  }
  e = cv::max(e, 0.0f);
  if (e.cols > max_width) {
    cv::Mat small;
    cv::resize(e, small, cv::Size(max_width, e.rows * max_width / e.cols), 0, 0, cv::INTER_AREA);
    e = small;
  }
  return e;
}

Bracket BracketFor(const cv::Mat& truth, int exposures, double noise, uint64_t seed) {
  static const synth::FilmicResponse kResponse;
  const double lo = synth::Percentile(truth, 0.005), hi = synth::Percentile(truth, 0.995);
  return synth::RenderBracket(truth, synth::ExposuresFor(lo, hi, exposures), kResponse, seed,
                              5e-5 * noise * noise, 2.5e-4 * noise);
}

// ---- Report helpers -------------------------------------------------------------------------

std::string HdrTable(const std::vector<HdrTrial>& trials) {
  std::string s = "| data | exposures | noise | method | time (s) | log-radiance RMS error |\n|---|---|---|---|---|---|\n";
  for (const auto& t : trials) {
    s += fmt::format("| {} | {} | {:g}x | {} | {:.4f} | {} |\n", t.dataset, t.exposures, t.noise,
                     t.method, t.time_s,
                     t.failure.empty() ? fmt::format("{:.4f}", t.log_rms) : "failed: " + t.failure);
  }
  return s;
}

std::string HdrCsv(const std::vector<HdrTrial>& trials) {
  std::string s = "dataset,exposures,noise,method,time_s,log_rms_error,failure\n";
  for (const auto& t : trials)
    s += fmt::format("{},{},{},{},{},{},\"{}\"\n", t.dataset, t.exposures, t.noise, t.method,
                     t.time_s, std::isfinite(t.log_rms) ? fmt::format("{}", t.log_rms) : "", t.failure);
  return s;
}

const char* const kHdrMethods[] = {"ours", "ours-photon", "ours-hat", "opencv-debevec",
                                   "opencv-robertson"};

// error against `key` (exposures or noise), one line per method.
cv::Mat HdrChart(const std::vector<HdrTrial>& trials, bool by_noise, const std::string& title) {
  std::vector<PlotSeries> series;
  for (const char* m : kHdrMethods) {
    PlotSeries s{m, {}, {}, {}, true};
    for (const auto& t : trials) {
      if (t.method != m) continue;
      s.x.push_back(by_noise ? t.noise : t.exposures);
      s.y.push_back(t.log_rms);
    }
    series.push_back(s);
  }
  PlotOptions o;
  o.title = title;
  o.x_label = by_noise ? "sensor noise (x the default shot and read noise)" : "exposures in the bracket";
  o.y_label = "log-radiance RMS error";
  o.log_y = true;
  o.log_x = by_noise;
  return DrawPlot(series, {}, o);
}

cv::Mat HdrSpeedChart(const std::vector<HdrTrial>& trials, int timing_runs) {
  std::vector<PlotSeries> series;
  for (const char* m : kHdrMethods) {
    PlotSeries s{m, {}, {}, {}, false};
    for (const auto& t : trials) {
      if (t.method != m) continue;
      s.x.push_back(t.time_s);
      s.y.push_back(t.log_rms);
      s.point_labels.push_back(t.dataset.substr(0, 14));
    }
    series.push_back(s);
  }
  PlotOptions o;
  o.title = "HDR methods: time against radiance error (response recovery + merge)";
  o.x_label = timing_runs > 1 ? fmt::format("time (s, median of {} runs)", timing_runs) : "time (s)";
  o.y_label = "log-radiance RMS error";
  o.log_x = o.log_y = true;
  return DrawPlot(series, {}, o);
}

struct SceneRow {
  std::string scene;
  int chosen = -1;
  std::vector<MethodResult> around;  // sh-rls at chosen-1, chosen, chosen+1
  std::string session_default;       // the scene's default model (family chosen per byte)
  std::optional<MethodResult> default_row;
  std::vector<FamilyFold> folds;     // the family choice under each held-out rule
};

// The HDR trials: on every bracket, then the stability sweeps on the first image.
struct HdrTrials {
  std::vector<HdrTrial> main, exposures, noise;
  int timing_runs = 1;  // each time_s the median of this many runs
};

// A dry run: every scene simulated under out/sessions/<scene> (sessions left by an
// interrupted evaluation reused); *scenes receives their names.
Status SimulateScenes(const EvaluationRequest& request, std::vector<std::string>* scenes) {
  ConfigResult cfg = LoadConfigOrBuiltIn(request.config_path);
  if (!cfg.ok()) return cfg.AsError();
  Config base = cfg.config;
  base.sim.width = request.width;
  base.sim.height = request.height;
  *scenes = request.quick ? std::vector<std::string>{"matte", "full"}
                          : std::vector<std::string>{"matte", "gloss", "sharp", "full"};
  for (const auto& scene : *scenes) {
    Config c = base;
    c.sim.scene = scene;
    const fs::path dir = request.out / "sessions" / scene;
    if (fs::exists(dir / "session.toml")) continue;  // an earlier, interrupted evaluation
    if (request.progress)
      request.progress(fmt::format("simulating session '{}' ({}x{})...", scene, request.width,
                                   request.height));
    if (Status st = RunSimulatedSession(c, dir); !st.ok()) return st.error().Within(dir.string());
  }
  return Ok();
}

// Every model's table and charts.
Status WriteMethodOutputs(const fs::path& out, const MethodEvaluation& methods) {
  RIG_TRY(WriteText(out / "methods.csv", MethodsCsv(methods)));
  RIG_TRY(WriteText(out / "methods.md", MethodsMarkdown(methods)));
  RIG_TRY(WritePng(out / "error_vs_time.png", ChartErrorVsTime(methods)));
  RIG_TRY(WritePng(out / "error_vs_storage.png", ChartErrorVsStorage(methods)));
  RIG_TRY(WritePng(out / "condition_vs_order.png", ChartConditionVsOrder(methods)));
  if (methods.has_truth) RIG_TRY(WritePng(out / "extrapolation.png", ChartExtrapolation(methods)));
  return Ok();
}

// Scenes of growing complexity: the order chosen on each, and SH-rls around it.
Result<std::vector<SceneRow>> SceneRows(const fs::path& out, const std::vector<std::string>& scenes,
                                        const MethodEvaluation& full, int timing_runs) {
  std::vector<SceneRow> rows;
  for (const auto& scene : scenes) {
    RIG_ASSIGN_OR_RETURN(LoadedSession s, LoadSession(out / "sessions" / scene));
    s.input.timing_runs = timing_runs;
    Result<MethodEvaluation> e = scene == "full" ? Result<MethodEvaluation>(full) : EvaluateMethods(s.input);
    if (!e.ok()) return e.error();
    SceneRow row{scene, -1, {}, e->session_default, std::nullopt, e->family_folds};
    for (const auto& r : e->rows) {
      if (r.selected) row.chosen = r.order;
      if (r.session_default) row.default_row = r;
    }
    for (const auto& r : e->rows)
      if (r.basis == "sh" && r.method == "rls" && std::abs(r.order - row.chosen) <= 1) row.around.push_back(r);
    rows.push_back(row);
  }
  return rows;
}

// HDR methods on the simulated brackets of the main session, as the camera stored them.
void SimulatedBracketTrials(const fs::path& main_session, int runs, std::vector<HdrTrial>* trials) {
  auto main = Session::OpenExisting(main_session);
  auto jobs = main.ok() ? CompleteBrackets(*main) : Result<std::vector<BracketJob>>(main.error());
  if (!jobs.ok()) return;
  const std::vector<std::string> poses = {"h000_v00", "h040_v20", "h090_v30"};
  for (auto& job : *jobs) {
    if (std::find(poses.begin(), poses.end(), job.pose.Name()) == poses.end()) continue;
    std::vector<std::string> files;
    std::vector<Seconds> times;
    for (size_t i = 0; i < job.files.size(); ++i) {
      files.push_back(job.files[i].string());
      times.push_back(Seconds(job.exposures_s[i]));
    }
    auto bracket = DecodeFrames(files, times);
    auto truth = ReadRgbExr((main_session / "truth" / "radiance" / (job.pose.Name() + ".exr")).string());
    if (!bracket.ok() || !truth.ok()) continue;
    for (auto& t : CompareHdr("sim " + job.pose.Name(), *bracket, *truth, 1, runs)) trials->push_back(t);
  }
}

// Real HDR images as truth, and always one synthetic radiance image (4.5 decades, with a
// saturated and a black spot) so that the comparison never depends on the folder.
std::vector<std::pair<std::string, cv::Mat>> HdrTruths(const EvaluationRequest& request) {
  auto log = Log("evaluate");
  std::vector<fs::path> images;
  if (request.hdr_images.empty()) {
    log->info("no real HDR images given (--hdr-images): HDR methods on simulated data only");
  } else if (fs::is_directory(request.hdr_images)) {
    for (const auto& e : fs::directory_iterator(request.hdr_images)) {
      const std::string ext = e.path().extension().string();
      if (ext == ".exr" || ext == ".hdr") images.push_back(e.path());
    }
    std::sort(images.begin(), images.end());
  } else {
    log->warn("no folder of real HDR images at {} (--hdr-images): HDR methods on simulated data only", request.hdr_images.string());
  }
  if (request.quick && images.size() > 1) images.resize(1);
  const int max_width = request.quick ? 256 : 640;
  std::vector<std::pair<std::string, cv::Mat>> truths;
  for (const auto& path : images) {
    auto truth = LoadHdrTruth(path, max_width);
    if (!truth.ok()) {
      log->warn("{}", truth.error().ToString());
      continue;
    }
    truths.push_back({path.filename().string(), *truth});
  }
  truths.push_back({"synthetic", synth::SyntheticRadiance(max_width, max_width * 3 / 4)});
  return truths;
}

// Every HDR method on every truth's bracket; on the first, the stability sweeps: the number
// of exposures, then the noise level.
HdrTrials RunHdrTrials(const EvaluationRequest& request, const fs::path& main_session, bool truth) {
  HdrTrials trials;
  const int runs = std::max(1, request.timing_runs);
  trials.timing_runs = runs;
  if (truth) SimulatedBracketTrials(main_session, runs, &trials.main);
  const auto truths = HdrTruths(request);
  const std::vector<int> exposures = request.quick ? std::vector<int>{2, 5} : std::vector<int>{2, 3, 4, 5, 7, 9, 12};
  const std::vector<double> noises = request.quick ? std::vector<double>{1, 8} : std::vector<double>{0.25, 1, 2, 4, 8, 16};
  // One step per bracket compared (every method on it): each truth, then the first's sweeps.
  ProgressTask task("HDR methods", static_cast<int64_t>(truths.size() + exposures.size() + noises.size()));
  for (const auto& [name, truth_image] : truths) {
    const cv::Mat* t_img = &truth_image;
    for (auto& t : CompareHdr(name, BracketFor(*t_img, 7, 1, 11), *t_img, 1, runs)) trials.main.push_back(t);
    task.Advance(1, name);
    if (name != truths.front().first) continue;
    // The sweeps chart error only (against exposures, against noise): one run each.
    for (int n : exposures) {
      for (auto& t : CompareHdr(name, BracketFor(*t_img, n, 1, 11), *t_img, 1, 1)) trials.exposures.push_back(t);
      task.Advance(1, fmt::format("{}: {} exposures", name, n));
    }
    for (double noise : noises) {
      for (auto& t : CompareHdr(name, BracketFor(*t_img, 7, noise, 11), *t_img, noise, 1)) trials.noise.push_back(t);
      task.Advance(1, fmt::format("{}: noise {:g}x", name, noise));
    }
  }
  return trials;
}

Status WriteHdrOutputs(const fs::path& out, const HdrTrials& hdr) {
  std::vector<HdrTrial> all_hdr = hdr.main;
  all_hdr.insert(all_hdr.end(), hdr.exposures.begin(), hdr.exposures.end());
  all_hdr.insert(all_hdr.end(), hdr.noise.begin(), hdr.noise.end());
  RIG_TRY(WriteText(out / "hdr_methods.csv", HdrCsv(all_hdr)));
  if (!hdr.main.empty()) RIG_TRY(WritePng(out / "hdr_time_vs_error.png", HdrSpeedChart(hdr.main, hdr.timing_runs)));
  if (!hdr.exposures.empty())
    RIG_TRY(WritePng(out / "hdr_error_vs_exposures.png", HdrChart(hdr.exposures, false, "HDR stability: error against the number of exposures")));
  if (!hdr.noise.empty())
    RIG_TRY(WritePng(out / "hdr_error_vs_noise.png", HdrChart(hdr.noise, true, "HDR stability: error against sensor noise")));
  return Ok();
}

// Findings on the models, from the numbers above.
std::string ModelFindings(const MethodEvaluation& methods) {
  const auto& rows = methods.rows;
  auto best_of = [&](const std::string& name) -> const MethodResult* {
    const MethodResult* b = nullptr;
    for (const auto& r : rows)
      if (r.supported && r.Name() == name && std::isfinite(r.Error()) && (!b || r.Error() < b->Error())) b = &r;
    return b;
  };
  const MethodResult* selected = nullptr;
  for (const auto& r : rows)
    if (r.selected) selected = &r;
  std::string findings;
  const std::string err_kind = methods.has_truth ? "error against the truth at held-out lamps" : "leave-one-out error";
  if (const auto *q = best_of("sh-quadrature"), *r = best_of("sh-rls"); q && r) {
    findings += fmt::format("- The paper's quadrature on this partial-sphere grid reaches at best {:.3f} relative {} (order {}); regularised least squares reaches {:.4f} (order {}), {:.0f}x less.\n",
                            q->Error(), err_kind, q->order, r->Error(), r->order, q->Error() / r->Error());
  }
  {
    int first_refused = -1;
    std::string why;
    for (const auto& r : rows)
      if (r.Name() == "sh-ls" && !r.supported && first_refused < 0) first_refused = r.order, why = r.refusal;
    if (first_refused >= 0)
      findings += fmt::format("- Plain least squares refuses SH order {} and above on this grid ({}); the regularised fit stays stable at every order (condition_vs_order.png).\n", first_refused, why);
  }
  if (selected) {
    findings += fmt::format("- The harmonic family's automatic choice is {} ({} terms, {:g} bytes/pixel): {} of {:.4f}, fitted in {:.3f} s; it is {} the error-against-time Pareto front.\n",
                            methods.selected, selected->terms, selected->bytes_per_pixel, err_kind, selected->Error(), selected->fit_time_s,
                            selected->pareto_time ? "on" : "not on");
  }
  const MethodResult* session_default = nullptr;
  for (const auto& r : rows)
    if (r.session_default) session_default = &r;
  if (session_default) {
    std::string why = methods.session_default_reason;
    if (!why.empty() && why.back() != '.') why += '.';
    findings += fmt::format("- The session's default model is {} ({:.2f} bytes/pixel as stored): {} of {:.4f}. The family's choice: {}\n",
                            methods.session_default, session_default->bytes_per_pixel, err_kind,
                            session_default->Error(), why);
  } else if (!methods.session_default_reason.empty()) {
    findings += fmt::format("- The session's default model: {}.\n", methods.session_default_reason);
  }
  if (methods.has_truth && selected) {
    findings += fmt::format("- Pixels shadowed at some sampled lamp ({} px) carry {:.3f} relative error with the chosen model against {:.3f} on always-lit pixels ({} px): attached and cast shadows are not band-limited.\n",
                            methods.shadowed_pixels, selected->truth_relative_shadowed, selected->truth_relative_lit, methods.lit_pixels);
    findings += fmt::format("- Beyond the sampled lamp region the chosen model's error grows to {:.3f} (extrapolation.png); `rig render` refuses such lamps unless --extrapolate.\n",
                            selected->extrapolation_relative);
  }
  return findings;
}

// Findings on the HDR methods.
std::string HdrFindings(const HdrTrials& hdr) {
  std::string findings;
  auto mean_of = [&](const std::vector<HdrTrial>& ts, const std::string& m, double HdrTrial::*f) {
    double s = 0;
    int n = 0;
    for (const auto& t : ts)
      if (t.method == m && std::isfinite(t.*f)) s += t.*f, ++n;
    return n ? s / n : kNan;
  };
  if (!hdr.main.empty()) {
    const auto& m = hdr.main;
    const auto brackets = std::count_if(m.begin(), m.end(), [](const HdrTrial& t) { return t.method == "ours"; });
    findings += fmt::format("- HDR, mean over {} brackets: ours {:.4f} log-radiance RMS error in {:.3f} s (photon weights {:.4f}, hat weights {:.4f}); OpenCV Debevec {:.4f} in {:.3f} s; Robertson {:.4f} in {:.3f} s.\n",
                            brackets, mean_of(m, "ours", &HdrTrial::log_rms), mean_of(m, "ours", &HdrTrial::time_s),
                            mean_of(m, "ours-photon", &HdrTrial::log_rms), mean_of(m, "ours-hat", &HdrTrial::log_rms),
                            mean_of(m, "opencv-debevec", &HdrTrial::log_rms), mean_of(m, "opencv-debevec", &HdrTrial::time_s),
                            mean_of(m, "opencv-robertson", &HdrTrial::log_rms), mean_of(m, "opencv-robertson", &HdrTrial::time_s));
  }
  if (hdr.exposures.empty()) return findings;
  // The trial of method `m` on the same bracket as `key` (same data, exposures and noise).
  auto on_same = [](const std::vector<HdrTrial>& ts, const HdrTrial& key, const char* m) -> const HdrTrial* {
    for (const auto& t : ts)
      if (t.dataset == key.dataset && t.exposures == key.exposures && t.noise == key.noise && t.method == m) return &t;
    return nullptr;
  };
  auto cell = [](const HdrTrial* t) -> std::string {
    if (!t) return "not run";
    if (t->failure.empty()) return fmt::format("{:.4f}", t->log_rms);
    // The failure's first clause whole (its detail, in parentheses, is in hdr_methods.csv).
    std::string why = t->failure.substr(0, t->failure.find(" ("));
    return "fails (" + why + ")";
  };
  const HdrTrial& fewest = hdr.exposures.front();
  findings += fmt::format("- With only {} exposures: ours {}, Debevec {}, Robertson {} (hdr_error_vs_exposures.png).\n",
                          fewest.exposures, cell(on_same(hdr.exposures, fewest, "ours")),
                          cell(on_same(hdr.exposures, fewest, "opencv-debevec")),
                          cell(on_same(hdr.exposures, fewest, "opencv-robertson")));
  if (!hdr.noise.empty()) {
    const HdrTrial& noisiest = hdr.noise.back();
    findings += fmt::format("- At {:g}x the default noise: ours {}, photon weights {}, Debevec {}, Robertson {} (hdr_error_vs_noise.png).\n",
                            noisiest.noise, cell(on_same(hdr.noise, noisiest, "ours")),
                            cell(on_same(hdr.noise, noisiest, "ours-photon")),
                            cell(on_same(hdr.noise, noisiest, "opencv-debevec")),
                            cell(on_same(hdr.noise, noisiest, "opencv-robertson")));
  }
  return findings;
}

// report.md: the findings, every model, the scenes, the HDR methods.
std::string EvaluationMarkdown(const fs::path& main_session, const LoadedSession& loaded,
                               const MethodEvaluation& methods,
                               const std::vector<SceneRow>& scene_rows, const HdrTrials& hdr,
                               const std::string& findings, double seconds) {
  std::string report = fmt::format("# Evaluation: speed against accuracy\n\nData: {}{} ({} poses, {}x{}). Made by `rig evaluate` in {:.0f} s.\n\n## Findings\n\n{}\n",
                                   main_session.string(), methods.has_truth ? " (simulated: truth known)" : "",
                                   loaded.input.radiance.size(), loaded.input.radiance[0].cols, loaded.input.radiance[0].rows,
                                   seconds, findings);
  report += "## Every model\n\n![error against time](error_vs_time.png)\n\n![error against storage](error_vs_storage.png)\n\n";
  report += MethodsMarkdown(methods);
  report += fmt::format("\nRelative errors: RMS of (model ρ − reference) over RMS of the reference, all pixels and colours; LOO = leave-one-out over the sampled poses. Render time: ρ of every pixel for one lamp.{}\n\n![condition](condition_vs_order.png)\n\n",
      methods.timing_runs > 1
          ? fmt::format(" Times (fit, render, HDR): wall seconds, the median of {} runs of each.",
                        methods.timing_runs)
          : " Times (fit, render, HDR): wall seconds, one run of each (they move with the machine's load).");
  if (methods.has_truth) report += "![extrapolation](extrapolation.png)\n\n";
  if (!scene_rows.empty()) {
    report += "## No more model than the scene needs\n\nSH, regularised least squares, order chosen from leave-one-out error (smallest within the tolerance of the best):\n\n| scene | chosen order | order | terms | bytes/px | fit s | LOO rel. | truth rel. |\n|---|---|---|---|---|---|---|---|\n";
    for (const auto& s : scene_rows)
      for (const auto& r : s.around)
        report += fmt::format("| {} | {} | {}{} | {} | {:g} | {:.4f} | {:.4f} | {:.4f} |\n", s.scene, s.chosen, r.order,
                              r.order == s.chosen ? " (chosen)" : "", r.terms, r.bytes_per_pixel, r.fit_time_s, r.loo_relative,
                              r.truth_relative);
    report += "\nThe session's default model — the family chosen per byte at held-out lamps, as `rig process` makes it — on each scene:\n\n| scene | default model | bytes/px | fit s | truth rel. |\n|---|---|---|---|---|\n";
    for (const auto& s : scene_rows) {
      if (s.default_row)
        report += fmt::format("| {} | {} | {:.2f} | {:.4f} | {:.4f} |\n", s.scene, s.session_default,
                              s.default_row->bytes_per_pixel, s.default_row->fit_time_s, s.default_row->truth_relative);
      else
        report += fmt::format("| {} | {} | | | |\n", s.scene, s.session_default);
    }
    report += "\n";
    bool any_fold = false;
    for (const auto& s : scene_rows) any_fold = any_fold || !s.folds.empty();
    if (any_fold) {
      report += "Which lamps the family choice holds out, and what each family's fold model scores there beside the truth (relative RMS at the cell centres) of the model each family would make — the rule `rig process` uses first:\n\n"
                "| scene | held out | lamps | PCA: held out | PCA truth | harmonic: held out | harmonic truth | chosen | the truth's pick |\n|---|---|---|---|---|---|---|---|---|\n";
      for (const auto& s : scene_rows)
        for (const auto& f : s.folds) {
          std::string truth_pick = "";
          if (std::isfinite(f.pca_truth) && std::isfinite(f.harmonic_truth))
            truth_pick = f.pca_truth <= f.harmonic_truth ? "pca" : "harmonic";
          report += fmt::format("| {} | {}{} | {} | {:.4f} ({} comp., {:.1f} B/px) | {:.4f} | {:.4f} (order {}, {:.0f} B/px) | {:.4f} | {} | {} |\n",
                                s.scene, f.rule, f.session ? " (rig process)" : "", f.held_out, f.pca_held_out,
                                f.pca_components, f.pca_bytes_per_pixel, f.pca_truth, f.harmonic_held_out,
                                f.harmonic_order, f.harmonic_bytes_per_pixel, f.harmonic_truth, f.chosen, truth_pick);
        }
      report += "\n";
    }
  }
  report += "## HDR methods\n\nEach method recovers its own response from the bracket, then merges it. Error: log-radiance RMS on pixels some exposure records well, offset per channel removed (radiance is relative).\n\n![hdr](hdr_time_vs_error.png)\n\n";
  report += HdrTable(hdr.main);
  if (!hdr.exposures.empty()) report += "\n![exposures](hdr_error_vs_exposures.png)\n\n![noise](hdr_error_vs_noise.png)\n\n" + HdrTable(hdr.exposures) + "\n" + HdrTable(hdr.noise);
  return report;
}

}  // namespace

Result<EvaluationReport> RunEvaluation(const EvaluationRequest& request) {
  auto progress = [&](const std::string& line) {
    if (request.progress) request.progress(line);
  };
  const fs::path& out = request.out;
  if (fs::exists(out / "report.md")) return MakeError(ErrorCode::kInvalidInput, out.string(), "holds a report already; choose another --out");
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return MakeError(ErrorCode::kIo, out.string(), "{}", ec.message());
  const auto t_start = Clock::now();

  std::vector<std::string> scenes;
  fs::path main_session = request.session;
  if (request.dry_run) {
    RIG_TRY(SimulateScenes(request, &scenes));
    main_session = out / "sessions" / "full";
  }
  RIG_ASSIGN_OR_RETURN(LoadedSession loaded, LoadSession(main_session));
  loaded.input.timing_runs = request.timing_runs;
  progress(fmt::format("evaluating every model on {}...", main_session.string()));
  RIG_ASSIGN_OR_RETURN(MethodEvaluation methods, EvaluateMethods(loaded.input));
  RIG_TRY(WriteMethodOutputs(out, methods));
  RIG_ASSIGN_OR_RETURN(std::vector<SceneRow> scene_rows, SceneRows(out, scenes, methods, request.timing_runs));
  progress("evaluating HDR methods...");
  const HdrTrials hdr = RunHdrTrials(request, main_session, loaded.truth != nullptr);
  RIG_TRY(WriteHdrOutputs(out, hdr));
  const std::string findings = ModelFindings(methods) + HdrFindings(hdr);
  RIG_TRY(WriteText(out / "report.md", EvaluationMarkdown(main_session, loaded, methods, scene_rows,
                                                           hdr, findings, Since(t_start))));
  return EvaluationReport{findings, out / "report.md"};
}

}  // namespace rig
