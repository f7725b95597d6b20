// A neural reflectance model in the manner of NeuralRTI (Dulecha, Fanni, Ponchio, Pellacini,
// Giachetti, CGI 2020): an encoder maps a pixel's L x 3 samples to a latent code of k values;
// one small MLP decoder, shared by every pixel, maps (code, lx, ly) to RGB. Trained on the CPU.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/light_direction.h"
#include "process/model/light_samples.h"

namespace rig {

// How the 8-bit code planes are stored. PNG: lossless, three codes per image (channel c of
// image i holds code 3i + c; the last image holds the remainder, grey when one is left).
// JPEG: one grey image per code. One grey image per code, not three codes per colour image:
// OpenCV's JPEG writer (4.6) converts to YCbCr and subsamples chroma 2x2, which would mix
// codes and blur two of every three; grey JPEG keeps each code plane to itself.
enum class NeuralCodeFormat { kPng, kJpeg };

struct NeuralOptions {
  int latent = 9;           // k: codes per pixel (NeuralRTI: 9)
  int hidden = 50;          // decoder hidden width (NeuralRTI paper: 50)
  int decoder_layers = 3;   // decoder hidden layers, ELU
  // Encoder hidden width; 0: 3 L like NeuralRTI. 128: on the 72-light icon (3 L = 216) as
  // good held out (22.7 against 21.3 dB on 3 images) at 0.6 of the time.
  int encoder_hidden = 128;
  int encoder_layers = 3;   // encoder hidden layers, ELU
  int epochs = 16;          // passes over the training pixels
  size_t train_pixels = 24000;  // pixels drawn (seeded, without repeats) for training; 0: all
  int batch_pixels = 16;    // pixels per Adam step
  // Lights each pixel of a step is decoded under (a fresh seeded subset every step); 0: all.
  // The encoder always sees all of them; the decoder's cost is per (pixel, light).
  int lights_per_step = 12;
  double learning_rate = 3e-3;      // Adam, cosine decay to learning_rate * final_lr_ratio
  double final_lr_ratio = 0.02;
  // Decoder-only passes after the codes are quantised (and JPEG-coded): the decoder learns
  // the codes as stored, so the 8-bit step and the JPEG error are partly absorbed.
  int finetune_epochs = 2;
  // JPEG q95 on the icon: 3.26 B/px against PNG's 5.86, held-out PSNR 28.24 against 28.26 dB.
  NeuralCodeFormat code_format = NeuralCodeFormat::kJpeg;
  int jpeg_quality = 95;
  uint64_t seed = 1;        // same seed and threads: bit-identical model and files
  int threads = 2;          // worker threads over fixed halves of every batch
};

// One dense layer, row-major weights: out = w * in + b, w is out x in.
struct NeuralLayer {
  int in = 0, out = 0;
  std::vector<float> w, b;
};

// A fitted model: the quantised codes (what is stored) and the decoder. Immutable after
// FitNeural or Load; Render is const and thread-safe.
class NeuralModel {
 public:
  NeuralModel() = default;

  int width() const { return width_; }
  int height() const { return height_; }
  int latent() const { return latent_; }
  const std::vector<NeuralLayer>& decoder() const { return decoder_; }
  // The code of pixel p, plane j: codes()[p * latent + j], 0..255; value = bias + scale * code.
  const std::vector<uint8_t>& codes() const { return codes_; }
  const std::vector<float>& plane_scale() const { return scale_; }
  const std::vector<float>& plane_bias() const { return bias_; }

  // The scene lit from `direction` (unit, x right, y up, z towards the camera; only x and y
  // enter the decoder): CV_32FC3, BGR order, values in encoded units (8-bit code / 255),
  // clamped to [0, 1]. Uses the quantised codes, so a loaded model renders identically.
  cv::Mat Render(const Vec3& direction) const;

  // Writes neural.json (sizes, per-plane scale and bias, file names), the code images
  // (codes_N.png or code_N.jpg) and decoder.bin (little-endian float32, per layer w then b)
  // into `folder` (created if missing). The bytes are those held since the fit.
  Status Save(const std::string& folder) const;
  static Result<NeuralModel> Load(const std::string& folder);
  // Sum of the sizes of the regular files in `folder` (0 if it does not exist).
  static uint64_t BytesOnDisk(const std::string& folder);

 private:
  friend Result<NeuralModel> FitNeural(const LightSamples& samples,
                                       const NeuralOptions& options);
  int width_ = 0, height_ = 0, latent_ = 0;
  std::vector<uint8_t> codes_;
  std::vector<float> scale_, bias_;
  std::vector<NeuralLayer> decoder_;
  NeuralCodeFormat format_ = NeuralCodeFormat::kPng;
  std::vector<std::string> code_names_;               // file names of the code images
  std::vector<std::vector<uint8_t>> code_files_;      // their encoded bytes
};

// Trains encoder and decoder on `options.train_pixels` pixels (every light of each; masked
// samples are left out of the loss and replaced in the encoder's input by the pixel's mean
// of its usable samples in that channel, so they are never read), encodes every pixel,
// quantises the codes to 8 bits per plane (min..max), stores them in the chosen format and
// fine-tunes the decoder on the stored codes. Errors: empty or inconsistent samples, bad
// options.
Result<NeuralModel> FitNeural(const LightSamples& samples, const NeuralOptions& options);

}  // namespace rig
