// NeuralRTI-style model: training (Adam, MSE over usable samples), encoding, 8-bit codes, files.
//
// Facts carried over from NeuralRTI (Univr-RTI/NeuralRTI): encoder of 3 hidden ELU layers as
// wide as its input (3 L), a k = 9 code; decoder (code, lx, ly) -> 3 ELU layers -> RGB,
// linear output; MSE on values / 255; Adam; codes quantised to 8 bits over min..max.
// Departures, and why: the code is the encoder's linear output (NeuralRTI puts an ELU on it,
// which only bounds it below); a batch is a set of pixels with all their lights, so each
// pixel is encoded once per step instead of once per (pixel, light) sample; the range is per
// plane, not one for all planes (a plane with a small range keeps its 256 steps); the
// decoder is fine-tuned on the stored codes, which NeuralRTI does not do.
#include "process/model/neural/neural.h"
#include "process/io/json_file.h"
#include "process/io/model_limits.h"
#include "config/atomic_file.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <numbers>
#include <thread>

#include <Eigen/Dense>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "config/log.h"

namespace rig {
namespace {

using MatF = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic>;
using VecF = Eigen::Matrix<float, Eigen::Dynamic, 1>;

struct Dense {
  MatF w;
  VecF b;
};
using Stack = std::vector<Dense>;  // every layer ELU but the last, which is linear
struct Net {
  Stack enc, dec;
};

// SplitMix64: a fixed generator, so a seed means the same numbers with every standard library.
uint64_t NextRandom(uint64_t* state) {
  uint64_t z = (*state += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
float UniformSigned(uint64_t* state) {  // [-1, 1)
  return static_cast<float>(NextRandom(state) >> 40) * (2.0f / 16777216.0f) - 1.0f;
}
size_t RandomBelow(uint64_t* state, size_t n) {
  return static_cast<size_t>(NextRandom(state) % static_cast<uint64_t>(n));
}
template <typename T>
void Shuffle(std::vector<T>* v, uint64_t* state) {
  for (size_t i = v->size(); i > 1; --i) std::swap((*v)[i - 1], (*v)[RandomBelow(state, i)]);
}

// He-uniform for the ELU layers, Glorot-uniform for the linear last one; zero biases.
Stack MakeStack(const std::vector<int>& dims, uint64_t* rng) {
  Stack s;
  for (size_t i = 0; i + 1 < dims.size(); ++i) {
    const int in = dims[i], out = dims[i + 1];
    const bool last = i + 2 == dims.size();
    const float limit = last ? std::sqrt(6.0f / static_cast<float>(in + out))
                             : std::sqrt(6.0f / static_cast<float>(in));
    Dense d;
    d.w.resize(out, in);
    for (int c = 0; c < in; ++c)
      for (int r = 0; r < out; ++r) d.w(r, c) = limit * UniformSigned(rng);
    d.b = VecF::Zero(out);
    s.push_back(std::move(d));
  }
  return s;
}

Stack ZerosLike(const Stack& s) {
  Stack z;
  for (const Dense& d : s) z.push_back({MatF::Zero(d.w.rows(), d.w.cols()), VecF::Zero(d.b.size())});
  return z;
}
void SetZero(Stack* s) {
  for (Dense& d : *s) {
    d.w.setZero();
    d.b.setZero();
  }
}

// acts[0] holds the input (one column per sample); fills acts[1..n].
void Forward(const Stack& s, std::vector<MatF>* acts) {
  acts->resize(s.size() + 1);
  for (size_t i = 0; i < s.size(); ++i) {
    MatF& out = (*acts)[i + 1];
    out.noalias() = s[i].w * (*acts)[i];
    out.colwise() += s[i].b;
    if (i + 1 < s.size()) {
      out.array() = (out.array() > 0.0f).select(out.array(), out.array().exp() - 1.0f);
    }
  }
}

// `d`: the loss gradient with respect to the stack's output (overwritten). Adds the weight
// gradients into `g`; if `d_input`, sets the gradient with respect to the input.
void Backward(const Stack& s, const std::vector<MatF>& acts, MatF* d, Stack* g, MatF* d_input) {
  for (size_t k = s.size(); k-- > 0;) {
    (*g)[k].w.noalias() += (*d) * acts[k].transpose();
    (*g)[k].b += d->rowwise().sum();
    if (k == 0) {
      if (d_input != nullptr) d_input->noalias() = s[0].w.transpose() * (*d);
      break;
    }
    MatF next = s[k].w.transpose() * (*d);
    // ELU'(a) = 1 for a > 0, exp(a) = h + 1 otherwise; h > 0 exactly when a > 0.
    next.array() *= (acts[k].array() > 0.0f).select(1.0f, acts[k].array() + 1.0f);
    *d = std::move(next);
  }
}

// What the workers read: the training pixels' encoder inputs and their samples.
struct TrainData {
  const LightSamples* samples = nullptr;
  int lights = 0, latent = 0;
  std::vector<size_t> pixel;  // training index -> pixel of `samples`
  MatF input;                 // 3 L x N encoder inputs
  MatF light_xy;              // 2 x L
  std::vector<int> usable;    // usable sample-channels per training pixel
  const MatF* fixed_codes = nullptr;  // k x N: decoder-only training on these codes
};

// The encoder's input for one pixel: value / 255 - 0.5 per (light, channel), light-major;
// a missing sample takes the pixel's mean of its usable samples in that channel (so what a
// masked sample holds is never read).
void EncoderInput(const LightSamples& s, size_t p, float* out) {
  const int lights = s.lights();
  for (int c = 0; c < 3; ++c) {
    double sum = 0;
    int n = 0;
    for (int l = 0; l < lights; ++l) {
      if (s.is_usable(p, l, c)) {
        sum += s.value(p, l, c);
        ++n;
      }
    }
    const float fill = n > 0 ? static_cast<float>(sum / n) / 255.0f - 0.5f : 0.0f;
    for (int l = 0; l < lights; ++l) {
      out[l * 3 + c] = s.is_usable(p, l, c) ? s.value(p, l, c) / 255.0f - 0.5f : fill;
    }
  }
}

// Forward and backward over training pixels order[0..n): adds gradients into `g`, returns
// the sum of squared errors. Gradients are of the batch mean (`inv_count` = 1 / usable).
double Work(const Net& net, const TrainData& d, const size_t* order, int n, const int* chosen,
            int lights, float inv_count, Net* g) {
  const int k = d.latent;
  const bool fixed = d.fixed_codes != nullptr;
  std::vector<MatF> ea, da(1);
  MatF z(k, n);
  if (!fixed) {
    ea.resize(1);
    ea[0].resize(d.input.rows(), n);
    for (int j = 0; j < n; ++j) ea[0].col(j) = d.input.col(static_cast<Eigen::Index>(order[j]));
    Forward(net.enc, &ea);
    z = ea.back();
  } else {
    for (int j = 0; j < n; ++j) z.col(j) = d.fixed_codes->col(static_cast<Eigen::Index>(order[j]));
  }
  MatF& x = da[0];
  x.resize(k + 2, static_cast<Eigen::Index>(n) * lights);
  for (int j = 0; j < n; ++j) {
    for (int l = 0; l < lights; ++l) {
      const Eigen::Index col = static_cast<Eigen::Index>(j) * lights + l;
      x.col(col).head(k) = z.col(j);
      const int li = chosen[static_cast<size_t>(j) * lights + l];
      x(k, col) = d.light_xy(0, li);
      x(k + 1, col) = d.light_xy(1, li);
    }
  }
  const Eigen::Index columns = x.cols();
  Forward(net.dec, &da);  // resizes da: x no longer refers to it
  const MatF& o = da.back();
  MatF r(3, columns);
  double loss = 0;
  const LightSamples& s = *d.samples;
  for (int j = 0; j < n; ++j) {
    const size_t p = d.pixel[order[j]];
    for (int l = 0; l < lights; ++l) {
      const Eigen::Index col = static_cast<Eigen::Index>(j) * lights + l;
      const int li = chosen[static_cast<size_t>(j) * lights + l];
      for (int c = 0; c < 3; ++c) {
        if (s.is_usable(p, li, c)) {
          const float diff = o(c, col) - s.value(p, li, c) / 255.0f;
          loss += static_cast<double>(diff) * diff;
          r(c, col) = 2.0f * diff * inv_count;
        } else {
          r(c, col) = 0.0f;
        }
      }
    }
  }
  MatF dx;
  Backward(net.dec, da, &r, &g->dec, fixed ? nullptr : &dx);
  if (!fixed) {
    MatF dz(k, n);
    for (int j = 0; j < n; ++j) {
      dz.col(j) = dx.block(0, static_cast<Eigen::Index>(j) * lights, k, lights).rowwise().sum();
    }
    Backward(net.enc, ea, &dz, &g->enc, nullptr);
  }
  return loss;
}

struct Adam {
  Net m, v;
  int t = 0;
};

void AdamStack(Stack* p, const Stack& g, Stack* m, Stack* v, float lr, float c1, float c2) {
  constexpr float kB1 = 0.9f, kB2 = 0.999f, kEps = 1e-7f;  // Keras's defaults
  auto update = [&](float* pp, const float* gg, float* mm, float* vv, Eigen::Index size) {
    for (Eigen::Index i = 0; i < size; ++i) {
      mm[i] = kB1 * mm[i] + (1 - kB1) * gg[i];
      vv[i] = kB2 * vv[i] + (1 - kB2) * gg[i] * gg[i];
      pp[i] -= lr * (mm[i] / c1) / (std::sqrt(vv[i] / c2) + kEps);
    }
  };
  for (size_t i = 0; i < p->size(); ++i) {
    update((*p)[i].w.data(), g[i].w.data(), (*m)[i].w.data(), (*v)[i].w.data(), g[i].w.size());
    update((*p)[i].b.data(), g[i].b.data(), (*m)[i].b.data(), (*v)[i].b.data(), g[i].b.size());
  }
}

void AddInto(Stack* a, const Stack& b) {
  for (size_t i = 0; i < a->size(); ++i) {
    (*a)[i].w += b[i].w;
    (*a)[i].b += b[i].b;
  }
}

// Epochs of Adam over the training pixels with a cosine learning rate lr0 -> lr1. With fixed
// codes only the decoder learns. Deterministic: the batch is cut into fixed thread shares and
// their gradients are added in share order.
void Train(Net* net, const TrainData& d, int epochs, int batch, int per_step, double lr0,
           double lr1, int threads, uint64_t* rng) {
  const bool fixed = d.fixed_codes != nullptr;
  const size_t count = d.pixel.size();
  if (epochs <= 0 || count == 0) return;
  const size_t steps_per_epoch = (count + static_cast<size_t>(batch) - 1) / static_cast<size_t>(batch);
  const double total = static_cast<double>(steps_per_epoch) * epochs;
  Adam adam{{fixed ? Stack{} : ZerosLike(net->enc), ZerosLike(net->dec)},
            {fixed ? Stack{} : ZerosLike(net->enc), ZerosLike(net->dec)}, 0};
  std::vector<Net> grads(static_cast<size_t>(threads));
  for (Net& g : grads) g = {fixed ? Stack{} : ZerosLike(net->enc), ZerosLike(net->dec)};
  std::vector<double> losses(static_cast<size_t>(threads));
  const int chosen_per_pixel = per_step > 0 ? std::min(per_step, d.lights) : d.lights;
  std::vector<int> chosen(static_cast<size_t>(batch) * chosen_per_pixel), all_lights(d.lights);
  for (int l = 0; l < d.lights; ++l) all_lights[l] = l;
  std::vector<size_t> order(count);
  for (size_t i = 0; i < count; ++i) order[i] = i;
  auto log = Log("process");
  size_t step = 0;
  for (int epoch = 0; epoch < epochs; ++epoch) {
    Shuffle(&order, rng);
    double epoch_loss = 0;
    size_t epoch_count = 0;
    for (size_t start = 0; start < count; start += static_cast<size_t>(batch), ++step) {
      const int n = static_cast<int>(std::min(count - start, static_cast<size_t>(batch)));
      // The lights each pixel of the batch is decoded under: all, or a seeded subset.
      size_t usable = 0;
      for (int j = 0; j < n; ++j) {
        int* dst = chosen.data() + static_cast<size_t>(j) * chosen_per_pixel;
        if (chosen_per_pixel == d.lights) {
          std::copy(all_lights.begin(), all_lights.end(), dst);
          usable += static_cast<size_t>(d.usable[order[start + j]]);
          continue;
        }
        for (int i = 0; i < chosen_per_pixel; ++i) {
          std::swap(all_lights[i], all_lights[i + RandomBelow(rng, d.lights - i)]);
          dst[i] = all_lights[i];
          for (int c = 0; c < 3; ++c)
            usable += d.samples->is_usable(d.pixel[order[start + j]], dst[i], c) ? 1 : 0;
        }
      }
      if (usable == 0) continue;
      const float inv = 1.0f / static_cast<float>(usable);
      const int shares = std::min(threads, n);
      auto share = [&](int t) {
        const int a = n * t / shares, b = n * (t + 1) / shares;
        Net& g = grads[static_cast<size_t>(t)];
        if (!fixed) SetZero(&g.enc);
        SetZero(&g.dec);
        losses[static_cast<size_t>(t)] =
            Work(*net, d, order.data() + start + a, b - a,
                 chosen.data() + static_cast<size_t>(a) * chosen_per_pixel, chosen_per_pixel, inv, &g);
      };
      std::vector<std::thread> pool;
      for (int t = 1; t < shares; ++t) pool.emplace_back(share, t);
      share(0);
      for (std::thread& th : pool) th.join();
      for (int t = 1; t < shares; ++t) {
        if (!fixed) AddInto(&grads[0].enc, grads[static_cast<size_t>(t)].enc);
        AddInto(&grads[0].dec, grads[static_cast<size_t>(t)].dec);
      }
      for (int t = 0; t < shares; ++t) epoch_loss += losses[static_cast<size_t>(t)];
      epoch_count += usable;
      const double progress = static_cast<double>(step) / total;
      const float lr = static_cast<float>(
          lr1 + 0.5 * (lr0 - lr1) * (1.0 + std::cos(std::numbers::pi * progress)));
      ++adam.t;
      const float c1 = 1.0f - std::pow(0.9f, static_cast<float>(adam.t));
      const float c2 = 1.0f - std::pow(0.999f, static_cast<float>(adam.t));
      if (!fixed) AdamStack(&net->enc, grads[0].enc, &adam.m.enc, &adam.v.enc, lr, c1, c2);
      AdamStack(&net->dec, grads[0].dec, &adam.m.dec, &adam.v.dec, lr, c1, c2);
    }
    log->debug("neural epoch={} fixed_codes={} rmse_8bit={:.3f}", epoch, fixed,
               255.0 * std::sqrt(epoch_loss / static_cast<double>(std::max<size_t>(1, epoch_count))));
  }
}

// Encodes pixels [a, b) into codes->col(p).
void EncodeRange(const Stack& enc, const LightSamples& s, size_t a, size_t b, MatF* codes) {
  constexpr size_t kChunk = 1024;
  const Eigen::Index in = 3 * s.lights();
  std::vector<MatF> acts(1);
  for (size_t c0 = a; c0 < b; c0 += kChunk) {
    const size_t n = std::min(kChunk, b - c0);
    acts[0].resize(in, static_cast<Eigen::Index>(n));
    for (size_t j = 0; j < n; ++j) EncoderInput(s, c0 + j, acts[0].col(static_cast<Eigen::Index>(j)).data());
    Forward(enc, &acts);
    codes->middleCols(static_cast<Eigen::Index>(c0), static_cast<Eigen::Index>(n)) = acts.back();
  }
}

std::vector<NeuralLayer> ToLayers(const Stack& s) {
  std::vector<NeuralLayer> out;
  for (const Dense& d : s) {
    NeuralLayer l;
    l.in = static_cast<int>(d.w.cols());
    l.out = static_cast<int>(d.w.rows());
    l.w.resize(static_cast<size_t>(l.in) * l.out);
    for (int r = 0; r < l.out; ++r)
      for (int c = 0; c < l.in; ++c) l.w[static_cast<size_t>(r) * l.in + c] = d.w(r, c);
    l.b.assign(d.b.data(), d.b.data() + d.b.size());
    out.push_back(std::move(l));
  }
  return out;
}

Stack FromLayers(const std::vector<NeuralLayer>& layers) {
  Stack s;
  for (const NeuralLayer& l : layers) {
    Dense d;
    d.w.resize(l.out, l.in);
    for (int r = 0; r < l.out; ++r)
      for (int c = 0; c < l.in; ++c) d.w(r, c) = l.w[static_cast<size_t>(r) * l.in + c];
    d.b = Eigen::Map<const VecF>(l.b.data(), l.out);
    s.push_back(std::move(d));
  }
  return s;
}

// The code images: names and planes (which codes each holds).
std::vector<std::vector<int>> ImagePlanes(int latent, NeuralCodeFormat format) {
  std::vector<std::vector<int>> planes;
  const int per = format == NeuralCodeFormat::kPng ? 3 : 1;
  for (int j = 0; j < latent; j += per) {
    std::vector<int> p;
    for (int c = j; c < std::min(latent, j + per); ++c) p.push_back(c);
    planes.push_back(p);
  }
  return planes;
}
std::string ImageName(int index, NeuralCodeFormat format) {
  return format == NeuralCodeFormat::kPng ? "codes_" + std::to_string(index) + ".png"
                                          : "code_" + std::to_string(index) + ".jpg";
}
// A 2-code PNG carries a zero third channel (PNG has grey, grey+alpha and RGB; alpha would do
// but a zero channel keeps the reader uniform).
int ImageChannels(size_t codes) { return codes == 1 ? 1 : 3; }

Result<std::vector<uint8_t>> ReadBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return MakeError(ErrorCode::kNotFound, path, "cannot open");
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (f.bad()) return MakeError(ErrorCode::kIo, path, "read failed");
  return bytes;
}
Status WriteBytes(const std::string& path, const void* data, size_t size) {
  return WriteFileAtomic(path, std::span<const uint8_t>(static_cast<const uint8_t*>(data), size));
}

void PutFloatLe(float v, std::vector<uint8_t>* out) {
  uint32_t u;
  std::memcpy(&u, &v, 4);
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<uint8_t>(u >> (8 * i)));
}
float GetFloatLe(const uint8_t* p) {
  uint32_t u = 0;
  for (int i = 0; i < 4; ++i) u |= static_cast<uint32_t>(p[i]) << (8 * i);
  float v;
  std::memcpy(&v, &u, 4);
  return v;
}

// The samples and options a fit can use; the problem named otherwise.
Status CheckNeuralInput(const LightSamples& samples, const NeuralOptions& options,
                        const std::string& ctx) {
  const size_t pixels = samples.pixels();
  const int lights = samples.lights();
  if (pixels == 0 || lights < 1)
    return MakeError(ErrorCode::kInvalidInput, ctx, "no pixels or no lights");
  if (samples.values.size() != pixels * static_cast<size_t>(lights) * 3 ||
      (!samples.usable.empty() && samples.usable.size() != samples.values.size()))
    return MakeError(ErrorCode::kInvalidInput, ctx,
                     "values/usable hold {} / {} entries, expected {} (pixels x lights x 3)",
                     samples.values.size(), samples.usable.size(),
                     pixels * static_cast<size_t>(lights) * 3);
  if (options.latent < 1 || options.latent > 64 || options.hidden < 1 ||
      options.decoder_layers < 1 || options.encoder_layers < 1 || options.encoder_hidden < 0 ||
      options.epochs < 0 || options.finetune_epochs < 0 || options.batch_pixels < 1 ||
      options.threads < 1 || options.lights_per_step < 0 || !(options.learning_rate > 0) || !(options.final_lr_ratio >= 0) ||
      options.jpeg_quality < 1 || options.jpeg_quality > 100)
    return MakeError(ErrorCode::kInvalidInput, ctx,
                     "bad options (latent 1..64, hidden, layers, batch, threads >= 1, "
                     "epochs >= 0, learning rate > 0, jpeg quality 1..100)");
  return Ok();
}

// The training pixels (a seeded subset of train_pixels, in memory order), their encoder
// inputs and usable-sample counts, and the lights' (x, y).
TrainData MakeTrainData(const LightSamples& samples, const NeuralOptions& options, uint64_t* rng_state) {
  const size_t pixels = samples.pixels();
  const int lights = samples.lights();
  const int in = 3 * lights;
  const int k = options.latent;
  uint64_t& rng = *rng_state;
  TrainData data;
  data.samples = &samples;
  data.lights = lights;
  data.latent = k;
  {
    std::vector<size_t> all(pixels);
    for (size_t p = 0; p < pixels; ++p) all[p] = p;
    const size_t n = options.train_pixels == 0 ? pixels : std::min(pixels, options.train_pixels);
    // A partial Fisher-Yates: the first n of a seeded permutation.
    for (size_t i = 0; i < n; ++i) std::swap(all[i], all[i + RandomBelow(&rng, pixels - i)]);
    all.resize(n);
    std::sort(all.begin(), all.end());  // memory order; the epochs shuffle anyway
    data.pixel = std::move(all);
  }
  const size_t n_train = data.pixel.size();
  data.input.resize(in, static_cast<Eigen::Index>(n_train));
  data.usable.resize(n_train);
  for (size_t j = 0; j < n_train; ++j) {
    EncoderInput(samples, data.pixel[j], data.input.col(static_cast<Eigen::Index>(j)).data());
    int u = 0;
    for (int l = 0; l < lights; ++l)
      for (int c = 0; c < 3; ++c) u += samples.is_usable(data.pixel[j], l, c) ? 1 : 0;
    data.usable[j] = u;
  }
  data.light_xy.resize(2, lights);
  for (int l = 0; l < lights; ++l) {
    data.light_xy(0, l) = static_cast<float>(samples.directions[l][0]);
    data.light_xy(1, l) = static_cast<float>(samples.directions[l][1]);
  }
  return data;
}

// Every pixel's code, in fixed thread shares.
MatF EncodeAll(const Stack& enc, int k, const LightSamples& samples, int threads) {
  const size_t pixels = samples.pixels();
  MatF z(k, static_cast<Eigen::Index>(pixels));
  {
    const int shares = static_cast<int>(std::min<size_t>(static_cast<size_t>(threads), pixels));
    std::vector<std::thread> pool;
    for (int t = 1; t < shares; ++t) {
      pool.emplace_back([&, t] {
        EncodeRange(enc, samples, pixels * t / shares, pixels * (t + 1) / shares, &z);
      });
    }
    EncodeRange(enc, samples, 0, pixels / shares, &z);
    for (std::thread& th : pool) th.join();
  }
  return z;
}

// A code image as stored: PNG, or JPEG at the options' quality.
Result<std::vector<uint8_t>> EncodeCodeImage(const cv::Mat& img, const NeuralOptions& options,
                                             const std::string& ctx) {
  std::vector<uint8_t> bytes;
  try {
    const bool png = options.code_format == NeuralCodeFormat::kPng;
    std::vector<int> params = png ? std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 9}
                                  : std::vector<int>{cv::IMWRITE_JPEG_QUALITY, options.jpeg_quality};
    if (!cv::imencode(png ? ".png" : ".jpg", img, bytes, params))
      return MakeError(ErrorCode::kInternal, ctx, "cannot encode the code image");
  } catch (const cv::Exception& e) {
    return MakeError(ErrorCode::kInternal, ctx, "OpenCV: {}", e.what());
  }
  return bytes;
}

}  // namespace

Result<NeuralModel> FitNeural(const LightSamples& samples, const NeuralOptions& options) {
  const size_t pixels = samples.pixels();
  const int lights = samples.lights();
  const std::string ctx = "neural fit";
  RIG_TRY(CheckNeuralInput(samples, options, ctx));
  const int k = options.latent;
  const int in = 3 * lights;
  const int enc_hidden = options.encoder_hidden > 0 ? options.encoder_hidden : in;
  uint64_t rng = options.seed;

  std::vector<int> enc_dims{in}, dec_dims{k + 2};
  for (int i = 0; i < options.encoder_layers; ++i) enc_dims.push_back(enc_hidden);
  enc_dims.push_back(k);
  for (int i = 0; i < options.decoder_layers; ++i) dec_dims.push_back(options.hidden);
  dec_dims.push_back(3);
  Net net;
  net.enc = MakeStack(enc_dims, &rng);
  net.dec = MakeStack(dec_dims, &rng);

  TrainData data = MakeTrainData(samples, options, &rng);
  const size_t n_train = data.pixel.size();
  const double lr0 = options.learning_rate, lr1 = options.learning_rate * options.final_lr_ratio;
  Train(&net, data, options.epochs, options.batch_pixels, options.lights_per_step, lr0, lr1,
        options.threads, &rng);

  const MatF z = EncodeAll(net.enc, k, samples, options.threads);
  NeuralModel model;
  model.width_ = samples.width;
  model.height_ = samples.height;
  model.latent_ = k;
  model.format_ = options.code_format;
  model.scale_.resize(k);
  model.bias_.resize(k);
  model.codes_.resize(pixels * static_cast<size_t>(k));
  for (int j = 0; j < k; ++j) {
    const float lo = z.row(j).minCoeff(), hi = z.row(j).maxCoeff();
    float scale = (hi - lo) / 255.0f;
    if (!(scale > 0)) scale = 1.0f;
    model.scale_[j] = scale;
    model.bias_[j] = lo;
    for (size_t p = 0; p < pixels; ++p) {
      const float q = std::round((z(j, static_cast<Eigen::Index>(p)) - lo) / scale);
      model.codes_[p * k + j] = static_cast<uint8_t>(std::clamp(q, 0.0f, 255.0f));
    }
  }
  // The code images as they will be stored; with JPEG the codes become what JPEG gives back.
  const auto planes = ImagePlanes(k, options.code_format);
  for (size_t i = 0; i < planes.size(); ++i) {
    const int ch = ImageChannels(planes[i].size());
    cv::Mat img(samples.height, samples.width, CV_8UC(ch), cv::Scalar::all(0));
    for (size_t p = 0; p < pixels; ++p) {
      uint8_t* px = img.data + p * static_cast<size_t>(ch);
      for (size_t c = 0; c < planes[i].size(); ++c) px[c] = model.codes_[p * k + planes[i][c]];
    }
    RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeCodeImage(img, options, ctx));
    if (options.code_format != NeuralCodeFormat::kPng) {
      cv::Mat back = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
      if (back.empty() || back.type() != CV_8UC1 || back.total() != pixels)
        return MakeError(ErrorCode::kInternal, ctx, "JPEG code image does not decode");
      for (size_t p = 0; p < pixels; ++p) model.codes_[p * k + planes[i][0]] = back.data[p];
    }
    model.code_names_.push_back(ImageName(static_cast<int>(i), options.code_format));
    model.code_files_.push_back(std::move(bytes));
  }

  // The decoder learns the codes as stored.
  if (options.finetune_epochs > 0) {
    MatF stored(k, static_cast<Eigen::Index>(n_train));
    for (size_t j = 0; j < n_train; ++j)
      for (int c = 0; c < k; ++c)
        stored(c, static_cast<Eigen::Index>(j)) =
            model.bias_[c] + model.scale_[c] * model.codes_[data.pixel[j] * k + c];
    data.fixed_codes = &stored;
    Train(&net, data, options.finetune_epochs, options.batch_pixels, options.lights_per_step,
          0.1 * lr0, lr1, options.threads, &rng);
    data.fixed_codes = nullptr;
  }
  model.decoder_ = ToLayers(net.dec);
  return model;
}

cv::Mat NeuralModel::Render(const Vec3& direction) const {
  cv::Mat out(height_, width_, CV_32FC3);
  if (out.empty() || decoder_.empty()) return out;
  const Stack dec = FromLayers(decoder_);
  const size_t pixels = static_cast<size_t>(width_) * height_;
  const int k = latent_;
  const float lx = static_cast<float>(direction[0]), ly = static_cast<float>(direction[1]);
  constexpr size_t kChunk = 4096;
  std::vector<MatF> acts(1);
  float* dst = out.ptr<float>();
  for (size_t c0 = 0; c0 < pixels; c0 += kChunk) {
    const size_t n = std::min(kChunk, pixels - c0);
    MatF& x = acts[0];
    x.resize(k + 2, static_cast<Eigen::Index>(n));
    for (size_t j = 0; j < n; ++j) {
      const uint8_t* code = codes_.data() + (c0 + j) * k;
      for (int c = 0; c < k; ++c) x(c, static_cast<Eigen::Index>(j)) = bias_[c] + scale_[c] * code[c];
      x(k, static_cast<Eigen::Index>(j)) = lx;
      x(k + 1, static_cast<Eigen::Index>(j)) = ly;
    }
    Forward(dec, &acts);
    const MatF& o = acts.back();
    for (size_t j = 0; j < n; ++j) {
      float* px = dst + (c0 + j) * 3;
      for (int c = 0; c < 3; ++c)
        px[2 - c] = std::clamp(o(c, static_cast<Eigen::Index>(j)), 0.0f, 1.0f);
    }
  }
  return out;
}

Status NeuralModel::Save(const std::string& folder) const {
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec) return MakeError(ErrorCode::kIo, folder, "cannot create folder: {}", ec.message());
  nlohmann::json j;
  j["format"] = "rig-neural-rti";
  j["version"] = 1;
  j["width"] = width_;
  j["height"] = height_;
  j["latent"] = latent_;
  j["code_format"] = format_ == NeuralCodeFormat::kPng ? "png" : "jpeg";
  j["code_images"] = code_names_;
  // Floats written as doubles round-trip exactly (nlohmann prints the shortest exact form).
  j["scale"] = std::vector<double>(scale_.begin(), scale_.end());
  j["bias"] = std::vector<double>(bias_.begin(), bias_.end());
  j["light_input"] = nlohmann::json::array({"lx", "ly"});
  nlohmann::json layers = nlohmann::json::array();
  std::vector<uint8_t> weights;
  for (const NeuralLayer& l : decoder_) {
    layers.push_back({{"in", l.in}, {"out", l.out}});
    for (float v : l.w) PutFloatLe(v, &weights);
    for (float v : l.b) PutFloatLe(v, &weights);
  }
  j["decoder"] = {{"file", "decoder.bin"},
                  {"dtype", "float32, little-endian; per layer w (out x in, row-major), then b"},
                  {"activation", "elu on every layer but the last"},
                  {"layers", layers}};
  const std::string text = j.dump(1) + "\n";
  RIG_TRY(WriteBytes(folder + "/neural.json", text.data(), text.size()));
  RIG_TRY(WriteBytes(folder + "/decoder.bin", weights.data(), weights.size()));
  for (size_t i = 0; i < code_names_.size(); ++i) {
    RIG_TRY(WriteBytes(folder + "/" + code_names_[i], code_files_[i].data(), code_files_[i].size()));
  }
  return Ok();
}

Result<NeuralModel> NeuralModel::Load(const std::string& folder) {
  const std::string json_path = folder + "/neural.json";
  RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> text, ReadBytes(json_path));
  NeuralModel m;
  std::vector<std::pair<int, int>> dims;
  std::string weights_name;
  try {
    const nlohmann::json j = nlohmann::json::parse(text.begin(), text.end());
    if (j.at("format").get<std::string>() != "rig-neural-rti" || !j.at("version").is_number_integer() ||
        j.at("version").get<int64_t>() != 1)
      return MakeError(ErrorCode::kCorrupt, json_path, "not a rig-neural-rti version 1 model");
    RIG_ASSIGN_OR_RETURN(m.width_, JsonIntegerIn(j.at("width"), 1, 65500, json_path, "width"));
    RIG_ASSIGN_OR_RETURN(m.height_, JsonIntegerIn(j.at("height"), 1, 65500, json_path, "height"));
    RIG_ASSIGN_OR_RETURN(m.latent_, JsonIntegerIn(j.at("latent"), 1, 64, json_path, "latent"));
    const std::string fmt = j.at("code_format").get<std::string>();
    if (fmt != "png" && fmt != "jpeg")
      return MakeError(ErrorCode::kCorrupt, json_path, "unknown code_format '{}'", fmt);
    m.format_ = fmt == "png" ? NeuralCodeFormat::kPng : NeuralCodeFormat::kJpeg;
    m.code_names_ = j.at("code_images").get<std::vector<std::string>>();
    for (const char* field : {"scale", "bias"}) {
      std::vector<float>& out = field[0] == 's' ? m.scale_ : m.bias_;
      for (double v : j.at(field).get<std::vector<double>>()) {
        RIG_TRY(CheckFloatValue(v, json_path, std::string(field) + "[" + std::to_string(out.size()) + "]"));
        out.push_back(static_cast<float>(v));
      }
    }
    weights_name = j.at("decoder").at("file").get<std::string>();
    for (const auto& l : j.at("decoder").at("layers")) {
      const std::string layer = fmt::format("decoder.layers[{}]", dims.size());
      RIG_ASSIGN_OR_RETURN(const int in, JsonIntegerIn(l.at("in"), 1, 4096, json_path, layer + ".in"));
      RIG_ASSIGN_OR_RETURN(const int out, JsonIntegerIn(l.at("out"), 1, 4096, json_path, layer + ".out"));
      dims.emplace_back(in, out);
    }
  } catch (const nlohmann::json::exception& e) {
    return MakeError(ErrorCode::kCorrupt, json_path, "{}", e.what());
  }
  const int k = m.latent_;
  if (m.width_ < 1 || m.height_ < 1 || m.width_ > 65500 || m.height_ > 65500 ||
      static_cast<int64_t>(m.width_) * m.height_ > (int64_t{1} << 28) || k < 1 || k > 64 ||
      m.scale_.size() != static_cast<size_t>(k) || m.bias_.size() != static_cast<size_t>(k) ||
      dims.empty() || dims.front().first != k + 2 || dims.back().second != 3)
    return MakeError(ErrorCode::kCorrupt, json_path, "inconsistent sizes");
  const auto planes = ImagePlanes(k, m.format_);
  if (m.code_names_.size() != planes.size())
    return MakeError(ErrorCode::kCorrupt, json_path, "{} code images for {} codes",
                     m.code_names_.size(), k);
  const size_t pixels = static_cast<size_t>(m.width_) * m.height_;
  for (size_t i = 0; i < planes.size(); ++i) {
    const std::string path = folder + "/" + m.code_names_[i];
    RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadBytes(path));
    cv::Mat img;
    try {
      img = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception& e) {
      return MakeError(ErrorCode::kCorrupt, path, "OpenCV: {}", e.what());
    }
    const int ch = m.format_ == NeuralCodeFormat::kPng ? ImageChannels(planes[i].size()) : 1;
    if (img.empty() || img.type() != CV_8UC(ch) || img.cols != m.width_ || img.rows != m.height_ ||
        !img.isContinuous())
      return MakeError(ErrorCode::kCorrupt, path, "expected an 8-bit {}-channel {}x{} image", ch,
                       m.width_, m.height_);
    // Allocated once an image of the declared size is there (not on the word of neural.json).
    if (m.codes_.empty()) m.codes_.assign(pixels * k, 0);
    for (size_t p = 0; p < pixels; ++p)
      for (size_t c = 0; c < planes[i].size(); ++c)
        m.codes_[p * k + planes[i][c]] = img.data[p * static_cast<size_t>(ch) + c];
    m.code_files_.push_back(std::move(bytes));
  }
  const std::string wpath = folder + "/" + weights_name;
  RIG_ASSIGN_OR_RETURN(std::vector<uint8_t> w, ReadBytes(wpath));
  size_t need = 0;
  for (size_t i = 0; i < dims.size(); ++i) {
    if (dims[i].first < 1 || dims[i].second < 1 || dims[i].first > 4096 || dims[i].second > 4096 ||
        (i > 0 && dims[i].first != dims[i - 1].second))
      return MakeError(ErrorCode::kCorrupt, json_path, "decoder layer {} has bad sizes", i);
    need += (static_cast<size_t>(dims[i].first) + 1) * dims[i].second * 4;
  }
  if (w.size() != need)
    return MakeError(ErrorCode::kCorrupt, wpath, "{} bytes, expected {}", w.size(), need);
  const uint8_t* p = w.data();
  for (const auto& [din, dout] : dims) {
    NeuralLayer l;
    l.in = din;
    l.out = dout;
    for (int i = 0; i < din * dout; ++i, p += 4) l.w.push_back(GetFloatLe(p));
    for (int i = 0; i < dout; ++i, p += 4) l.b.push_back(GetFloatLe(p));
    m.decoder_.push_back(std::move(l));
  }
  return m;
}

uint64_t NeuralModel::BytesOnDisk(const std::string& folder) {
  std::error_code ec;
  uint64_t total = 0;
  for (std::filesystem::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code fe;
    if (it->is_regular_file(fe)) {
      const auto size = it->file_size(fe);
      if (!fe) total += size;
    }
  }
  return total;
}

}  // namespace rig
