// Models of the rig's own HDR sessions per byte: the default dry run (config/sim.toml) is
// captured, its radiance maps fitted by every family and size asked for, each model written
// as it ships and read back, rendered at lamp poses it never saw — the truth of a second grid
// offset by half a step (h 5–85°, v 5–25°: the centres of the first grid's cells), whose
// truth/radiance gives the exact radiance there — and scored: relative RMS error (RMS of
// (s_c · model − truth) over RMS of truth, one scale s_c per channel removed, as brackets fix
// radiance only up to the response's scale) on all pixels, on pixels shadowed at some sampled
// lamp, on always-lit ones; bytes per pixel on disk; fit time.
//
//   build/bench/hdr_model_bench [--dir /tmp/hdr_model_bench] [--width 320 --height 240]
//       [--config FILE] [--sh 2,3,4,5,6] [--sh-compressions none,dwaa,dwab] [--pca K:R:Q,...] [--curves log,srgb,power1.25]
//       [--auto-budgets 30] [--neural 9,...] [--high 0.9999] [--smoothness S] [--no-auto]
//       [--threads 2] [--fresh]
//
// Rows: the session's model; the maps interpolated bilinearly in (h, v) (a reference, no
// model); the PCA model FitPcaHdrAuto chooses (its candidate table first); SH of each order;
// for each curve, PCA of each K components, R×R grid, JPEG quality Q, the PCA size choice of
// the photographs' path (ChoosePca, code-space error) within each budget, neural models.
//
// The session's own model (the dry run's default family: model/pca/ or model/model.exr, as
// written) is the first row; a folder left by an earlier run with the same size is reused (--fresh: not).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "capture/daemon/session_model.h"
#include "capture/plan/pose.h"
#include "capture/session/render_source.h"
#include "capture/session/session_store.h"
#include "config/builtin_config.h"
#include "process/io/exr_io.h"
#include "process/model/any/load_model.h"
#include "process/model/hdr_codes.h"
#include "process/model/harmonic/fit.h"
#include "process/model/neural/neural.h"
#include "process/model/pca/pca.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/pca/pca_hdr.h"
#include "process/model/session/model_stream.h"
#include "sim/dry_session.h"
#include "sim/truth.h"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double Seconds(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "hdr_model_bench: %s\n", what.c_str());
  std::exit(1);
}

template <class T>
T Must(rig::Result<T> r) {
  if (!r.ok()) Die(r.error().ToString());
  return std::move(*r);
}
void Must(const rig::Status& s) {
  if (!s.ok()) Die(s.error().ToString());
}

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> out;
  size_t i = 0;
  while (i <= s.size() && !s.empty()) {
    const size_t j = s.find(sep, i);
    out.push_back(s.substr(i, j == std::string::npos ? std::string::npos : j - i));
    if (j == std::string::npos) break;
    i = j + 1;
  }
  return out;
}

struct Args {
  fs::path dir = "/tmp/hdr_model_bench";
  std::string config;
  int width = 0, height = 0;  // 0: the config's
  std::vector<int> sh = {2, 3, 4, 5, 6};
  std::vector<std::string> sh_compressions = {"none"};
  std::vector<std::array<int, 3>> pca = {{9, 16, 85}, {12, 24, 85}, {18, 32, 95}};
  std::vector<std::string> curves = {"log", "srgb"};
  std::vector<double> budgets = {30};
  std::vector<int> neural;  // latent sizes (codes per pixel) of neural models fitted to the log codes
  int threads = 2;
  double smoothness = -1;
  double high = 0.9999;  // the curve's max at this quantile of ρ  // the PCA grid prior's strength; < 0: chosen by leave-one-out
  bool fresh = false;
  bool hdr_auto = true;  // the HDR PCA choice (FitPcaHdrAuto, the session default's candidate)
};

Args ParseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) Die(k + " needs a value");
      return argv[++i];
    };
    if (k == "--dir") a.dir = next();
    else if (k == "--config") a.config = next();
    else if (k == "--width") a.width = std::stoi(next());
    else if (k == "--height") a.height = std::stoi(next());
    else if (k == "--threads") a.threads = std::stoi(next());
    else if (k == "--fresh") a.fresh = true;
    else if (k == "--no-auto") a.hdr_auto = false;
    else if (k == "--high") a.high = std::stod(next());
    else if (k == "--smoothness") a.smoothness = std::stod(next());
    else if (k == "--sh") {
      a.sh.clear();
      for (const auto& s : Split(next(), ',')) a.sh.push_back(std::stoi(s));
    } else if (k == "--sh-compressions") {
      a.sh_compressions = Split(next(), ',');
    } else if (k == "--pca") {
      a.pca.clear();
      for (const auto& s : Split(next(), ',')) {
        const auto f = Split(s, ':');
        if (f.size() != 3) Die("--pca wants K:R:Q,...");
        a.pca.push_back({std::stoi(f[0]), std::stoi(f[1]), std::stoi(f[2])});
      }
    } else if (k == "--curves") a.curves = Split(next(), ',');
    else if (k == "--auto-budgets") {
      a.budgets.clear();
      for (const auto& s : Split(next(), ',')) a.budgets.push_back(std::stod(s));
    } else if (k == "--neural") {
      a.neural.clear();
      for (const auto& s : Split(next(), ',')) a.neural.push_back(std::stoi(s));
    } else Die("unknown option " + k);
  }
  return a;
}

// What every model is scored against.
struct Reference {
  rig::Config config;                   // the captured session's
  std::vector<rig::Pose> poses;         // the offset grid's
  std::vector<cv::Mat> truth;           // exact radiance at them, CV_32FC3 BGR
  cv::Mat shadowed;                     // CV_8U: 0 in some channel at some sampled pose
  std::vector<cv::Mat> maps;            // the session's radiance maps
  std::vector<rig::Vec3> directions;    // their lamp directions
  std::vector<std::string> map_paths;
};

rig::Config OffsetGrid(rig::Config c) {
  auto& g = c.grid;
  g.h_min_deg += g.h_step_deg / 2;
  g.h_max_deg -= g.h_step_deg / 2;
  g.v_min_deg += g.v_step_deg / 2;
  g.v_max_deg -= g.v_step_deg / 2;
  return c;
}

Reference Prepare(const Args& a) {
  rig::ConfigResult cfg = rig::LoadConfigOrBuiltIn(a.config);
  if (!cfg.ok()) Die(cfg.AsError().ToString());
  Reference ref;
  ref.config = cfg.config;
  if (a.width > 0) ref.config.sim.width = a.width;
  if (a.height > 0) ref.config.sim.height = a.height;
  const fs::path session = a.dir / "session";
  const fs::path offset = a.dir / "offset";
  if (a.fresh) fs::remove_all(a.dir);
  fs::create_directories(a.dir);
  if (!fs::exists(session / "model" / "report.md")) {
    fs::remove_all(session);
    const auto t = Clock::now();
    Must(rig::RunSimulatedSession(ref.config, session));
    std::printf("dry run %dx%d: %.1f s (%s)\n", ref.config.sim.width, ref.config.sim.height,
                Seconds(t), session.c_str());
    // The session's own model, as `rig capture` fits it after the last frame (from the files).
    const auto t_fit = Clock::now();
    Must(rig::FitSessionModel(Must(rig::Session::OpenExisting(session))));
    std::printf("session model: %.2f s\n", Seconds(t_fit));
  }
  const rig::Config off = OffsetGrid(ref.config);
  if (!fs::exists(offset / "truth" / "scene.json")) Must(rig::WriteTruth((offset / "truth").string(), off));
  for (const rig::Pose& p : rig::PlanGrid(off.grid)) {
    ref.poses.push_back(p);
    ref.truth.push_back(Must(rig::ReadRgbExr((offset / "truth" / "radiance" / (p.Name() + ".exr")).string())));
  }
  for (const rig::Pose& p : rig::PlanGrid(ref.config.grid)) {
    const fs::path hdr = session / "hdr" / (p.Name() + ".exr");
    ref.map_paths.push_back(hdr.string());
    ref.maps.push_back(Must(rig::ReadRgbExr(hdr.string())));
    ref.directions.push_back(rig::LightDirection(p.h_deg, p.v_deg, ref.config.light_frame));
    cv::Mat t = Must(rig::ReadRgbExr((session / "truth" / "radiance" / (p.Name() + ".exr")).string()));
    if (ref.shadowed.empty()) ref.shadowed = cv::Mat::zeros(t.size(), CV_8U);
    for (int y = 0; y < t.rows; ++y)
      for (int x = 0; x < t.cols; ++x) {
        const cv::Vec3f v = t.at<cv::Vec3f>(y, x);
        if (v[0] <= 0 || v[1] <= 0 || v[2] <= 0) ref.shadowed.at<uint8_t>(y, x) = 1;
      }
  }
  return ref;
}

struct Score {
  double all = 0, lit = 0, shadowed = 0;
};

// Relit at the offset poses through the model's own lamp radiance and light frame.
Score ScoreModel(const rig::ReflectanceModel& m, const Reference& ref) {
  // Per channel and per subset (0 all, 1 lit, 2 shadowed): Σ p·t, Σ p·p, Σ t·t.
  double pt[3][3] = {}, pp[3][3] = {}, tt[3][3] = {};
  for (size_t k = 0; k < ref.poses.size(); ++k) {
    cv::Mat sum;
    m.AddLamp(rig::LightDirection(ref.poses[k].h_deg, ref.poses[k].v_deg, m.light_frame()), {1, 1, 1}, &sum);
    for (int y = 0; y < sum.rows; ++y)
      for (int x = 0; x < sum.cols; ++x) {
        const cv::Vec3f p = sum.at<cv::Vec3f>(y, x), t = ref.truth[k].at<cv::Vec3f>(y, x);
        const int sub = ref.shadowed.at<uint8_t>(y, x) ? 2 : 1;
        for (int c = 0; c < 3; ++c)
          for (int s : {0, sub}) {
            pt[s][c] += double(p[c]) * t[c];
            pp[s][c] += double(p[c]) * p[c];
            tt[s][c] += double(t[c]) * t[c];
          }
      }
  }
  double rel[3];
  for (int s = 0; s < 3; ++s) {
    double err = 0, ref_sq = 0;
    for (int c = 0; c < 3; ++c) {
      const double scale = pp[0][c] > 0 ? pt[0][c] / pp[0][c] : 0;  // from all pixels
      err += scale * scale * pp[s][c] - 2 * scale * pt[s][c] + tt[s][c];
      ref_sq += tt[s][c];
    }
    rel[s] = ref_sq > 0 ? std::sqrt(std::max(0.0, err) / ref_sq) : 0;
  }
  return {rel[0], rel[1], rel[2]};
}

void Row(const std::string& name, const std::string& path, double fit_s, const Reference& ref,
         const std::string& note = "") {
  auto model = Must(rig::LoadReflectanceModel(path));
  const Score s = ScoreModel(*model, ref);
  const double px = double(model->width()) * model->height();
  std::printf("%-34s %8.2f %8.2f   %.4f  %.4f  %.4f  %s\n", name.c_str(),
              double(rig::ModelBytesOnDisk(path)) / px, fit_s, s.all, s.lit, s.shadowed,
              note.c_str());
  std::fflush(stdout);
}

// A neural model of HDR codes, read back from its folder, behind the interface (the family
// has no HDR values of its own yet: the curve is the bench's).
class NeuralHdr final : public rig::ReflectanceModel {
 public:
  NeuralHdr(rig::NeuralModel m, rig::PcaHdrValues v) : m_(std::move(m)), v_(v) {}
  std::string family() const override { return "neural"; }
  std::string Describe() const override { return "neural"; }
  int width() const override { return m_.width(); }
  int height() const override { return m_.height(); }
  rig::ValueEncoding encoding() const override { return rig::ValueEncoding::kLinear; }
  const rig::LightFrameConfig& light_frame() const override { return v_.light_frame; }
  std::array<double, 3> lamp_radiance_rgb() const override { return v_.lamp_radiance_rgb; }
  cv::Mat EvaluateRho(const rig::Vec3& d) const override {
    cv::Mat v = m_.Render(d);
    float* p = v.ptr<float>();
    for (size_t i = 0; i < v.total() * 3; ++i) p[i] = static_cast<float>(v_.curve.Decode(p[i] * 255.0));
    return v;
  }
  rig::RegionCheck CheckRegion(const rig::Vec3&) const override { return {}; }
  rig::Status Save(const std::string& path) const override { return m_.Save(path); }

 private:
  rig::NeuralModel m_;
  rig::PcaHdrValues v_;
};

void NeuralRows(const Args& a, const Reference& ref, const rig::LightSamples& samples,
                const rig::PcaHdrValues& values, const std::string& name) {
  for (int latent : a.neural) {
    rig::NeuralOptions o;
    o.latent = latent;
    o.threads = a.threads;
    const auto t = Clock::now();
    rig::NeuralModel m = Must(rig::FitNeural(samples, o));
    const double fit_s = Seconds(t);
    const std::string out = (a.dir / fmt::format("neural-{}-{}", name, latent)).string();
    Must(m.Save(out));
    NeuralHdr loaded(Must(rig::NeuralModel::Load(out)), values);
    const Score s = ScoreModel(loaded, ref);
    std::printf("%-34s %8.2f %8.2f   %.4f  %.4f  %.4f  %s\n",
                fmt::format("neural {} {} codes", name, latent).c_str(),
                double(rig::NeuralModel::BytesOnDisk(out)) / (double(m.width()) * m.height()), fit_s,
                s.all, s.lit, s.shadowed, "JPEG q95 codes, float32 decoder");
    std::fflush(stdout);
  }
}

// The data's own reference: each off-grid pose relit by interpolating the session's maps
// bilinearly in (h, v) (no model: every map kept, 40 × 6 B/px in half). What any model that
// interpolates the light dependence between the sampled lamps can hope for.
class MapInterpolation final : public rig::ReflectanceModel {
 public:
  explicit MapInterpolation(const Reference& ref) : ref_(ref) {
    for (const rig::Pose& p : rig::PlanGrid(ref.config.grid)) poses_.push_back(p);
  }
  std::string family() const override { return "maps"; }
  std::string Describe() const override { return "maps"; }
  int width() const override { return ref_.maps[0].cols; }
  int height() const override { return ref_.maps[0].rows; }
  rig::ValueEncoding encoding() const override { return rig::ValueEncoding::kLinear; }
  const rig::LightFrameConfig& light_frame() const override { return ref_.config.light_frame; }
  std::array<double, 3> lamp_radiance_rgb() const override { return ref_.config.lamp.radiance_rgb; }
  cv::Mat EvaluateRho(const rig::Vec3&) const override { return {}; }
  rig::RegionCheck CheckRegion(const rig::Vec3&) const override { return {}; }
  rig::Status Save(const std::string&) const override { return rig::Ok(); }
  // Radiance at rig angles: bilinear between the four surrounding poses.
  cv::Mat At(double h, double v) const {
    const auto& g = ref_.config.grid;
    const double fh = (h - g.h_min_deg) / g.h_step_deg, fv = (v - g.v_min_deg) / g.v_step_deg;
    const int h0 = static_cast<int>(std::floor(fh)), v0 = static_cast<int>(std::floor(fv));
    cv::Mat sum = cv::Mat::zeros(height(), width(), CV_32FC3);
    for (int dh = 0; dh < 2; ++dh)
      for (int dv = 0; dv < 2; ++dv) {
        const double w = (dh ? fh - h0 : 1 - (fh - h0)) * (dv ? fv - v0 : 1 - (fv - v0));
        const double ph = g.h_min_deg + (h0 + dh) * g.h_step_deg, pv = g.v_min_deg + (v0 + dv) * g.v_step_deg;
        for (size_t i = 0; i < poses_.size(); ++i)
          if (std::abs(poses_[i].h_deg - ph) < 1e-6 && std::abs(poses_[i].v_deg - pv) < 1e-6)
            cv::scaleAdd(ref_.maps[i], w, sum, sum);
      }
    return sum;
  }

 private:
  const Reference& ref_;
  std::vector<rig::Pose> poses_;
};

void InterpolationRow(const Reference& ref) {
  const MapInterpolation interp(ref);
  // Score through the same sums: relit images are the interpolated maps themselves.
  double pt[3][3] = {}, pp[3][3] = {}, tt[3][3] = {};
  for (size_t k = 0; k < ref.poses.size(); ++k) {
    const cv::Mat sum = interp.At(ref.poses[k].h_deg, ref.poses[k].v_deg);
    for (int y = 0; y < sum.rows; ++y)
      for (int x = 0; x < sum.cols; ++x) {
        const cv::Vec3f p = sum.at<cv::Vec3f>(y, x), t = ref.truth[k].at<cv::Vec3f>(y, x);
        const int sub = ref.shadowed.at<uint8_t>(y, x) ? 2 : 1;
        for (int c = 0; c < 3; ++c)
          for (int s : {0, sub}) {
            pt[s][c] += double(p[c]) * t[c];
            pp[s][c] += double(p[c]) * p[c];
            tt[s][c] += double(t[c]) * t[c];
          }
      }
  }
  double rel[3];
  for (int s = 0; s < 3; ++s) {
    double err = 0, ref_sq = 0;
    for (int c = 0; c < 3; ++c) {
      const double scale = pp[0][c] > 0 ? pt[0][c] / pp[0][c] : 0;
      err += scale * scale * pp[s][c] - 2 * scale * pt[s][c] + tt[s][c];
      ref_sq += tt[s][c];
    }
    rel[s] = ref_sq > 0 ? std::sqrt(std::max(0.0, err) / ref_sq) : 0;
  }
  std::printf("%-34s %8.2f %8.2f   %.4f  %.4f  %.4f  %s\n", "maps interpolated (reference)",
              ref.maps.size() * 6.0, 0.0, rel[0], rel[1], rel[2], "bilinear in (h, v), every map kept");
}

void HdrAutoRow(const Args& a, const Reference& ref) {
  rig::PcaHdrChoiceOptions o;
  o.threads = a.threads;
  const auto t = Clock::now();
  rig::PcaHdrFit fit = Must(rig::FitPcaHdrAuto(ref.maps, ref.directions, ref.config.lamp.radiance_rgb,
                                               ref.config.light_frame, o));
  const double fit_s = Seconds(t);
  const std::string out = (a.dir / "pca-hdr-auto").string();
  Must(fit.model.Save(out));
  std::printf("%s", rig::PcaHdrChoiceMarkdown(fit).c_str());
  Row("pca hdr chosen (FitPcaHdrAuto)", out, fit_s, ref, fit.reason);
}

void HarmonicRows(const Args& a, const Reference& ref) {
  rig::StreamFitInput in;
  in.paths = ref.map_paths;
  in.directions = ref.directions;
  in.lamp_radiance_rgb = ref.config.lamp.radiance_rgb;
  in.light_frame = ref.config.light_frame;
  in.compression = rig::ExrCompression::kNone;
  rig::FitOptions o = Must(rig::FitOptionsFromConfig(ref.config.process));
  o.threads = a.threads;
  for (const std::string& name : a.sh_compressions) {
    in.compression = Must(rig::ParseExrCompression(name, /*lossy=*/true));
    for (int order : a.sh) {
      o.order = order;
      const std::string out = (a.dir / fmt::format("sh{}_{}.exr", order, name)).string();
      const auto t = Clock::now();
      Must(rig::FitModelStreaming(in, o, out, rig::ExrPixelType::kHalf));
      Row(fmt::format("sh order {} ({} terms), half{}", order, (order + 1) * (order + 1),
                      name == "none" ? std::string() : ", " + name),
          out, Seconds(t), ref);
    }
  }
}

void PcaRows(const Args& a, const Reference& ref) {
  const auto rho = rig::ReflectanceOf(ref.maps, ref.config.lamp.radiance_rgb);
  for (const std::string& name : a.curves) {
    rig::HdrCurveOptions co;
    // "power1.5": the power curve with that gamma.
    co.curve = Must(rig::ParseHdrCurve(name.rfind("power", 0) == 0 ? "power" : name));
    if (co.curve == rig::HdrCurve::kPower) co.gamma = name.size() > 5 ? std::stod(name.substr(5)) : 1.0;
    co.high = a.high;
    auto t0 = Clock::now();
    const rig::HdrCodeCurve curve = rig::FitHdrCurve(rho, co);
    rig::LightSamples samples = rig::SamplesFromMaps(ref.maps, ref.directions, ref.config.lamp.radiance_rgb, curve);
    rig::PcaOptions po;
    po.thresholds = rig::kHdrMaskThresholds;
    po.threads = a.threads;
    po.smoothness = a.smoothness;
    int largest = 0;
    for (const auto& c : a.pca) largest = std::max(largest, c[0]);
    rig::PcaChoiceOptions choice;
    choice.base = po;
    largest = std::max(largest, rig::LargestCandidate(choice));
    const rig::PcaComponents comps = Must(rig::ComputePcaComponents(samples, po, largest));
    const double prep_s = Seconds(t0);
    rig::PcaHdrValues values{curve, ref.config.lamp.radiance_rgb, ref.config.light_frame};
    const std::string curve_note = fmt::format("max {:.4g} floor {:.3g}, top step {:.1f}%", curve.max,
                                               curve.floor, 100 * curve.TopStep());
    for (const auto& c : a.pca) {
      rig::PcaOptions o = po;
      o.components = c[0];
      o.grid_resolution = c[1];
      o.jpeg_quality = c[2];
      const auto t = Clock::now();
      rig::PcaModel m = Must(rig::FitPcaWith(samples, comps, o));
      m.set_hdr(values);
      const std::string out = (a.dir / fmt::format("pca-{}-{}-{}-{}", name, c[0], c[1], c[2])).string();
      Must(m.Save(out));
      Row(fmt::format("pca {} k{} grid{} q{}", name, c[0], c[1], c[2]), out, prep_s + Seconds(t), ref,
          curve_note);
    }
    for (double budget : a.budgets) {
      choice.max_bytes_per_pixel = budget;
      const auto t = Clock::now();
      rig::PcaAutoFit fit = Must(rig::FitPcaAuto(samples, &comps, choice));
      fit.model.set_hdr(values);
      const std::string out = (a.dir / fmt::format("pca-{}-auto{:g}", name, budget)).string();
      Must(fit.model.Save(out));
      Row(fmt::format("pca {} chosen within {:g} B/px", name, budget), out, prep_s + Seconds(t), ref,
          fit.choice.reason);
    }
    NeuralRows(a, ref, samples, values, name);
  }
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = ParseArgs(argc, argv);
  const Reference ref = Prepare(a);
  std::printf("%zu maps %dx%d, %zu off-grid poses (h %g-%g, v %g-%g), %d shadowed px of %d\n",
              ref.maps.size(), ref.maps[0].cols, ref.maps[0].rows, ref.poses.size(),
              OffsetGrid(ref.config).grid.h_min_deg, OffsetGrid(ref.config).grid.h_max_deg,
              OffsetGrid(ref.config).grid.v_min_deg, OffsetGrid(ref.config).grid.v_max_deg,
              cv::countNonZero(ref.shadowed), static_cast<int>(ref.shadowed.total()));
  std::printf("%-34s %8s %8s   %-6s  %-6s  %-6s\n", "model", "B/px", "fit s", "all", "lit", "shadow");
  const std::string session_model = Must(rig::ResolveRenderSource((a.dir / "session").string())).model_path;
  Row(fmt::format("session default ({})", fs::path(session_model).filename().string()), session_model, 0,
      ref, "as the dry run wrote it");
  InterpolationRow(ref);
  if (a.hdr_auto) HdrAutoRow(a, ref);
  HarmonicRows(a, ref);
  PcaRows(a, ref);
  return 0;
}
