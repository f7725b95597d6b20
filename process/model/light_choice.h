// Next-best-light: which lights of a dense capture to take, one after another, each chosen
// from the images of the lights already taken (never from an image not yet chosen: only the
// candidates' directions are known), so that a capture can stop at N lights. docs/lights.md
// "Choosing the lights".
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Dense>
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
  // What taking a candidate costs (seconds: a rig's motion from the light taken last and its
  // bracket), or null: every light costs the same. With it, the model's choice is the
  // largest score per second. Seeds are not weighed.
  std::function<double(int last, int candidate)> cost_s;
  // Where the error counts: directions covering the region a model of the capture will be
  // relit in (a rig's span sampled finer than its grid), or empty: the candidates not chosen
  // (a dense capture: its other lights). The model's choice removes the most predicted error
  // summed over them.
  std::vector<Vec3> region;
  // Stop early (LightChooser::Propose, 0: never; the count alone stops): when the predicted
  // RMS error over the region is within this fraction (plus kChoiceNoiseCodes) of what taking
  // every candidate would leave, by the same per-pixel model.
  double target = 0;
  // The candidates' names in reasons (a rig's pose names), or empty: "light N" (1-based).
  std::vector<std::string> names;
};

// The absolute slack of the stop at the target, 8-bit codes: below a JPEG's quantisation, an
// error no photograph of the capture can show.
inline constexpr double kChoiceNoiseCodes = 0.5;

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
  // When it was chosen, by the same model: the predicted RMS error over the region
  // (options.region, else the lights not chosen), and what it would be with every candidate
  // taken (-1 for seeds).
  double region_rms = -1, floor_rms = -1;
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

// The choice one light at a time, for a capture that takes each light as it is chosen (the
// rig's adaptive grid): Propose() says which light is next and why; the caller takes it (or
// another, e.g. one a journal already chose) and hands its image to Take(). Deterministic:
// the same images give the same proposals.
class LightChooser {
 public:
  LightChooser(std::vector<Vec3> directions, LightChoiceOptions options);

  struct Proposal {
    bool stop = false;        // nothing more to take: `stop_reason` says why
    std::string stop_reason;
    LightChoiceStep step;     // the light to take next, when !stop
  };
  // The next light: the seed's next (farthest point), then the model's choice; stops at
  // options.count lights, when every light is taken, or at options.target.
  Result<Proposal> Propose() const;
  // Takes `light` (any light not taken yet) with its image (8-bit colour, CV_8UC3, the
  // working size: the first image's size; every later one must match). `step` is recorded
  // as the reason (Propose's, or the caller's own).
  Status Take(int light, const cv::Mat& image, LightChoiceStep step);

  const LightChoice& choice() const { return choice_; }
  int taken() const { return static_cast<int>(chosen_.size()); }
  const std::vector<Vec3>& directions() const { return dirs_; }

 private:
  std::vector<Vec3> dirs_;
  LightChoiceOptions options_;
  std::vector<int> seed_;
  std::vector<int> chosen_;
  std::vector<int> pixels_;
  Eigen::MatrixXd values_;
  LightChoice choice_;
};

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
