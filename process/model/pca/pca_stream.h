// The PCA model of a multi-light capture too large to hold in memory (24 MP × 72 lights is
// 5.2 GB of samples): two passes over the JPEG images, every decoder open at once and read by
// bands of rows, never a whole image in memory — the same model, byte for byte, as the
// in-memory FitPcaAuto followed by PcaModel::Save.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "config/result.h"
#include "process/model/pca/pca.h"
#include "process/model/pca/pca_choice.h"
#include "process/model/lp.h"

namespace rig {

struct PcaStreamOptions {
  int band_rows = 16;  // rows read from every image at a time (memory ∝ band_rows × width × lights)
  int threads = 2;     // decoding and solving; the result does not depend on it
  std::string lp;      // the .lp file, for error messages only
};

struct PcaStreamFit {
  PcaChoice choice;
  PcaFitStats stats;  // the coefficients' over every pixel; time_s: the whole fit, both passes
  int width = 0, height = 0, lights = 0;
  size_t masked_samples = 0;      // sample-channels at or beyond the thresholds (MaskLdrSamples)
  double masked_fraction = 0;     // of all sample-channels
  double pixels_with_masked = 0;  // fraction of pixels with at least one masked sample
  int bands = 0;                  // per pass
  double gather_s = 0;            // pass 1: the seeded pixel sample and the central crop
  double choice_s = 0;            // components, the size choice, the basis, the planes' ranges
  double write_s = 0;             // pass 2: every pixel's coefficients, the planes, info.json
  // Pass 2's parts (WritePcaPlanes): the bands' samples from the source, the coefficients
  // solved and quantised (with the masked-sample counts), the JPEG encoding and files.
  double source_s = 0, solve_s = 0, encode_s = 0;
};

// What a capture's samples take in memory, pixels × lights × 3 bytes (values only; the
// in-memory path also holds the usable mask and, while loading, the images), from the first
// image's size (a JPEG's header; other formats are read) after `downsample`.
Result<uint64_t> RtiSampleBytes(const std::vector<LpEntry>& entries, int downsample = 1);

// Pass 1 gathers what the choice reads (the pixels ComputePcaComponents samples, the crop
// ChoosePca compresses); the choice and the basis as FitPcaAuto makes them; the planes' ranges
// from the sampled pixels' coefficients, each solved in the block FitPcaCoefficients would
// solve it in; pass 2 solves every pixel's coefficients band by band, in the same blocks, and
// writes them quantised row by row into the plane JPEGs of `out_folder` (created; files in it
// replaced), then info.json. JPEG images only, 8-bit colour, all one size, lights above the
// horizon. Memory: the bands, the sample (basis_pixels × lights × 3 B), the crop, and libjpeg's
// own buffers — a plane writer with optimised Huffman tables (as Save writes them) holds its
// file's DCT coefficients until the end, 6 B per pixel for each of the ceil(k / 3) files.
Result<PcaStreamFit> FitPcaStreaming(const std::vector<LpEntry>& entries,
                                     const PcaChoiceOptions& options,
                                     const std::string& out_folder,
                                     const PcaStreamOptions& stream = {});

// The pieces of pass 2 for another source of bands (a session's radiance maps as codes).
// Rows [y0, y0 + rows) of every light's samples, laid out as LightSamples::values.
using PcaBandSource = std::function<Status(int y0, int rows, std::vector<uint8_t>* values)>;
struct PcaPlanePass {
  const std::vector<Vec3>& directions;
  const PcaOptions& po;  // the model's: quality, thresholds
  const PcaCoefficientSolver& solver;
  const std::vector<std::pair<size_t, size_t>>& blocks;  // PcaCoefficientBlocks(pixels, po.threads)
  const std::vector<PlaneQuantisation>& quant;
  int k = 0;
  int width = 0, height = 0;
  int band_rows = 16, threads = 2;
  std::string context;  // for error messages
};
// Every pixel's coefficients in FitPcaCoefficients' blocks, quantised, written row by row into
// the ceil(k / 3) plane files of `out_folder` (created); *out's sample counts added to. The
// bytes are those of FitPcaCoefficients + PcaModel::Save on the same samples.
Status WritePcaPlanes(const PcaPlanePass& pass, const PcaBandSource& source,
                      const std::string& out_folder, PcaStreamFit* out);
// The planes' ranges from the sampled pixels' coefficients (`sampled`: the `subset` pixels'
// samples in that order), each solved in the block FitPcaCoefficients solves it in: the ranges
// FitPcaCoefficients takes.
std::vector<PlaneQuantisation> PcaSampledQuantisation(
    const PcaCoefficientSolver& solver, const std::vector<std::pair<size_t, size_t>>& blocks,
    const std::vector<size_t>& subset, const LightSamples& sampled, int k, double quantile,
    int threads);

}  // namespace rig
