// The PCA model family: every pixel's multi-light samples (3 colours × L lights) projected
// onto k principal components shared by all pixels; each component's (and the mean's)
// dependence on the light direction stored on an octahedral grid and read by bilinear
// interpolation — the "bilinear" type of relight's web format, so a model written here opens
// in relight and OpenLIME as it is. What is ours is how the grid is filled (a smoothness-
// regularised least-squares fit to the sampled lights, its strength and kind chosen by
// leave-one-out over lights, instead of resampling), coefficients refitted through the
// basis exactly as stored, and clipped or black samples fitted around.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/io/jpeg_io.h"
#include "process/model/hdr_codes.h"
#include "process/model/light_direction.h"
#include "process/model/light_samples.h"
#include "process/model/reflectance_model.h"

namespace rig {

enum class PcaMaskMode {
  kNone,   // every sample is used as it is
  kDrop,   // clipped and black samples are left out of each pixel's fit
  kHinge,  // censored: a clipped sample only pulls the fit up to its value, a black one only
           // down (left out where the fit already lies beyond it)
};
const char* PcaMaskModeName(PcaMaskMode mode);

enum class GridPrior {
  kMembrane,  // penalises the gradient: flat beyond the sampled lights
  kBending,   // penalises the Laplacian: linear trends carried beyond the sampled lights
};

struct PcaOptions {
  int components = 9;        // k, planes stored
  int grid_resolution = 12;  // octahedral grid nodes per side (relight's default is 8)
  // Strength of the grid prior relative to the data term; < 0: chosen with the prior's kind
  // by leave-one-out over the sampled lights (inside every fit, so inside every fold).
  double smoothness = -1;
  int jpeg_quality = 95;
  double quantile = 0.0025;      // coefficient range from these quantiles (relight: 0.25%)
  size_t basis_pixels = 1 << 16; // pixels (a seeded sample) for the components and the ranges
  uint64_t seed = 1;
  PcaMaskMode mask = PcaMaskMode::kHinge;
  LdrMaskThresholds thresholds;
  // With a mask, the components too can be fitted around censored samples: clipped (black)
  // samples of the sampled pixels replaced by the larger (smaller) of their value and the
  // components' prediction, and the components computed again, this many times. It recovers
  // what lies beyond the clipping (a dimmer relit lamp shows it) but spends components on
  // what no photograph shows: on the shared icon it costs 0.1 dB (1) and 0.8 dB (2) of
  // leave-one-out PSNR against the (clipped) photographs, so it is off by default.
  int impute_iterations = 0;
  int threads = 2;
};

// The light dependence of the mean and of each component, per colour, on the grid, as it is
// stored (the integers of relight's "basis" array and the per-component "range").
struct PcaBasis {
  int components = 0, resolution = 0;
  // relight's "rbf" type (read, not fitted here): the light dependence held at each of these
  // lights, interpolated by normalised Gaussians of width `sigma` (Rti::lightWeightsRbf); a
  // node is then a light. Empty: the octahedral grid of `resolution`² nodes.
  std::vector<Vec3> rbf_lights;
  double sigma = 0;
  std::vector<int> stored;     // ((p * nodes + node) * 3 + c), p = 0 the mean (0..255), node x + y·R
  std::vector<double> range;   // per component p = 1..k: stored = 127 + range · e
  std::vector<double> values;  // `stored` decoded: the mean in 0..255, components e
  GridPrior prior = GridPrior::kBending;
  double smoothness = 0;        // the strength used
  double light_loo_rms = 0;     // the grid fit's leave-one-out error over lights (0..255 units)
  std::vector<double> eigenvalues;  // of the k components (variance, 0..255 units²)

  bool rbf() const { return !rbf_lights.empty(); }
  int nodes() const { return rbf() ? static_cast<int>(rbf_lights.size()) : resolution * resolution; }
  // The (k + 1) × 3 values at a direction: [p * 3 + c], as relight reads them (bilinear on
  // the grid, or the rbf weights of the lights).
  void Evaluate(const Vec3& direction, double* out) const;
};

// Relight's quantisation of a plane: byte = (c − min)/(max − min)·255, c = byte·scale + min.
struct PlaneQuantisation {
  double min = 0, max = 1;
  double scale() const { return (max - min) / 255.0; }
  double bias() const { return max > min ? -min / (max - min) : 0; }  // as relight writes it
};

struct PcaFitStats {
  size_t masked_samples = 0;   // sample-channels at or beyond the LDR thresholds
  size_t refitted_pixels = 0;  // pixels whose coefficients were solved around masked samples
  double time_s = 0;
};

// What relight's web format folders this build reads, as messages list them.
inline constexpr const char* kRelightTypesRead =
    "ptm rgb/lrgb, hsh rgb, sh rgb, bilinear and rbf mrgb, ybilinear and yrbf (mycc) folders";

// How the coefficient planes are stored: YCbCr 4:4:4, as relight's builder writes every
// plane file (mrgb included) and as every version of its reader decodes them (some force the
// YCbCr interpretation whatever the file's markers say), and browsers too. An RGB-space JPEG
// would keep the three planes' errors apart, but not every relight reader would read it.
inline constexpr JpegColor kPcaPlaneColor = JpegColor::kYcbcr;

// What the codes of a model fitted to radiance maps are (info.json's rig.values): reflectance
// (radiance ÷ the session's lamp radiance) through an HDR curve, lamp directions from the
// rig's angles through the session's light frame. Without it the codes are the photographs'
// own (sRGB, lamp radiance 1, directions as the capture gave them).
struct PcaHdrValues {
  HdrCodeCurve curve;
  std::array<double, 3> lamp_radiance_rgb = {1, 1, 1};
  LightFrameConfig light_frame;
};

struct PcaComponents;

class PcaModel {
 public:
  int width() const { return width_; }
  int height() const { return height_; }
  int components() const { return basis_.components; }
  const PcaBasis& basis() const { return basis_; }
  const std::vector<PlaneQuantisation>& quantisation() const { return quant_; }
  const std::vector<Vec3>& lights() const { return lights_; }
  int jpeg_quality() const { return jpeg_quality_; }
  const std::vector<cv::Mat>& planes() const { return planes_; }  // k × CV_8U
  // relight's "mycc" colour space (read, not fitted here): [ny, nc, nc] planes of luminance and
  // of the two chroma channels (YCoCg), the first 3·nc interleaved Y, Co, Cg, then Y alone;
  // {0, 0, 0}: mrgb (every plane feeds the three channels).
  const std::array<int, 3>& ycc_planes() const { return ycc_planes_; }
  bool ycc() const { return ycc_planes_[0] > 0; }
  // "bilinear", "rbf", "ybilinear" or "yrbf": relight's name of the type and colour space.
  std::string relight_type() const;
  // A near lamp's correction of the samples it was fitted to (info.json's rig.near_lamp);
  // empty: none.
  const std::string& near_lamp() const { return near_lamp_; }
  void set_near_lamp(std::string note) { near_lamp_ = std::move(note); }
  // Radiance-map reflectance (see PcaHdrValues); empty: photographs' codes.
  const std::optional<PcaHdrValues>& hdr() const { return hdr_; }
  void set_hdr(PcaHdrValues values) { hdr_ = std::move(values); }

  // Predicted values at a direction, CV_32FC3 in B, G, R order, in encoded units (code / 255,
  // not clipped). Uses the coefficients exactly as held (after Load: as the files hold them).
  cv::Mat Render(const Vec3& direction) const;

  // A relight web-format folder: info.json (type "bilinear", colorspace "mrgb") and
  // plane_N.jpg (three components per file, RGB colour space, no subsampling). The folder is
  // created; files in it are replaced.
  Status Save(const std::string& folder) const;
  static Result<PcaModel> Load(const std::string& folder);
  // The model exactly as Load would read back the folder Save writes, without the disk: the
  // planes JPEG-encoded and decoded in memory (EncodeJpeg: the bytes WriteJpeg writes),
  // info.json's text parsed back. *bytes (may be null): the folder's size, info.json and planes.
  Result<PcaModel> AsStored(uint64_t* bytes) const;
  void set_jpeg_quality(int quality) { jpeg_quality_ = quality; }

 private:
  // info.json's fields (no planes yet); errors name `path`.
  static Result<PcaModel> FromInfo(const nlohmann::json& info, const std::string& path);
  // The next (up to) three planes from one plane file's decoded R, G, B.
  Status AddPlaneFile(const cv::Mat& rgb, const std::string& plane);
  cv::Mat PlaneFile(int j) const;  // plane file j as Save encodes it (R, G, B = planes 3j..)
  friend Result<PcaModel> FitPcaCoefficients(const LightSamples&, PcaBasis, const PcaOptions&,
                                             const std::vector<size_t>&, PcaFitStats*);
  int width_ = 0, height_ = 0;
  int jpeg_quality_ = 95;
  PcaBasis basis_;
  std::array<int, 3> ycc_planes_ = {0, 0, 0};
  std::vector<PlaneQuantisation> quant_;
  std::vector<cv::Mat> planes_;  // k × CV_8U, the quantised coefficients
  std::vector<Vec3> lights_;     // the fitted lights (written as relight does)
  std::string near_lamp_;
  std::optional<PcaHdrValues> hdr_;
};

// The principal components of a capture's samples over a seeded sample of pixels, with the
// mean and covariance kept, so that the components without some lights (a fold) are exact
// and cost one small eigen-decomposition.
struct PcaComponents {
  std::vector<Vec3> lights;
  Eigen::VectorXd mean;            // 3 × lights, 0..255 units
  Eigen::MatrixXd covariance;      // (3 × lights)²
  Eigen::MatrixXd vectors;         // 3 × lights by count, by decreasing variance
  std::vector<double> eigenvalues;
  std::vector<size_t> subset;      // the sampled pixels
};
Result<PcaComponents> ComputePcaComponents(const LightSamples& samples, const PcaOptions& options,
                                           int count);
// The same from the sampled pixels alone (what a streamed fit gathers): `sampled` holds the
// samples of the `subset` pixels in that order (any width × height of subset.size() pixels).
// On the pixels ComputePcaComponents samples, the result is the same to the last bit.
Result<PcaComponents> ComputePcaComponentsOfSample(const LightSamples& sampled,
                                                   std::vector<size_t> subset, int count,
                                                   const PcaOptions& options);
// The pixels ComputePcaComponents samples (options.basis_pixels, options.seed): one per
// stride at a seeded offset within it, increasing; all of them when wanted >= pixels.
std::vector<size_t> SamplePixels(size_t pixels, size_t wanted, uint64_t seed);
// Exactly the components of the same pixels without the `dropped` lights.
PcaComponents PcaComponentsWithout(const PcaComponents& full, const std::vector<int>& dropped,
                                   int count);

// The model: components (computed, or given and matching the samples' lights), the grid,
// every pixel's coefficients, quantised.
Result<PcaModel> FitPca(const LightSamples& samples, const PcaOptions& options,
                        PcaFitStats* stats = nullptr);
Result<PcaModel> FitPcaWith(const LightSamples& samples, const PcaComponents& components,
                            const PcaOptions& options, PcaFitStats* stats = nullptr);
// The two halves of FitPcaWith. The basis: the first k components' and the mean's light
// dependence fitted onto a res × res grid (smoothness < 0: chosen by leave-one-out over the
// lights) and quantised as stored. The coefficients: every pixel's, through that basis,
// masked samples fitted around, ranges from the `subset` pixels, quantised.
Result<PcaBasis> FitPcaBasis(const PcaComponents& components, int k, int res, double smoothness);
Result<PcaModel> FitPcaCoefficients(const LightSamples& samples, PcaBasis basis,
                                    const PcaOptions& options, const std::vector<size_t>& subset,
                                    PcaFitStats* stats = nullptr);
// The pieces of FitPcaCoefficients, for callers that hold a band of pixels at a time and want
// the same bytes. The solver: coefficients of contiguous pixels (`count` pixels' samples laid
// out as LightSamples::values) through the basis at `directions`, masked samples fitted
// around; *out is k × count; *masked and *refitted are added to (sample-channels at or beyond
// the thresholds, pixels solved around them). Solve is const: any number of threads at once.
class PcaCoefficientSolver {
 public:
  PcaCoefficientSolver(const PcaBasis& basis, const std::vector<Vec3>& directions,
                       const PcaOptions& options);
  int components() const { return k_; }
  void Solve(const uint8_t* values, size_t count, Eigen::MatrixXf* out, size_t* masked,
             size_t* refitted) const;

 private:
  int dim_ = 0, k_ = 0;
  PcaMaskMode mode_ = PcaMaskMode::kHinge;
  LdrMaskThresholds thresholds_;
  Eigen::MatrixXd a_, ata_;
  Eigen::MatrixXf proj_, af_;
  Eigen::VectorXf muf_;
};
// The blocks of pixels [first, first + second) FitPcaCoefficients solves together for this
// many pixels and threads. A pixel's float coefficients can differ in the last bit with its
// place in its block (the matrix product's kernels), so the same bytes need the same blocks.
std::vector<std::pair<size_t, size_t>> PcaCoefficientBlocks(size_t pixels, int threads);
// Each plane's range from the coefficients of the sampled pixels (rows: pixels in `subset`
// order, columns: components), at this quantile — as FitPcaCoefficients sets them.
std::vector<PlaneQuantisation> PcaQuantisation(const Eigen::MatrixXf& sampled, double quantile);
// Row p of coefficients (k × n) quantised as stored: n bytes to `out`.
void QuantisePcaPlane(const Eigen::MatrixXf& coefficients, int p, const PlaneQuantisation& q,
                      uint8_t* out);
// info.json alone, exactly as PcaModel::Save writes it beside the planes (replaced through a
// temporary name), for writers that produce the planes themselves; the folder must exist.
// `near_lamp` (non-empty): how the samples were corrected for a near lamp, written in the
// "rig" block; `hdr`: what the codes are, in the "rig" block's "values"; `ycc`: mycc's
// yccplanes (PcaModel::ycc_planes), else mrgb.
Status WritePcaInfo(const std::string& folder, int width, int height, const PcaBasis& basis,
                    const std::vector<PlaneQuantisation>& quantisation,
                    const std::vector<Vec3>& lights, int jpeg_quality,
                    const std::string& near_lamp = "",
                    const std::optional<PcaHdrValues>& hdr = std::nullopt,
                    const std::array<int, 3>& ycc = {0, 0, 0});

// The same basis with only its first k components (exact: each is quantised on its own).
PcaBasis TruncatePcaBasis(const PcaBasis& basis, int k);

// Bytes of every regular file in a folder (a model's size on disk).
uint64_t FolderBytes(const std::string& folder);

// The PCA family (a relight web-format folder) behind ReflectanceModel; lamp directions as the
// capture gave them.
std::unique_ptr<ReflectanceModel> WrapPca(PcaModel model);

}  // namespace rig
