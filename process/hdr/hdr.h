// HDR radiance maps from exposure brackets: Debevec-Malik response recovery and weighted merge.
//
// The response g maps a pixel level z to ln(exposure) = ln(E * t) per channel (B, G, R);
// it is known up to one constant per channel, fixed by the anchor g(mid) = 0, so radiance is
// relative (a pixel at the middle level after 1 s has radiance 1). Weights are the hat
// w(z) = z - z_min for z <= mid, z_max - z above, zero at both ends: a level that says nothing
// about exposure (black or clipped) never contributes.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/config.h"
#include "config/result.h"
#include "process/io/exr_io.h"
#include "process/io/image_io.h"

namespace rig {

// Debevec-Malik g: ln(exposure) for each pixel level, per channel.
struct ResponseCurve {
  int levels = 256;                                  // 256 (8-bit) or 65536 (16-bit)
  std::array<std::vector<double>, 3> log_exposure;   // [channel B,G,R][level]
  bool linear = false;                               // linear input: g(z) = ln(z / mid)
  std::string id;                                    // stable content hash (EXR headers)
};

struct ResponseOptions {
  double lambda = 10;   // smoothness weight (relative to the data term; see docs/hdr.md)
  int samples = 1000;   // pixel locations in total over all brackets
  uint64_t seed = 1;    // sample selection is deterministic for a seed
  int threads = 2;
  // For comparison only (docs/hdr.md): take samples on a plain regular grid, as OpenCV's
  // CalibrateDebevec does, instead of choosing them.
  bool grid_sampling = false;
};

// Recovers g per channel jointly from several brackets of the same camera (same settings).
// Frames of all brackets must share one type (8- or 16-bit; 16-bit is recovered on 256 bins
// and interpolated). Errors: empty input, invalid brackets (see ValidateBracket), too few
// usable sample pixels.
Result<ResponseCurve> RecoverResponse(std::span<const Bracket> brackets,
                                      const ResponseOptions& o);

// The response of linear data: g(z) = ln(z / mid) (g(0) is clamped; its weight is 0).
ResponseCurve LinearResponse(int levels = 256);

// The content hash of a curve: "g-<16 hex>" over levels, the linear flag and every value;
// "linear-<levels>" for LinearResponse. RecoverResponse and LoadResponse set `id` with it.
std::string ResponseId(const ResponseCurve& c);

// A CSV text file ('#' header lines: levels, linear, id; then "level,B,G,R"), atomically.
Status SaveResponse(const ResponseCurve& c, const std::string& path);
// Reads SaveResponse's format; a curve whose values do not match its id is kCorrupt.
Result<ResponseCurve> LoadResponse(const std::string& path);

// Checks a bracket before merging or recovery: at least two frames, one size, one type
// (CV_8UC3 or CV_16UC3), positive exposures strictly increasing in order. Errors name the
// offending file (and the other file it disagrees with).
Status ValidateBracket(std::span<const LdrFrame> frames);

struct RadianceMap {
  cv::Mat radiance;   // CV_32FC3 BGR, relative radiance (units of the response anchor g(mid)=0)
  // CV_8UC1 per pixel: 0 ok; 1 some channel saturated in every exposure (that channel holds
  // the lower bound exp(g(z_sat) - ln t_shortest)); 2 some channel black in every exposure
  // (that channel holds 0). 1 wins when a pixel has both.
  cv::Mat flags;
  int saturated_pixels = 0, black_pixels = 0;
  std::map<std::string, std::string> attributes;  // exposures_s, response_id, ... (EXR header)
};

enum RadianceFlag : uint8_t { kFlagOk = 0, kFlagSaturated = 1, kFlagBlack = 2 };

// How the frames of a bracket are weighted in the merge (the weight is always zero at and
// beyond the black and saturation levels).
enum class MergeWeighting {
  kHat,     // Debevec-Malik's hat w(z): symmetric, treats dark and bright levels alike
  kPhoton,  // hat(z) * exp(g(z)): inverse variance under photon (shot) noise, where a frame's
            // relative noise falls as 1/sqrt(exposure): longer exposures count more
  kNoise,   // inverse variance under a noise model fitted to the bracket itself (FitNoise):
            // quantisation through the slope of g, shot and read noise; kPhoton when the
            // bracket holds too few pixels recorded by two neighbouring frames to fit it
};

// Variance of one frame's estimate of ln E at level z, per channel:
//   v(z) = quant * g'(z)^2 + shot * exp(-G) + read * exp(-2 G),   G = g(z) - g(mid),
// the three terms of quantisation (g' per level), shot noise and read noise. Fitted by
// non-negative least squares to the squared differences of neighbouring frames' estimates
// of the same pixel (each difference has variance v(z_j) + v(z_j+1)).
struct NoiseModel {
  std::array<double, 3> quant{}, shot{}, read{};  // per channel B, G, R
  std::array<int64_t, 3> pairs{};                 // pixel pairs the fit used
  bool ok = false;
  double Variance(const ResponseCurve& r, int c, int z) const;
};
// "hat" | "photon" | "noise".
Result<MergeWeighting> ParseMergeWeighting(const std::string& name);
const char* MergeWeightingName(MergeWeighting w);

NoiseModel FitNoise(std::span<const LdrFrame> frames, const ResponseCurve& response,
                    std::array<int, 3> black_level, std::array<int, 3> saturation_level);

struct MergeOptions {
  int threads = 2;
  MergeWeighting weighting = MergeWeighting::kNoise;
  // Per channel (B, G, R) levels at or below which a sample counts as black, and at or above
  // which it counts as saturated; -1: the ends of the range (0 and levels-1). The hat weight
  // is zero at and beyond both.
  std::array<int, 3> black_level = {-1, -1, -1};
  std::array<int, 3> saturation_level = {-1, -1, -1};
  // A bracket too short to cover the scene: more than this fraction of the pixels saturated
  // in every exposure (or black in every one) is an error naming the shortest (longest) frame.
  // 1 disables the check.
  double max_unrecorded_fraction = 0.5;
};

// Weighted merge of one bracket through a response: ln E = sum w(z)(g(z) - ln t) / sum w(z)
// per channel. Frame types must match the response's levels (8-bit: 256, 16-bit: 65536).
Result<RadianceMap> MergeBracket(std::span<const LdrFrame> frames, const ResponseCurve& response,
                                 const MergeOptions& o);

// Writes R, G, B and a "flags" channel, with the map's attributes in the header.
Status WriteRadianceMap(const std::string& path, const RadianceMap& map, ExrPixelType type,
                        int threads, ExrCompression compression = ExrCompression::kZip);

// Parses "half" | "float".
Result<ExrPixelType> ParseExrPixelType(const std::string& name);

}  // namespace rig
