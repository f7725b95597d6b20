// The neural model on the real NeuralRTI example capture (72 JPEGs, 402x395): fit time, bytes on
// disk, and held-out PSNR in 8-bit for every 6th image (k = 0, 6, ..., 66, each refitted without
// it), mean-MSE like relight's figures in ../shared/docs/rti-formats.md (PCA-RBF, 9 planes:
// 24.52 dB on this protocol at 3.35 B/px). Measured with the defaults (seed 1, 2 cores shared
// with other builds): 28.24 dB mean-MSE / 35.68 median at 3.26 B/px (JPEG q95 codes), fit of
// all 72 in 19-29 s; PNG codes 28.26 dB at 5.86 B/px; --mask (clipped and black samples out of
// the loss) loses on the two frontal images with 17% and 28% clipped channels.
//
//   build/bench/neural_bench [--data DIR] [--epochs N] [--train-pixels N] [--batch N]
//       [--encoder-hidden N] [--lights-per-step N] [--hidden N] [--latent N] [--lr X] [--finetune N]
//       [--format png|jpeg] [--quality Q] [--mask] [--skip-full] [--held-step S] [--held-max N]
//       [--threads N] [--seed N]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "process/model/light_samples.h"
#include "process/model/neural/neural.h"
#include "process/model/harmonic/loo.h"

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

double Seconds(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// 8-bit MSE of a render (BGR, [0, 1], rounded to 8 bits as a stored image would be) against
// the photo under light l.
double Mse(const cv::Mat& render, const rig::LightSamples& s, int l) {
  double sum = 0;
  const float* p = render.ptr<float>();
  for (size_t px = 0; px < s.pixels(); ++px)
    for (int c = 0; c < 3; ++c) {
      const double d = std::round(255.0 * p[px * 3 + (2 - c)]) - s.value(px, l, c);
      sum += d * d;
    }
  return sum / (3.0 * static_cast<double>(s.pixels()));
}
double Psnr(double mse) { return 10 * std::log10(255.0 * 255.0 / mse); }

}  // namespace

int main(int argc, char** argv) {
  std::string data = (fs::path(__FILE__).parent_path() / "../../shared/data/rti/neuralrti-example")
                         .lexically_normal()
                         .string();
  rig::NeuralOptions o;
  // The options' defaults, chosen on this capture (see the report of issue 14).
  bool mask = false, skip_full = false;
  int held_step = 6, held_max = 1000;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "neural_bench: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--data") data = next();
    else if (a == "--epochs") o.epochs = std::stoi(next());
    else if (a == "--train-pixels") o.train_pixels = std::stoul(next());
    else if (a == "--batch") o.batch_pixels = std::stoi(next());
    else if (a == "--encoder-hidden") o.encoder_hidden = std::stoi(next());
    else if (a == "--lights-per-step") o.lights_per_step = std::stoi(next());
    else if (a == "--hidden") o.hidden = std::stoi(next());
    else if (a == "--latent") o.latent = std::stoi(next());
    else if (a == "--lr") o.learning_rate = std::stod(next());
    else if (a == "--finetune") o.finetune_epochs = std::stoi(next());
    else if (a == "--format") o.code_format = next() == "jpeg" ? rig::NeuralCodeFormat::kJpeg
                                                               : rig::NeuralCodeFormat::kPng;
    else if (a == "--quality") o.jpeg_quality = std::stoi(next());
    else if (a == "--threads") o.threads = std::stoi(next());
    else if (a == "--seed") o.seed = std::stoull(next());
    else if (a == "--mask") mask = true;
    else if (a == "--no-mask") mask = false;
    else if (a == "--skip-full") skip_full = true;
    else if (a == "--held-step") held_step = std::stoi(next());
    else if (a == "--held-max") held_max = std::stoi(next());
    else {
      std::fprintf(stderr, "neural_bench: unknown option %s\n", a.c_str());
      return 2;
    }
  }

  auto lp = rig::ReadLp(data + "/dirs.lp");
  if (!lp.ok()) {
    std::fprintf(stderr, "neural_bench: %s\n", lp.error().ToString().c_str());
    return 1;
  }
  rig::LightSamples s;
  std::vector<cv::Mat> rgb;
  for (const auto& e : *lp) {
    cv::Mat bgr = cv::imread(e.image, cv::IMREAD_COLOR);
    if (bgr.empty()) {
      std::fprintf(stderr, "neural_bench: cannot read %s\n", e.image.c_str());
      return 1;
    }
    cv::Mat m;
    cv::cvtColor(bgr, m, cv::COLOR_BGR2RGB);
    rgb.push_back(m);
    s.directions.push_back(e.direction);
  }
  s.width = rgb[0].cols;
  s.height = rgb[0].rows;
  const int lights = s.lights();
  s.values.resize(s.pixels() * static_cast<size_t>(lights) * 3);
  for (int l = 0; l < lights; ++l) {
    if (rgb[l].size() != rgb[0].size()) {
      std::fprintf(stderr, "neural_bench: image %d differs in size\n", l);
      return 1;
    }
    for (size_t p = 0; p < s.pixels(); ++p)
      for (int c = 0; c < 3; ++c)
        s.values[(p * lights + l) * 3 + c] = rgb[l].data[p * 3 + c];
  }
  size_t masked = 0;
  if (mask) masked = rig::MaskLdrSamples(&s);

  std::printf("neural_bench: %s, %d images %dx%d, mask %s (%zu sample-channels missing, %.2f%%)\n",
              data.c_str(), lights, s.width, s.height, mask ? "on" : "off", masked,
              100.0 * masked / s.values.size());
  std::printf("options: latent %d, encoder %d x %s ELU, decoder %d x %d ELU, epochs %d, "
              "train_pixels %zu, batch_pixels %d, lights_per_step %d, lr %.4g -> x%.3g cosine, finetune %d, "
              "format %s%s, seed %llu, threads %d\n",
              o.latent, o.encoder_layers,
              o.encoder_hidden > 0 ? std::to_string(o.encoder_hidden).c_str() : "3L",
              o.decoder_layers, o.hidden, o.epochs, o.train_pixels, o.batch_pixels, o.lights_per_step,
              o.learning_rate, o.final_lr_ratio, o.finetune_epochs,
              o.code_format == rig::NeuralCodeFormat::kPng ? "png" : "jpeg",
              o.code_format == rig::NeuralCodeFormat::kPng
                  ? ""
                  : (" q" + std::to_string(o.jpeg_quality)).c_str(),
              static_cast<unsigned long long>(o.seed), o.threads);

  // The fit on all 72: time, bytes, PSNR on the images it saw.
  const std::string dir =
      (fs::temp_directory_path() / ("rig_neural_bench_" + std::to_string(::getpid()))).string();
  if (!skip_full) {
    const auto t = Clock::now();
    auto model = rig::FitNeural(s, o);
    const double fit_s = Seconds(t);
    if (!model.ok()) {
      std::fprintf(stderr, "neural_bench: %s\n", model.error().ToString().c_str());
      return 1;
    }
    fs::remove_all(dir);
    if (auto st = model->Save(dir); !st.ok()) {
      std::fprintf(stderr, "neural_bench: %s\n", st.error().ToString().c_str());
      return 1;
    }
    const uint64_t bytes = rig::NeuralModel::BytesOnDisk(dir);
    uint64_t decoder_bytes = 0;
    std::error_code ec;
    decoder_bytes = fs::file_size(dir + "/decoder.bin", ec);
    const auto tr = Clock::now();
    double mse = 0;
    for (int l = 0; l < lights; ++l) mse += Mse(model->Render(s.directions[l]), s, l) / lights;
    const double render_s = Seconds(tr) / lights;
    std::printf("\nall %d images: fit %.1f s, render %.3f s/image, %llu bytes on disk "
                "(decoder %llu) = %.2f B/px, PSNR on the fitted images %.2f dB (mean-MSE)\n",
                lights, fit_s, render_s, static_cast<unsigned long long>(bytes),
                static_cast<unsigned long long>(decoder_bytes),
                static_cast<double>(bytes) / static_cast<double>(s.pixels()), Psnr(mse));
    fs::remove_all(dir);
  }

  // Held out: every held_step-th image, each refitted without it.
  std::printf("\n| held-out image | light (x, y, z) | fit s | PSNR dB | nearest photo dB | clipped |\n|---|---|---|---|---|---|\n");
  double sum_mse = 0, sum_fit = 0;
  std::vector<double> psnrs;
  for (int k = 0, n = 0; k < lights && n < held_max; k += held_step, ++n) {
    const rig::LightSamples train = rig::WithoutLight(s, k);
    const auto t = Clock::now();
    auto model = rig::FitNeural(train, o);
    const double fit_s = Seconds(t);
    if (!model.ok()) {
      std::fprintf(stderr, "neural_bench: %s\n", model.error().ToString().c_str());
      return 1;
    }
    const double mse = Mse(model->Render(s.directions[k]), s, k);
    // Reference: the photo of the nearest other light, as it is.
    int nearest = -1;
    double best = -2;
    for (int l = 0; l < lights; ++l) {
      if (l == k) continue;
      const double dot = s.directions[l][0] * s.directions[k][0] +
                         s.directions[l][1] * s.directions[k][1] +
                         s.directions[l][2] * s.directions[k][2];
      if (dot > best) best = dot, nearest = l;
    }
    double nn_mse = 0;
    size_t clipped = 0;
    for (size_t px = 0; px < s.pixels(); ++px)
      for (int c = 0; c < 3; ++c) {
        const double d = double(s.value(px, nearest, c)) - s.value(px, k, c);
        nn_mse += d * d;
        clipped += s.value(px, k, c) >= 250 ? 1 : 0;
      }
    nn_mse /= 3.0 * static_cast<double>(s.pixels());
    std::printf("| %d (%s) | %.3f, %.3f, %.3f | %.1f | %.2f | %.2f | %.2f%% |\n", k,
                fs::path((*lp)[k].image).filename().c_str(), s.directions[k][0],
                s.directions[k][1], s.directions[k][2], fit_s, Psnr(mse), Psnr(nn_mse),
                100.0 * clipped / (3.0 * s.pixels()));
    std::fflush(stdout);
    sum_mse += mse;
    sum_fit += fit_s;
    psnrs.push_back(Psnr(mse));
  }
  std::sort(psnrs.begin(), psnrs.end());
  const double n = static_cast<double>(psnrs.size());
  std::printf("\nheld out %zu images: mean-MSE PSNR %.2f dB, median PSNR %.2f dB, mean fit %.1f s "
              "(relight PCA-RBF, 9 planes: 24.52 dB mean-MSE / 30.61 median at 3.35 B/px)\n",
              psnrs.size(), Psnr(sum_mse / n), psnrs[psnrs.size() / 2], sum_fit / n);
  return 0;
}
