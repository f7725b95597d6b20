// Next-best-light: which lights of a dense capture to take, one after another, each chosen
// from the images of the lights already taken (never from an image not yet chosen: only the
// candidates' directions are known), so that a capture can stop at N lights. docs/lights.md
// "Choosing the lights".
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "config/result.h"
#include "process/model/light_direction.h"
#include "process/model/lp.h"

namespace rig {

enum class LightCriterion {
  kErrorReduction,  // the light whose taking removes the most predicted error over all untaken
  kLargestError,    // the light of largest predicted error itself
};

struct LightChoiceOptions {
  int count = 24;  // N lights to choose (the seed included)
  int seed = 8;    // the first lights, spread by farthest point on the sphere (min(seed, N))
  // The working copy: images shrunk (area averaging) by the smallest integer factor that
  // brings them to at most this many pixels, then at most `pixels` of them (a fixed stride)
  // enter the per-pixel model. The choice reads no more than that.
  int max_working_pixels = 1 << 16;
  int pixels = 1 << 14;
  // Ridge of the per-pixel kernel interpolation (relative to the kernel's diagonal of 1).
  double ridge = 1e-3;
  LightCriterion criterion = LightCriterion::kErrorReduction;
};

// The seed's size: min(count, max(seed, 6)) — the per-pixel model's trend has 4 terms, and its
// leave-one-out needs a few lights beyond them.
int LightChoiceSeedCount(const LightChoiceOptions& options);

struct LightChoiceStep {
  int light = 0;             // index into the candidates
  bool seed = false;
  double gap_deg = 0;        // angle to the nearest light chosen before it
  double predicted_rms = 0;  // the predicted 8-bit RMS error at it when chosen (0 for seeds)
  // When it was chosen: the predicted 8-bit RMS error over every light not yet chosen (it
  // included), by the model of the lights before it (-1 for seeds: no model yet).
  double remaining_rms = -1;
  std::string reason;
};

struct LightChoice {
  std::vector<LightChoiceStep> steps;  // in the order chosen
  int working_width = 0, working_height = 0, downsample = 1;
  std::vector<int> images_read;        // candidate indices, in the order they were read
  std::vector<int> Chosen() const;
};

// Returns a candidate's image, 8-bit BGR (CV_8UC3), at the working size. Called once per
// chosen light, after the light is chosen.
using LightImageReader = std::function<Result<cv::Mat>(int light)>;

// The spread seed, and the even spread used as the baseline: the light nearest the zenith
// (highest z), then repeatedly the light farthest (in angle) from every light taken; ties to
// the lowest index. Deterministic.
std::vector<int> FarthestPointLights(const std::vector<Vec3>& directions, int count);

// The sequential choice among `directions` (unit vectors). After the seed, a per-pixel model
// of the chosen lights predicts the 8-bit MSE at every candidate c:
//   predicted(c) = g(c) · d(c)²,
// d(c) the angle to the nearest chosen light, g(c) the kernel-weighted mean over chosen
// lights l of e_l / d_l², where e_l is the exact leave-one-out MSE at l (over the working
// pixels and channels, the prediction clipped to 0..255) of a per-pixel Gaussian-kernel
// interpolation with a linear trend (what a matte surface is) and d_l the gap at l. The next
// light is the one of largest score (options.criterion).
Result<LightChoice> ChooseLights(const std::vector<Vec3>& directions,
                                 const LightImageReader& read, const LightChoiceOptions& options);

// The same on an .lp capture: images read, one at a time as chosen, through LoadRtiImages
// at the working size.
Result<LightChoice> ChooseLpLights(const std::vector<LpEntry>& entries,
                                   const LightChoiceOptions& options);

// Markdown: the options, then one row per chosen light in order (image, direction, why).
std::string LightChoiceMarkdown(const std::vector<LpEntry>& entries, const LightChoice& choice,
                                const LightChoiceOptions& options);

}  // namespace rig
