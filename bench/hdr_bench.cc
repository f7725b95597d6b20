// HDR benchmark: ours beside OpenCV's CalibrateDebevec + MergeDebevec on the same frames, in
// one run: accuracy against known radiance, response error, merge and recovery speed, decoding
// and EXR writing. Usage: hdr_bench [--width W --height H --frames N --repeat R --threads T]
//                                   [--shared DIR] [--sim-config TOML] [--sweep] [--profile]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "process/io/exr_io.h"
#include "process/hdr/hdr.h"
#include "process/io/image_io.h"
#include "config/config.h"
#include "process/model/light_direction.h"
#include "sim/bracket_synth.h"
#include "sim/sim_camera.h"
#include "sim/world.h"

namespace {

namespace fs = std::filesystem;
using rig::Bracket;
using Clock = std::chrono::steady_clock;

struct Args {
  int width = 3000, height = 2000, frames = 10, repeat = 3, threads = 2;
  std::string shared = "/work/shared";
  std::string sim_config;
  bool sweep = false;
};

template <typename Fn>
std::pair<double, double> Time(int repeat, Fn&& fn) {  // (best, median) seconds
  std::vector<double> t;
  for (int i = 0; i < repeat; ++i) {
    auto a = Clock::now();
    fn();
    t.push_back(std::chrono::duration<double>(Clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return {t.front(), t[t.size() / 2]};
}

std::vector<cv::Mat> Images(const Bracket& b) {
  std::vector<cv::Mat> v;
  for (const auto& f : b) v.push_back(f.image);
  return v;
}
cv::Mat Times(const Bracket& b) {
  cv::Mat t(int(b.size()), 1, CV_32F);
  for (size_t i = 0; i < b.size(); ++i) t.at<float>(int(i)) = float(b[i].exposure.count());
  return t;
}

struct Accuracy {
  double ours_rms = 0, cv_rms = 0, ours_g = 0, cv_g = 0;
  double ours_g_mid = 0;  // over levels 32..224 (the toe and shoulder left out)
  double oracle_rms = 0;  // our merge through the TRUE response: the floor noise leaves
  double ivw_rms = -1;  // inverse-variance merge, true response and noise (-1: noise unknown)
  // The Cramér–Rao bound for unbiased estimators over the pixel-channels it determines to
  // kBoundLimit (-1: noise unknown), the fraction of scored pixel-channels those are, and the
  // merges through the true response (hat, photon, noise, ivw-true) on that same subset.
  double crb_rms = -1, crb_fraction = 0;
  std::array<double, 4> bounded_true{-1, -1, -1, -1};
  // Merge error per weighting (hat, photon, noise), through our response and the true one.
  std::array<double, 3> weighting_ours{}, weighting_true{};
  size_t pixels = 0;
};

using TrueCurve = std::function<double(int c, int z)>;  // g(z) of the camera, per channel

// max |g - g_true| over levels lo..hi per channel after removing the mean offset there.
double CurveError(const TrueCurve& g, const TrueCurve& truth, int lo = 13, int hi = 242) {
  double worst = 0;
  for (int c = 0; c < 3; ++c) {
    double mean = 0;
    for (int z = lo; z <= hi; ++z) mean += g(c, z) - truth(c, z);
    mean /= hi - lo + 1;
    for (int z = lo; z <= hi; ++z) worst = std::max(worst, std::abs(g(c, z) - truth(c, z) - mean));
  }
  return worst;
}

// The noise a bracket was rendered with (RenderBracket's shot and read terms, relative to the
// saturation exposure), when it is known.
struct NoiseModel {
  double shot = 0, read = 0;
};

// A strong reference estimator (not a bound): every sample weighted by the inverse of its
// log-radiance variance — shot and read noise from the known noise model plus 8-bit
// quantisation through the true slope g'(z) (g'^2/12) — through the TRUE response. The
// variance is evaluated at the OBSERVED level, so the weights are noisy themselves and other
// estimators can beat it (photon weighting through the true response did, on the simulator's
// PNG bracket); the bound is CramerRaoRms below.
cv::Mat InverseVarianceMerge(const Bracket& b, const TrueCurve& f, const NoiseModel& nm) {
  std::array<std::array<double, 256>, 3> g{}, var{};
  for (int c = 0; c < 3; ++c) {
    for (int z = 0; z < 256; ++z) g[c][z] = f(c, std::max(z, 1));
    for (int z = 1; z < 255; ++z) {
      const double slope = 0.5 * (g[c][z + 1] - g[c][z - 1]);
      const double x = std::exp(g[c][z]);
      var[c][z] = slope * slope / 12 + (nm.shot * x + nm.read * nm.read) / (x * x);
    }
  }
  cv::Mat out(b[0].image.size(), CV_32FC3);
  for (int y = 0; y < out.rows; ++y) {
    float* o = out.ptr<float>(y);
    for (int k = 0; k < out.cols * 3; ++k) {
      const int c = k % 3;
      double num = 0, den = 0;
      for (const auto& fr : b) {
        const int z = fr.image.ptr<uint8_t>(y)[k];
        if (z == 0 || z == 255) continue;
        const double w = 1.0 / var[c][z];
        num += w * (g[c][z] - std::log(fr.exposure.count()));
        den += w;
      }
      o[k] = den > 0 ? float(std::exp(num / den)) : 0.f;
    }
  }
  return out;
}

// The Cramér–Rao bound on the log-radiance error of any unbiased per-pixel estimator, for the
// noise model the bracket was rendered with: frame i records z_i = Q(X_i + n_i) with X_i = E t_i,
// n_i ~ N(0, shot X_i + read^2) and Q the true response quantised to 8 bits (levels 0 and 255
// censored: they hold every value beyond). The Fisher information about theta = ln E is summed
// over frames from the exact level probabilities P(z) = Phi(u_z) - Phi(u_{z-1}), u = (B - X)/sigma,
// with the level boundaries B_z taken midway (in log) between the true g(z) and g(z+1). Returned
// per pixel-channel as sqrt(1/I) (0 where LogRmsError does not score).
cv::Mat CramerRaoMap(const Bracket& b, const cv::Mat& truth, const TrueCurve& f,
                     const NoiseModel& nm) {
  std::array<std::array<double, 255>, 3> bound{};  // B_z between level z and z+1
  for (int c = 0; c < 3; ++c) {
    for (int z = 0; z < 255; ++z) bound[c][z] = std::exp(0.5 * (f(c, std::max(z, 1)) + f(c, z + 1)));
    if (bound[c][0] >= bound[c][1]) bound[c][0] = 0.5 * bound[c][1];  // g(0) unknown: half of B_1
  }
  const double lo = 0.05 * 255, hi = 0.95 * 255;
  cv::Mat out(truth.size(), CV_32FC3, cv::Scalar::all(0));
  cv::parallel_for_(cv::Range(0, truth.rows), [&](const cv::Range& r) {
    for (int y = r.start; y < r.end; ++y) {
      const float* t = truth.ptr<float>(y);
      float* o = out.ptr<float>(y);
      for (int k = 0; k < truth.cols * 3; ++k) {
        if (!(t[k] > 0)) continue;
        bool well = false;
        for (const auto& fr : b) {
          const int z = fr.image.ptr<uint8_t>(y)[k];
          if (z >= lo && z <= hi) {
            well = true;
            break;
          }
        }
        if (!well) continue;
        const auto& B = bound[k % 3];
        double info = 0;
        for (const auto& fr : b) {
          const double mu = double(t[k]) * fr.exposure.count();
          const double sigma = std::sqrt(nm.shot * mu + nm.read * nm.read);
          if (!(sigma > 0)) continue;
          const double dsigma = nm.shot * mu / (2 * sigma);  // d sigma / d theta
          // Only the levels within 8 sigma of X carry probability; the rest are folded into
          // the first and last of them (their boundaries beyond are at +-infinity).
          const int z0 = int(std::lower_bound(B.begin(), B.end(), mu - 8 * sigma) - B.begin());
          const int z1 = int(std::lower_bound(B.begin(), B.end(), mu + 8 * sigma) - B.begin());
          // Boundary j (between level j and j+1) -> (Phi(u), phi(u) du/dtheta); open ends 0.
          auto edge = [&](int j, double* cdf, double* dcdf) {
            if (j < z0) { *cdf = 0; *dcdf = 0; return; }
            if (j >= z1) { *cdf = 1; *dcdf = 0; return; }
            const double u = (B[j] - mu) / sigma;
            *cdf = 0.5 * std::erfc(-u / std::sqrt(2.0));
            const double du = -mu / sigma - u * dsigma / sigma;
            *dcdf = std::exp(-0.5 * u * u) / std::sqrt(2 * M_PI) * du;
          };
          double c_prev, d_prev;
          edge(z0 - 1, &c_prev, &d_prev);
          for (int z = z0; z <= z1; ++z) {
            double c_next, d_next;
            edge(z, &c_next, &d_next);
            const double p = c_next - c_prev, dp = d_next - d_prev;
            if (p > 1e-300) info += dp * dp / p;
            c_prev = c_next;
            d_prev = d_next;
          }
        }
        o[k] = info > 0 ? float(std::sqrt(1.0 / info)) : std::numeric_limits<float>::infinity();
      }
    }
  });
  return out;
}

// The bound's RMS over the pixel-channels it determines to within `limit` (sd of ln E), and the
// fraction of scored pixel-channels those are. Where the bound is larger, no unbiased estimator
// exists in practice (a signal far below the read noise): every merge there is biased, and so
// can score below the bound; comparisons with the bound are made on this subset.
double BoundRms(const cv::Mat& crb, double limit, double* fraction) {
  double sum = 0;
  size_t n = 0, scored = 0;
  for (int y = 0; y < crb.rows; ++y) {
    const float* c = crb.ptr<float>(y);
    for (int k = 0; k < crb.cols * 3; ++k) {
      if (!(c[k] > 0)) continue;
      ++scored;
      if (c[k] > limit) continue;
      sum += double(c[k]) * c[k];
      ++n;
    }
  }
  if (fraction) *fraction = scored ? double(n) / scored : 0.0;
  return n ? std::sqrt(sum / n) : 0.0;
}

// LogRmsError (mean log offset per channel removed) over the pixel-channels where the bound is
// at most `limit`.
double LogRmsWhereBounded(const cv::Mat& estimate, const cv::Mat& truth, const cv::Mat& crb,
                          double limit) {
  std::array<std::vector<double>, 3> d;
  for (int y = 0; y < truth.rows; ++y) {
    const float* t = truth.ptr<float>(y);
    const float* e = estimate.ptr<float>(y);
    const float* c = crb.ptr<float>(y);
    for (int k = 0; k < truth.cols * 3; ++k) {
      if (!(c[k] > 0) || c[k] > limit) continue;
      d[k % 3].push_back(std::log(std::max<double>(e[k], 1e-30)) - std::log(double(t[k])));
    }
  }
  double sum = 0;
  size_t n = 0;
  for (auto& ch : d) {
    if (ch.empty()) continue;
    double mean = 0;
    for (double v : ch) mean += v;
    mean /= ch.size();
    for (double v : ch) sum += (v - mean) * (v - mean);
    n += ch.size();
  }
  return n ? std::sqrt(sum / n) : 0.0;
}

constexpr double kBoundLimit = 0.1;  // sd of ln E: the subset where the bound is compared

bool g_profile = false;  // --profile: print g - g_true at chosen levels for every bracket

// Accuracy of both pipelines on one bracket with known radiance.
Accuracy Compare(const Bracket& b, const cv::Mat& truth, const TrueCurve& f,
                 const rig::ResponseOptions& ro, int threads,
                 std::optional<NoiseModel> noise = std::nullopt) {
  Accuracy a;
  cv::Mat crb;
  if (noise) {
    const cv::Mat ivw = InverseVarianceMerge(b, f, *noise);
    a.ivw_rms = rig::synth::LogRmsError(ivw, truth, b);
    crb = CramerRaoMap(b, truth, f, *noise);
    a.crb_rms = BoundRms(crb, kBoundLimit, &a.crb_fraction);
    a.bounded_true[3] = LogRmsWhereBounded(ivw, truth, crb, kBoundLimit);
  }
  const Bracket brackets[1] = {b};
  auto resp = rig::RecoverResponse(brackets, ro);
  if (!resp.ok()) {
    std::fprintf(stderr, "recovery failed: %s\n", resp.error().ToString().c_str());
    std::exit(1);
  }
  rig::MergeOptions mo;
  mo.threads = threads;
  mo.max_unrecorded_fraction = 1.0;
  auto map = rig::MergeBracket(b, *resp, mo);
  if (!map.ok()) {
    std::fprintf(stderr, "merge failed: %s\n", map.error().ToString().c_str());
    std::exit(1);
  }
  a.ours_rms = rig::synth::LogRmsError(map->radiance, truth, b, &a.pixels);
  a.ours_g = CurveError([&](int c, int z) { return resp->log_exposure[c][z]; }, f);
  a.ours_g_mid = CurveError([&](int c, int z) { return resp->log_exposure[c][z]; }, f, 32, 224);
  if (g_profile) {
    // Offsets removed over 32..224 as in the g 32-224 column.
    for (int c = 0; c < 3; ++c) {
      double mean = 0;
      for (int z = 32; z <= 224; ++z) mean += resp->log_exposure[c][z] - f(c, z);
      mean /= 193;
      std::printf("  g - g_true, channel %c:", "BGR"[c]);
      for (int z : {3, 6, 10, 13, 20, 32, 64, 128, 192, 224, 232, 242, 248, 252})
        std::printf(" %d:%+.3f", z, resp->log_exposure[c][z] - f(c, z) - mean);
      std::printf("\n");
    }
    std::printf("  g_true - g_true(128), channel G:");
    for (int z : {3, 6, 10, 13, 20, 32, 64, 128, 192, 224, 232, 242, 248, 252})
      std::printf(" %d:%+.2f", z, f(1, z) - f(1, 128));
    std::printf("\n");
  }
  rig::ResponseCurve true_g;
  for (int c = 0; c < 3; ++c) {
    for (int z = 0; z < 256; ++z) true_g.log_exposure[c].push_back(f(c, std::max(z, 1)));
  }
  true_g.id = "truth";
  auto oracle = rig::MergeBracket(b, true_g, mo);
  if (oracle.ok()) a.oracle_rms = rig::synth::LogRmsError(oracle->radiance, truth, b);

  const rig::MergeWeighting weightings[3] = {rig::MergeWeighting::kHat, rig::MergeWeighting::kPhoton,
                                             rig::MergeWeighting::kNoise};
  for (int k = 0; k < 3; ++k) {
    rig::MergeOptions wo = mo;
    wo.weighting = weightings[k];
    auto ours = rig::MergeBracket(b, *resp, wo);
    auto through_truth = rig::MergeBracket(b, true_g, wo);
    if (ours.ok()) a.weighting_ours[k] = rig::synth::LogRmsError(ours->radiance, truth, b);
    if (through_truth.ok()) {
      a.weighting_true[k] = rig::synth::LogRmsError(through_truth->radiance, truth, b);
      if (!crb.empty())
        a.bounded_true[k] = LogRmsWhereBounded(through_truth->radiance, truth, crb, kBoundLimit);
    }
  }

  cv::Mat cv_resp, cv_hdr;
  cv::createCalibrateDebevec()->process(Images(b), cv_resp, Times(b));
  cv::createMergeDebevec()->process(Images(b), cv_hdr, Times(b), cv_resp);
  a.cv_rms = rig::synth::LogRmsError(cv_hdr, truth, b);
  a.cv_g = CurveError([&](int c, int z) { return std::log(double(cv_resp.at<cv::Vec3f>(z)[c])); }, f);
  return a;
}

std::vector<std::pair<std::string, Accuracy>> g_rows;  // for the weighting table

void PrintAccuracy(const char* name, const Accuracy& a) {
  g_rows.emplace_back(name, a);
  const std::string ivw = a.ivw_rms < 0 ? "-" : fmt::format("{:.4f}", a.ivw_rms);
  const std::string crb = a.crb_rms < 0 ? "-" : fmt::format("{:.4f}", a.crb_rms);
  std::printf("%-34s %10.4f %10.4f %8.1fx %10.4f %10s %10s %9.4f   %8.4f %8.4f %8.4f   %zu\n",
              name, a.ours_rms, a.cv_rms, a.cv_rms / a.ours_rms, a.oracle_rms, ivw.c_str(),
              crb.c_str(),
              a.cv_rms / 5, a.ours_g, a.cv_g, a.ours_g_mid, a.pixels);
}

// A real HDR image as a bracket with known truth: scaled to median 1, negatives clipped,
// exposures covering its 0.5th..99.5th percentiles.
bool RealBracket(const std::string& path, const rig::synth::FilmicResponse& f, int frames,
                 cv::Mat* truth, Bracket* bracket) {
  cv::Mat e;
  if (path.ends_with(".exr")) {
    auto r = rig::ReadRgbExr(path);
    if (!r.ok()) return false;
    e = *r;
  } else {
    e = cv::imread(path, cv::IMREAD_UNCHANGED);
    if (e.empty()) return false;
    e.convertTo(e, CV_32FC3);
  }
  e = cv::max(e, 0.0f);
  const double lo = rig::synth::Percentile(e, 0.005), hi = rig::synth::Percentile(e, 0.995);
  *truth = e;
  *bracket = rig::synth::RenderBracket(e, rig::synth::ExposuresFor(lo, hi, frames), f, 11);
  return true;
}

// The simulator's own camera (config/sim.toml: its response, noise, JPEG encoding) on its
// own scene's exact radiance at one lamp pose, over the configured bracket.
bool SimulatorBracket(const std::string& config_path, int width, int height,
                      const std::string& format, cv::Mat* truth, Bracket* bracket, TrueCurve* g,
                      NoiseModel* noise) {
  auto cfg = rig::LoadConfigOrError(config_path);
  if (!cfg.ok()) {
    std::fprintf(stderr, "%s\n", cfg.error().ToString().c_str());
    return false;
  }
  cfg->sim.width = width;
  cfg->sim.height = height;
  cfg->sim.camera.format = format;
  // Electrons: shot variance X * gain, read variance read_e^2; in X (radiance * s) units.
  const auto& k = cfg->sim.camera;
  *noise = {k.shot_noise ? 1.0 / k.gain : 0.0, k.read_noise_e / k.gain};
  auto cam = rig::SimCamera::Create(*cfg, std::make_shared<rig::SimWorld>());
  if (!cam.ok()) {
    std::fprintf(stderr, "%s\n", cam.error().ToString().c_str());
    return false;
  }
  *truth = (*cam)->scene().Radiance(rig::LightDirection(30, 20, cfg->light_frame),
                                    cfg->lamp.radiance_rgb);
  const auto& br = cfg->bracket;
  bracket->clear();
  for (int k = 0; k < br.count; ++k) {
    const rig::Seconds t(br.center_s * std::pow(2.0, br.ev_step * (k - (br.count - 1) / 2.0)));
    auto bytes = (*cam)->Encode((*cam)->Expose(*truth, t, 100 + k));
    if (!bytes.ok()) return false;
    const std::string name = fmt::format("sim_{}.{}", k, cfg->sim.camera.format);
    auto img = rig::DecodeImageBytes(*bytes, name);
    if (!img.ok()) return false;
    bracket->push_back({*img, t, name});
  }
  const rig::SimResponse response = (*cam)->response();
  *g = [response](int c, int z) { return response.LogExposure(c, z); };
  return true;
}

// config/sim.toml: in the working folder, or beside the build folder the benchmark is in.
std::string DefaultSimConfig() {
  if (fs::exists("config/sim.toml")) return "config/sim.toml";
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  const fs::path beside = exe.parent_path().parent_path().parent_path() / "config" / "sim.toml";
  return beside.string();
}

}  // namespace

int main(int argc, char** argv) {
  Args args;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&] { return i + 1 < argc ? std::string(argv[++i]) : std::string(); };
    if (a == "--width") args.width = std::atoi(next().c_str());
    else if (a == "--height") args.height = std::atoi(next().c_str());
    else if (a == "--frames") args.frames = std::atoi(next().c_str());
    else if (a == "--repeat") args.repeat = std::max(1, std::atoi(next().c_str()));
    else if (a == "--threads") args.threads = std::max(1, std::atoi(next().c_str()));
    else if (a == "--shared") args.shared = next();
    else if (a == "--sim-config") args.sim_config = next();
    else if (a == "--sweep") args.sweep = true;
    else if (a == "--profile") g_profile = true;
    else {
      std::fprintf(stderr, "usage: hdr_bench [--width W] [--height H] [--frames N] [--repeat R] "
                           "[--threads T] [--shared DIR] [--sim-config TOML] [--sweep] [--profile]\n");
      return 2;
    }
  }
  cv::setNumThreads(args.threads);
  const rig::synth::FilmicResponse film;
  rig::ResponseOptions ro;
  ro.threads = args.threads;

  std::printf("hdr_bench: %dx%d (%.1f MP) x %d frames, threads %d, repeat %d (best of)\n",
              args.width, args.height, args.width * args.height / 1e6, args.frames, args.threads,
              args.repeat);
  std::printf("truth: filmic per-channel response (Hable curve, not a gamma), seeded shot+read "
              "noise, 8-bit\n\n");

  // --- the synthetic 6 MP bracket ---
  auto t0 = Clock::now();
  cv::Mat truth = rig::synth::SyntheticRadiance(args.width, args.height);
  const Bracket b = rig::synth::RenderBracket(
      truth, rig::synth::ExposuresFor(0.01, 300.0, args.frames), film, 7, 5e-5, 2.5e-4, CV_8U,
      args.threads);
  std::printf("rendered the bracket in %.2f s\n\n",
              std::chrono::duration<double>(Clock::now() - t0).count());

  // --- accuracy ---
  std::printf("ACCURACY (log-radiance RMS on well-recorded pixels, mean offset per channel "
              "removed;\n          true-g: our merge through the TRUE response;\n"
              "          ivw-true: inverse-variance weights (true noise model and quantisation, at "
              "the observed level)\n          through the TRUE response, a reference, not a bound;\n"
              "          CRB: the Cramer-Rao bound of any unbiased per-pixel estimator for the "
              "noise model, over the\n          pixel-channels it determines (table AGAINST THE "
              "BOUND) (-: noise model not known: JPEG);\n          response: max |g - g_true| over levels 13..242 "
              "(g 32-224: over 32..224), mean offset removed)\n");
  std::printf("%-34s %10s %10s %9s %10s %10s %10s %9s   %8s %8s %8s   %s\n", "bracket", "ours",
              "opencv", "ratio", "true-g", "ivw-true", "CRB", "opencv/5", "g ours", "g opencv", "g 32-224",
              "pixel-channels");
  const TrueCurve film_g = [&film](int c, int z) { return film.TrueG(c, z); };
  const NoiseModel rendered{5e-5, 2.5e-4};  // RenderBracket's noise, used for every rendering
  PrintAccuracy(fmt::format("synthetic {:.1f} MP", args.width * args.height / 1e6).c_str(),
                Compare(b, truth, film_g, ro, args.threads, rendered));
  // The simulator's camera as configured (JPEG), and the same exposures saved losslessly
  // (PNG), where its noise model is all there is and the bound can be computed.
  for (const char* format : {"jpg", "png"}) {
    cv::Mat st;
    Bracket sb;
    TrueCurve sg;
    NoiseModel sn;
    const std::string cfg = args.sim_config.empty() ? DefaultSimConfig() : args.sim_config;
    const bool jpeg = std::string(format) == "jpg";
    if (SimulatorBracket(cfg, 640, 480, format, &st, &sb, &sg, &sn)) {
      PrintAccuracy(jpeg ? "simulator camera 640x480 (JPEG)" : "simulator camera 640x480 (PNG)",
                    Compare(sb, st, sg, ro, args.threads,
                            jpeg ? std::nullopt : std::optional<NoiseModel>(sn)));
    } else {
      std::printf("%-34s (cannot set up the simulator from %s)\n", "simulator", cfg.c_str());
    }
  }
  const char* real[] = {"mpi_atrium_3.hdr", "Desk.exr"};
  for (const char* name : real) {
    cv::Mat rt;
    Bracket rb;
    const std::string path = args.shared + "/data/hdr/" + name;
    if (!RealBracket(path, film, args.frames, &rt, &rb)) {
      std::printf("%-34s (cannot read %s)\n", name, path.c_str());
      continue;
    }
    PrintAccuracy(fmt::format("{} {}x{}", name, rt.cols, rt.rows).c_str(),
                  Compare(rb, rt, film_g, ro, args.threads, rendered));
  }

  std::printf("\nMERGE WEIGHTING (log-radiance RMS as above; through our response | through the "
              "true one)\n%-34s %8s %8s %8s   | %8s %8s %8s %8s %8s\n", "bracket", "hat", "photon",
              "noise", "hat", "photon", "noise", "ivw-true", "CRB");
  for (const auto& [name, a] : g_rows) {
    const std::string ivw = a.ivw_rms < 0 ? "-" : fmt::format("{:.4f}", a.ivw_rms);
    const std::string crb = a.crb_rms < 0 ? "-" : fmt::format("{:.4f}", a.crb_rms);
    std::printf("%-34s %8.4f %8.4f %8.4f   | %8.4f %8.4f %8.4f %8s %8s\n", name.c_str(),
                a.weighting_ours[0], a.weighting_ours[1], a.weighting_ours[2], a.weighting_true[0],
                a.weighting_true[1], a.weighting_true[2], ivw.c_str(), crb.c_str());
  }
  std::printf("\nAGAINST THE BOUND (through the true response, on the pixel-channels whose Cramer-Rao "
              "bound is <= %.2f;\n          share: of the pixel-channels scored above)\n"
              "%-34s %8s %8s %8s %8s %8s %8s\n", kBoundLimit, "bracket", "hat", "photon",
              "noise", "ivw-true", "CRB", "share");
  for (const auto& [name, a] : g_rows) {
    if (a.crb_rms < 0) continue;
    std::printf("%-34s %8.4f %8.4f %8.4f %8.4f %8.4f %7.1f%%\n", name.c_str(), a.bounded_true[0],
                a.bounded_true[1], a.bounded_true[2], a.bounded_true[3], a.crb_rms,
                100 * a.crb_fraction);
  }

  // --- speed ---
  const double mp = args.width * double(args.height) / 1e6;
  const Bracket brackets[1] = {b};
  rig::ResponseCurve resp;
  auto rec = Time(args.repeat, [&] { resp = *rig::RecoverResponse(brackets, ro); });
  cv::Mat cv_resp;
  auto cv_rec = Time(args.repeat, [&] {
    cv::createCalibrateDebevec()->process(Images(b), cv_resp, Times(b));
  });
  rig::MergeOptions mo;
  mo.threads = args.threads;
  rig::RadianceMap map;
  auto merge = Time(args.repeat, [&] { map = *rig::MergeBracket(b, resp, mo); });
  mo.threads = 1;
  auto merge1 = Time(args.repeat, [&] { (void)*rig::MergeBracket(b, resp, mo); });
  cv::Mat cv_hdr;
  auto cv_merge = Time(std::max(1, args.repeat / 2), [&] {
    cv::createMergeDebevec()->process(Images(b), cv_hdr, Times(b), cv_resp);
  });
  std::printf("\nSPEED (%.1f MP x %d frames)           ours      opencv    ratio\n", mp,
              args.frames);
  std::printf("response recovery, s (best/median)  %.4f/%.4f  %.4f/%.4f\n", rec.first,
              rec.second, cv_rec.first, cv_rec.second);
  std::printf("merge MP/s (best, %d threads)        %8.1f  %8.2f  %6.1fx   (fitted-noise weights, fit included)\n", args.threads,
              mp / merge.first, mp / cv_merge.first, cv_merge.first / merge.first);
  std::printf("merge MP/s (median, %d threads)      %8.1f  %8.2f  %6.1fx\n", args.threads,
              mp / merge.second, mp / cv_merge.second, cv_merge.second / merge.second);
  std::printf("merge MP/s (best, 1 thread)          %8.1f\n", mp / merge1.first);
  for (auto [name, wt] : {std::pair{"hat weights", rig::MergeWeighting::kHat},
                          std::pair{"photon weights", rig::MergeWeighting::kPhoton}}) {
    rig::MergeOptions wo;
    wo.threads = args.threads;
    wo.weighting = wt;
    auto t = Time(args.repeat, [&] { (void)*rig::MergeBracket(b, resp, wo); });
    std::printf("merge MP/s (best, %d threads), %-20s %8.1f            %6.1fx\n", args.threads, name,
                mp / t.first, cv_merge.first / t.first);
  }
  {
    auto t = Time(args.repeat, [&] { (void)rig::FitNoise(b, resp, {-1, -1, -1}, {-1, -1, -1}); });
    std::printf("noise model fit alone, s (best)      %.4f\n", t.first);
  }
  // Both again with freed memory kept for reuse (what `rig` itself does): a fresh image-sized
  // block costs a page fault per 4 KiB, and OpenCV's merge allocates several per frame.
  rig::ReuseFreedImageMemory();
  {
    rig::MergeOptions wo;
    wo.threads = args.threads;
    auto ours_r = Time(args.repeat + 1, [&] { (void)*rig::MergeBracket(b, resp, wo); });
    auto cv_r = Time(args.repeat + 1, [&] {
      cv::createMergeDebevec()->process(Images(b), cv_hdr, Times(b), cv_resp);
    });
    std::printf("merge MP/s, freed memory reused      %8.1f  %8.2f  %6.1fx   (as in rig; both "
                "sides)\n", mp / ours_r.first, mp / cv_r.first, cv_r.first / ours_r.first);
  }

  // --- decoding and EXR writing ---
  const fs::path dir = fs::temp_directory_path() / ("rig_hdr_bench_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::vector<std::string> files;
  std::vector<rig::Seconds> times;
  for (size_t j = 0; j < b.size(); ++j) {
    files.push_back((dir / fmt::format("{}.jpg", j)).string());
    cv::imwrite(files.back(), b[j].image, {cv::IMWRITE_JPEG_QUALITY, 95});
    times.push_back(b[j].exposure);
  }
  auto dec1 = Time(args.repeat, [&] { (void)*rig::DecodeFrames(files, times, 1); });
  auto decn = Time(args.repeat,
                   [&] { (void)*rig::DecodeFrames(files, times, args.threads); });
  auto cv_dec = Time(args.repeat, [&] {
    std::vector<cv::Mat> kept;  // kept, as a bracket must be (fresh memory for every frame)
    for (const auto& f : files) kept.push_back(cv::imread(f, cv::IMREAD_COLOR));
  });
  std::printf("\nDECODE %d JPEG q95 frames             ours(1 thr) ours(%d thr) cv::imread loop\n",
              args.frames, args.threads);
  std::printf("seconds (best)                       %8.3f    %8.3f    %8.3f\n", dec1.first,
              decn.first, cv_dec.first);

  std::printf("\nEXR WRITE (R,G,B,flags; ZIP)         1 thread  %d threads   cv::imwrite\n",
              args.threads);
  for (auto type : {rig::ExrPixelType::kHalf, rig::ExrPixelType::kFloat}) {
    const std::string out = (dir / "map.exr").string();
    auto w1 = Time(2, [&] { (void)rig::WriteRadianceMap(out, map, type, 1).ok(); });
    auto wn = Time(2, [&] { (void)rig::WriteRadianceMap(out, map, type, args.threads).ok(); });
    auto cvw = Time(2, [&] {
      cv::imwrite(out, map.radiance,
                  {cv::IMWRITE_EXR_TYPE, type == rig::ExrPixelType::kHalf
                                             ? cv::IMWRITE_EXR_TYPE_HALF
                                             : cv::IMWRITE_EXR_TYPE_FLOAT});
    });
    std::printf("%-36s %8.3f  %8.3f    %8.3f  s (%.1f MB)\n",
                type == rig::ExrPixelType::kHalf ? "half" : "float", w1.first, wn.first,
                cvw.first, fs::file_size(out) / 1e6);
  }
  fs::remove_all(dir);

  if (args.sweep) {
    std::printf("\nSWEEP (synthetic bracket): max |g - g_true| over 13..242 / log-radiance RMS\n");
    std::printf("%-10s", "lambda");
    const int sample_counts[] = {50, 100, 300, 1000, 3000};
    for (int s : sample_counts) std::printf("   samples=%-5d", s);
    std::printf("\n");
    for (double lambda : {0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 1000.0}) {
      for (bool grid : {false, true}) {
        std::printf("%-6g%-4s", lambda, grid ? "grid" : "");
        for (int s : sample_counts) {
          rig::ResponseOptions o = ro;
          o.lambda = lambda;
          o.samples = s;
          o.grid_sampling = grid;
          auto r = rig::RecoverResponse(brackets, o);
          if (!r.ok()) {
            std::printf("   %-14s", "failed");
            continue;
          }
          rig::MergeOptions m;
          m.threads = args.threads;
          m.max_unrecorded_fraction = 1.0;
          auto mm = rig::MergeBracket(b, *r, m);
          const double ge = rig::synth::MaxResponseError(
              [&](int c, int z) { return r->log_exposure[c][z]; }, film, 13, 242);
          std::printf("   %.4f/%.4f  ", ge, rig::synth::LogRmsError(mm->radiance, truth, b));
        }
        std::printf("\n");
      }
    }
  }
  return 0;
}
