// Tone mapping of radiance maps for a screen: Ward Larson, Rushmeier & Piatko 1997 histogram
// adjustment with the linear ceiling (the paper's §4.2), a linear/clipped mapping, and three
// of OpenCV's operators (Reinhard, Drago, Mantiuk) for comparison. See docs/render.md.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/render/radiance_file.h"

namespace rig {

enum class ToneMapMethod { kWard, kLinear, kReinhard, kDrago, kMantiuk };

// Ward's histogram adjustment as Radiance's pcond computes it (the default), or as the 1997
// paper describes it. See docs/render.md, "Ward's curve", for every difference.
//   kPcond: the picture's view (or the field of view on the larger image side, 2·tan(fov/2) /
//           1° samples across it); single pixels added to the foveal samples (pcond: 16 random
//           per foveal sample; ours by default 256 stratified, see WardSampling), together
//           weighted as much as the foveal samples; the range padded (max × 1.01, one extra bin below the minimum, half of
//           bin 1 moved into it); the stop test against the current total; the cumulative
//           from before the last trim; the linear fallback at the mean log of all samples.
//   kPaper: 1° foveal samples only, horizontal field of view, the exact sample range, the
//           stop test against the original total, the cumulative after the last trim.
enum class WardVariant { kPcond, kPaper };
const char* WardVariantName(WardVariant variant);  // "pcond", "paper"
Result<WardVariant> ParseWardVariant(const std::string& name);

struct WardMapping;

// What becomes of a colour the display cannot show (a channel under 0 or over 1 once tone
// mapped and converted to the display's primaries):
//   kDesaturate: as Radiance's clipgamut, which pcond applies after its colour conversion:
//                black when its luminance is under 0, white when over 1, else moved towards
//                the grey of the same luminance just far enough that every channel is in
//                [0, 1] (hue and luminance kept, saturation given up);
//   kClip:       every channel clipped on its own (hue and luminance may shift).
enum class GamutMapping { kDesaturate, kClip };
const char* GamutMappingName(GamutMapping g);  // "desaturate", "clip"
Result<GamutMapping> ParseGamutMapping(const std::string& name);

// The random single pixels Ward's pcond variant adds to its histogram:
//   kStratified: one pixel drawn uniformly inside each cell of a grid of
//                (points per foveal sample) cells per foveal sample, the grid k × k with
//                k = round(sqrt(points)) (4 × 4 for 16): the same count as pcond, spread
//                evenly, so the curve moves less from seed to seed than pcond's own;
//   kRandom:     distinct pixels anywhere (Floyd's algorithm), as pcond draws them.
enum class WardSampling { kStratified, kRandom };
const char* WardSamplingName(WardSampling s);  // "stratified", "random"
Result<WardSampling> ParseWardSampling(const std::string& name);

// "ward", "linear", "reinhard", "drago", "mantiuk".
const char* ToneMapMethodName(ToneMapMethod method);
Result<ToneMapMethod> ParseToneMapMethod(const std::string& name);

struct ToneMapOptions {
  ToneMapMethod method = ToneMapMethod::kWard;
  double field_of_view_deg = 40;    // horizontal; sets the ~1° foveal sample size
  double display_min_cd_m2 = 1, display_max_cd_m2 = 100;
  double ceiling_tolerance = 0.025; // stop trimming when what is trimmed falls under this fraction of T
  int bins = 100;
  double gamma = 2.2;               // display encoding: pixel = value^(1/gamma) ...
  bool srgb = false;                // ... or the sRGB transfer curve when true
  // Linear method: pixel = radiance * linear_scale before encoding, clipped at 1. 0: automatic,
  // the `linear_percentile` of pixel luminance maps to white.
  double linear_scale = 0;
  double linear_percentile = 99;
  WardVariant ward_variant = WardVariant::kPcond;
  // kPcond: the seed of the single-pixel samples (std::mt19937_64; pcond itself draws with its
  // own random(), so its pixels differ from ours), how many per foveal sample (pcond: 16; 256
  // here, the default, makes the curve nearly independent of the seed) and how they are drawn.
  uint64_t ward_seed = 1;
  int ward_point_samples_per_foveal = 256;
  WardSampling ward_sampling = WardSampling::kStratified;
  // kPcond: the image-plane extents of the picture's view (ViewExtent of its VIEW= line), the
  // foveal samples across each side being extent / 1° (in radians) + 0.5. {0, 0}: pcond's
  // default, a perspective view of field_of_view_deg across the larger side (stretched by
  // pixel_aspect, height over width of a pixel, as Radiance's PIXASPECT).
  std::array<double, 2> view_extent{0, 0};
  double pixel_aspect = 1;
  // The primaries of the radiance's RGB and of the display's. Luminance is weighed with the
  // Y row of RgbToXyzWhiteBalanced(picture_primaries) (Rec. 709: 0.2126, 0.7152, 0.0722;
  // Radiance's: 0.265, 0.670, 0.065); when they differ from the display's, the tone-mapped
  // pixels are converted (RgbToRgbWhiteBalanced) before `gamut` applies.
  Chromaticities picture_primaries = Rec709Primaries();
  Chromaticities display_primaries = Rec709Primaries();
  GamutMapping gamut = GamutMapping::kDesaturate;
  // kWard: when set, this mapping is applied as it is instead of one computed from the image
  // (a fixed display: comparisons, lamp intensity, sweeps).
  std::shared_ptr<const WardMapping> ward_fixed;
};

// The default options with a configuration's display: [process] field_of_view_deg,
// display_min_cd_m2, display_max_cd_m2.
ToneMapOptions ToneMapOptionsFor(const ProcessConfig& process);

// What a picture's header changes, as pcond takes it: the picture's primaries, its pixel
// aspect, and its view's extent unless the view is missing, parallel (-vtl) or under 5° on
// a side (then pcond's default view stands). An illegal view size is an error.
Status ApplyPictureHeader(const PictureHeader& header, ToneMapOptions* o);

// The luminance weights of the options' picture primaries, in OpenCV's B, G, R order.
cv::Vec3f LuminanceWeightsBgr(const ToneMapOptions& o);

struct ToneMapReport {
  bool linear_fallback = false;  // Ward: a linear mapping was used (the range fits the display,
                                 // or trimming emptied the histogram)
  int trim_iterations = 0;       // Ward: passes of the ceiling procedure
  double scene_log_range = 0;    // ln(max / min) of the foveal samples (Ward), else of the pixels
  int foveal_width = 0, foveal_height = 0;  // Ward: size of the foveal sample image
  int point_samples = 0;         // Ward (pcond): random single pixels added to the histogram
  double linear_scale = 0;       // the scale used by a linear mapping (Ward fallback or kLinear)
  double clipped_low_fraction = 0, clipped_high_fraction = 0;  // pixels at 0 / at 255 (any channel)
};

// radiance: CV_32FC3 BGR linear (any scale). Returns CV_8UC3 BGR for a screen (display gamma
// or sRGB applied). Errors: empty image, wrong type, bad options (kInvalidInput), OpenCV
// failures (kInternal). Uses cv::parallel_for_ over rows.
Result<cv::Mat> ToneMap(const cv::Mat& radiance, const ToneMapOptions& o,
                        ToneMapReport* report = nullptr);

// The same up to the display encoding: CV_32FC3 BGR linear pixel values ("before gamma"),
// nominally in [0, 1]; values above 1 are clipped only by the encoding. For kWard and kLinear
// every pixel's RGB is its radiance times one factor (colour ratios kept).
Result<cv::Mat> ToneMapLinearPixels(const cv::Mat& radiance, const ToneMapOptions& o,
                                    ToneMapReport* report = nullptr);

// Encodes linear pixel values (CV_32FC3, clipped to [0, 1]) to CV_8UC3 with the options' gamma
// or sRGB curve, through a lookup table; fills the clipped fractions of `report` if given.
cv::Mat EncodeForDisplay(const cv::Mat& linear_pixels, const ToneMapOptions& o,
                         ToneMapReport* report = nullptr);

// Horizontal field of view of a lens on a sensor: 2·atan(sensor_width / (2·focal_length)).
double FieldOfViewDeg(double focal_length_mm, double sensor_width_mm);

// Rec. 709 luminance of a CV_32FC3 BGR image, CV_32FC1; or with other weights (B, G, R).
cv::Mat Luminance(const cv::Mat& bgr);
cv::Mat Luminance(const cv::Mat& bgr, const cv::Vec3f& weights_bgr);

// Ward's foveal samples: the luminance averaged (linearly, as the eye integrates light) over
// blocks of about 1° of visual angle. kPaper: field_of_view_deg samples across the width;
// kPcond: 2·tan(fov/2)/(1° in radians) + 0.5 (truncated) across the larger side, the other
// side in proportion. At least 2 samples each way, never more than the image has. CV_32FC1.
cv::Mat FovealLuminance(const cv::Mat& luminance, double field_of_view_deg,
                        WardVariant variant = WardVariant::kPaper);
cv::Size FovealSampleSize(int cols, int rows, double field_of_view_deg, WardVariant variant);
// The foveal grid of the options (kPcond: from view_extent or the default view).
cv::Size FovealSampleSize(int cols, int rows, const ToneMapOptions& o);

// pcond's random single-pixel samples: `count` distinct pixel indices of an image of `pixels`
// pixels (every pixel when count >= pixels), drawn by Floyd's algorithm from
// std::mt19937_64(seed): for j = pixels − count … pixels − 1, t = gen() % (j + 1); t is taken
// unless already chosen, then j is. In draw order.
std::vector<int64_t> RandomPixelIndices(int64_t pixels, int64_t count, uint64_t seed);
// kStratified: one pixel index (y · cols + x) per cell of a cells.width × cells.height grid
// over the image (cell edges at i · cols / cells.width), uniform inside the cell, from
// std::mt19937_64(seed); row by row. Cells wider than the image are clamped to its size.
std::vector<int64_t> StratifiedPixelIndices(int cols, int rows, cv::Size cells, uint64_t seed);

// Converts tone-mapped linear display pixels (CV_32FC3 BGR) in place: through `to_display`
// (a 3 × 3 matrix on R, G, B; identity skips it), then the gamut mapping against [0, 1] with
// the display's luminance weights (B, G, R) for kDesaturate.
void MapToDisplayGamut(cv::Mat* pixels, const cv::Matx33d& to_display,
                       const cv::Vec3f& display_weights_bgr, GamutMapping gamut);

// ---- Ward's histogram adjustment, exposed for tests -------------------------------------
// All logarithms are natural: b = ln(L_w), B_d = ln(L_d).

struct WardHistogram {
  double log_min = 0, log_max = 0;  // range of b over the samples (kPcond: padded)
  double bin_width = 0;             // Δb = (log_max - log_min) / bins
  std::vector<double> counts;       // f(b_i), bin i covers [log_min + iΔb, log_min + (i+1)Δb)
  double original_total = 0;        // T before any trimming
  double mean_log = 0;              // the (weighted) mean of b over the samples
  double Total() const;             // T = Σ f(b_i) now
  int bins() const { return static_cast<int>(counts.size()); }
};

// Histogram of ln(L) over the samples that are positive and finite (others are ignored).
// An empty or one-valued sample set gives log_min == log_max and all counts in bin 0.
WardHistogram BuildLogHistogram(const std::vector<float>& luminance_samples, int bins);

// pcond's histogram (comphist): foveal samples weight 1, the point samples together as much
// as the foveal ones; range [ln L_max·1.01 − (ln(1.01·L_max) − ln L_min)·bins/(bins−1),
// ln(1.01·L_max)] over both sets; then half of bin 1 is moved into bin 0. Non-positive and
// non-finite samples are ignored (pcond has absolute limits 1e-7 … 1e5 cd/m²; our radiance
// is relative, so none are applied).
WardHistogram BuildPcondHistogram(const std::vector<float>& foveal_samples,
                                  const std::vector<float>& point_samples, int bins);

// The linear ceiling of eq. 11 for the histogram's current total:
// T · Δb / (ln L_dmax − ln L_dmin).
double CeilingValue(const WardHistogram& h, double display_log_range);

struct CeilingOutcome {
  bool converged = false;  // false: the histogram emptied (total fell under tolerance·T)
  int iterations = 0;
  double last_trimmed = 0;  // counts removed by the last pass
};

// Ward's procedure: repeatedly clip every bin to the ceiling of the current total until a
// pass trims no more than tolerance · original_total, or the total itself falls under it.
CeilingOutcome ApplyLinearCeiling(WardHistogram* h, double display_log_range, double tolerance);

// pcond's loop (mkbrmap): the cumulative of the current histogram is taken, the loop gives
// up (not converged) when the current total is at or under tolerance · original total, every
// bin is clipped to the ceiling of the current total, and the loop repeats while a pass trims
// more than tolerance · the total it started from. *cumulative_before: the cumulative taken
// at the start of the last pass (before its trim), which is the one pcond maps with.
CeilingOutcome ApplyPcondCeiling(WardHistogram* h, double display_log_range, double tolerance,
                                 std::vector<double>* cumulative_before);

// P at the bin edges: bins + 1 values, P[0] = 0, P[bins] = 1, P[k] = Σ_{i<k} f(b_i) / T.
std::vector<double> CumulativeDistribution(const WardHistogram& h);

// The scene-to-display luminance mapping Ward's operator settled on.
struct WardMapping {
  bool linear = false;
  double linear_scale = 0;  // linear: L_d = linear_scale · L_w
  double log_min = 0, log_max = 0;
  std::vector<double> cumulative;  // CumulativeDistribution of the trimmed histogram
  double display_min_cd_m2 = 1, display_max_cd_m2 = 100;

  // B_d = ln L_dmin + (ln L_dmax − ln L_dmin) · P(b), P interpolated linearly in a bin; b
  // below/above the histogram clamps to the display's ends. Linear: ln(linear_scale · L_w).
  double DisplayLogLuminance(double world_luminance) const;
  double DisplayLuminance(double world_luminance) const;
  // Pixel luminance before gamma: histogram mapping (L_d − L_dmin) / (L_dmax − L_dmin);
  // linear mapping L_d / L_dmax (ratios kept exactly, as Radiance's pcond does). 0 for L_w ≤ 0.
  double PixelLuminance(double world_luminance) const;
};

// Builds the mapping from foveal luminance samples: histogram, linear fallback when the
// samples' log range fits the display's (then the log-average maps to the display's
// geometric middle), ceiling, cumulative. Fills the Ward fields of `report` if given.
WardMapping ComputeWardMapping(const std::vector<float>& foveal_samples,
                               const ToneMapOptions& o, ToneMapReport* report = nullptr);
// The same with pcond's point samples (used by kPcond; ignored by kPaper).
WardMapping ComputeWardMapping(const std::vector<float>& foveal_samples,
                               const std::vector<float>& point_samples, const ToneMapOptions& o,
                               ToneMapReport* report = nullptr);
// The mapping Ward's operator settles on for a whole radiance map (CV_32FC3): foveal samples,
// point samples (kPcond), histogram, ceiling. What ToneMap applies (unless ward_fixed is set).
WardMapping ComputeWardMappingForImage(const cv::Mat& radiance, const ToneMapOptions& o,
                                       ToneMapReport* report = nullptr);

}  // namespace rig
