// Next-best-light choice on a dense capture: a spread seed, then the light of largest
// predicted error of a per-pixel model of the lights chosen so far.
#include "process/model/light_choice.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>


namespace rig {
namespace {

constexpr double kDeg = 180.0 / M_PI;
constexpr double kMseFloor = 1e-4;  // codes²

double Angle(const Vec3& a, const Vec3& b) {
  const double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  return std::acos(std::clamp(d, -1.0, 1.0));
}

// Angle from `c` to the nearest of `chosen` (excluding `skip`), and which one.
double NearestAngle(const std::vector<Vec3>& dirs, const std::vector<int>& chosen, const Vec3& c,
                    int skip, int* which = nullptr) {
  double best = std::numeric_limits<double>::infinity();
  for (int l : chosen) {
    if (l == skip) continue;
    const double a = Angle(dirs[l], c);
    if (a < best) {
      best = a;
      if (which) *which = l;
    }
  }
  return best;
}

// The working pixels' values of one chosen image, B, G, R interleaved, as doubles.
Eigen::RowVectorXd WorkingRow(const cv::Mat& img, const std::vector<int>& pixels) {
  Eigen::RowVectorXd row(static_cast<Eigen::Index>(pixels.size()) * 3);
  const uint8_t* data = img.ptr<uint8_t>(0);
  for (size_t i = 0; i < pixels.size(); ++i)
    for (int c = 0; c < 3; ++c)
      row(static_cast<Eigen::Index>(i * 3 + c)) = data[static_cast<size_t>(pixels[i]) * 3 + c];
  return row;
}

// What the model of the chosen lights says: per chosen light its leave-one-out MSE e_l, its
// gap d_l and roughness g_l = e_l / d_l²; the kernel width.
struct ChosenModel {
  std::vector<double> loo_mse, gap, roughness;
  double sigma = 0;
};

// Per pixel and channel, a Gaussian-kernel interpolation (kernel exp(-θ²/2σ²) of the angle θ
// between lights, σ the median gap) with an unpenalised trend 1, lx, ly, lz. Every pixel
// shares the lights, so the bordered system's inverse is computed once; its top-left block A
// gives the exact leave-one-out residual of every pixel at light l as (A y)_l / A_ll
// (Dubrule 1983, for kriging with a trend).
ChosenModel FitChosen(const std::vector<Vec3>& dirs, const std::vector<int>& chosen,
                      const Eigen::MatrixXd& values, double ridge) {
  const int n = static_cast<int>(chosen.size());
  ChosenModel m;
  for (int i = 0; i < n; ++i) m.gap.push_back(NearestAngle(dirs, chosen, dirs[chosen[i]], chosen[i]));
  std::vector<double> sorted = m.gap;
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
  m.sigma = std::max(sorted[n / 2], 1e-3);
  Eigen::MatrixXd bordered = Eigen::MatrixXd::Zero(n + 4, n + 4);
  for (int i = 0; i < n; ++i) {
    const Vec3& a = dirs[chosen[i]];
    for (int j = 0; j < n; ++j) {
      const double t = Angle(a, dirs[chosen[j]]);
      bordered(i, j) = std::exp(-t * t / (2 * m.sigma * m.sigma)) + (i == j ? ridge : 0.0);
    }
    const double trend[4] = {1, a[0], a[1], a[2]};
    for (int k = 0; k < 4; ++k) bordered(i, n + k) = bordered(n + k, i) = trend[k];
  }
  const Eigen::MatrixXd inverse = bordered.fullPivLu().inverse();
  const Eigen::MatrixXd a = inverse.topLeftCorner(n, n);
  const Eigen::MatrixXd residual = a * values;  // n × (3 · pixels), before the division
  for (int i = 0; i < n; ++i) {
    double sum = 0;
    for (Eigen::Index j = 0; j < values.cols(); ++j) {
      // A photograph stops at 0 and 255, and so does the prediction scored against it.
      const double y = values(i, j);
      const double predicted = std::clamp(y - residual(i, j) / a(i, i), 0.0, 255.0);
      sum += (y - predicted) * (y - predicted);
    }
    m.loo_mse.push_back(sum / static_cast<double>(values.cols()));
    // A floor far below 8-bit noise: where the model has no error anywhere (a scene a
    // linear trend explains) the gaps alone decide, and the choice is an even spread.
    m.roughness.push_back(std::max(m.loo_mse.back(), kMseFloor) /
                          std::max(m.gap[i] * m.gap[i], 1e-12));
  }
  return m;
}

struct Prediction {
  double mse = 0, gap = 0, roughness = 0;
  int nearest = -1, driver = -1;  // the nearest chosen light; the one weighing most in g
};

Prediction Predict(const std::vector<Vec3>& dirs, const std::vector<int>& chosen,
                   const ChosenModel& m, const Vec3& at) {
  Prediction p;
  p.gap = NearestAngle(dirs, chosen, at, -1, &p.nearest);
  double wsum = 0, gsum = 0, wmax = -1;
  for (size_t i = 0; i < chosen.size(); ++i) {
    const double t = Angle(at, dirs[chosen[i]]);
    // Relative to the nearest, so that a candidate far from all keeps finite weights.
    const double w = std::exp(-(t * t - p.gap * p.gap) / (2 * m.sigma * m.sigma));
    wsum += w;
    gsum += w * m.roughness[i];
    if (w * m.roughness[i] > wmax) {
      wmax = w * m.roughness[i];
      p.driver = chosen[i];
    }
  }
  p.roughness = gsum / wsum;
  p.mse = p.roughness * p.gap * p.gap;
  return p;
}

struct Pick {
  int light = -1, runner_up = -1;
  double score = -1, runner_up_score = -1;
  Prediction prediction;     // at `light`
  double remaining_mse = 0;  // mean predicted MSE over the lights not chosen
  double region_mse = 0;     // mean predicted MSE over the region
  double floor_mse = 0;      // the same with every candidate taken
};

// The candidate of largest score. kLargestError: its own predicted MSE. kErrorReduction: the
// predicted MSE removed over every light not chosen (itself included) if it were taken, each
// light's gap becoming min(its gap, its angle to the candidate) with its roughness unchanged —
// so a light between unsampled neighbours is worth more than an isolated peak, and a region
// already dense gains little from one more. Ties keep the lower index.
Pick NextLight(const std::vector<Vec3>& dirs, const std::vector<int>& chosen,
               const ChosenModel& model, LightCriterion criterion,
               const std::function<double(int, int)>& cost_s, const std::vector<Vec3>& region) {
  std::vector<int> open, all;
  std::vector<Prediction> pred;
  for (int c = 0; c < static_cast<int>(dirs.size()); ++c) {
    all.push_back(c);
    if (std::find(chosen.begin(), chosen.end(), c) != chosen.end()) continue;
    open.push_back(c);
    pred.push_back(Predict(dirs, chosen, model, dirs[c]));
  }
  Pick pick;
  for (const auto& p : pred) pick.remaining_mse += p.mse / static_cast<double>(pred.size());
  // Where the error counts: the region's directions, else the lights not chosen.
  std::vector<Vec3> at;
  std::vector<Prediction> at_pred;
  if (region.empty()) {
    for (int c : open) at.push_back(dirs[c]);
    at_pred = pred;
  } else {
    at = region;
    for (const Vec3& x : region) at_pred.push_back(Predict(dirs, chosen, model, x));
  }
  for (size_t j = 0; j < at.size(); ++j) {
    const double full_gap = NearestAngle(dirs, all, at[j], -1);
    pick.region_mse += at_pred[j].mse / static_cast<double>(at.size());
    pick.floor_mse += at_pred[j].roughness * full_gap * full_gap / static_cast<double>(at.size());
  }
  for (size_t i = 0; i < open.size(); ++i) {
    double score = pred[i].mse;
    if (criterion == LightCriterion::kErrorReduction) {
      score = 0;
      for (size_t j = 0; j < at.size(); ++j) {
        const double gap = std::min(at_pred[j].gap, Angle(dirs[open[i]], at[j]));
        score += at_pred[j].roughness * (at_pred[j].gap * at_pred[j].gap - gap * gap);
      }
    }
    // Per second of the rig's time, when taking a light has a cost.
    if (cost_s) score /= std::max(1e-3, cost_s(chosen.back(), open[i]));
    if (score > pick.score) {
      pick.runner_up = pick.light;
      pick.runner_up_score = pick.score;
      pick.light = open[i];
      pick.score = score;
      pick.prediction = pred[i];
    } else if (score > pick.runner_up_score) {
      pick.runner_up = open[i];
      pick.runner_up_score = score;
    }
  }
  return pick;
}

}  // namespace

int LightChoiceSeedCount(const LightChoiceOptions& options) {
  return std::min(options.count, std::max(options.seed, 6));
}

std::vector<int> LightChoice::Chosen() const {
  std::vector<int> out;
  for (const auto& s : steps) out.push_back(s.light);
  return out;
}

std::vector<int> FarthestPointLights(const std::vector<Vec3>& directions, int count) {
  std::vector<int> chosen;
  const int n = static_cast<int>(directions.size());
  count = std::min(count, n);
  if (count <= 0) return chosen;
  int top = 0;
  for (int l = 1; l < n; ++l)
    if (directions[l][2] > directions[top][2]) top = l;
  chosen.push_back(top);
  std::vector<double> nearest(n);
  for (int l = 0; l < n; ++l) nearest[l] = Angle(directions[l], directions[top]);
  while (static_cast<int>(chosen.size()) < count) {
    int best = -1;
    for (int l = 0; l < n; ++l)
      if (nearest[l] > 0 && (best < 0 || nearest[l] > nearest[best])) best = l;
    if (best < 0) break;  // only duplicates of chosen directions are left
    chosen.push_back(best);
    for (int l = 0; l < n; ++l) nearest[l] = std::min(nearest[l], Angle(directions[l], directions[best]));
  }
  // Duplicated directions: fill up in index order (they add nothing the spread could rank).
  for (int l = 0; l < n && static_cast<int>(chosen.size()) < count; ++l)
    if (std::find(chosen.begin(), chosen.end(), l) == chosen.end()) chosen.push_back(l);
  return chosen;
}

LightChooser::LightChooser(std::vector<Vec3> directions, LightChoiceOptions options)
    : dirs_(std::move(directions)), options_(std::move(options)) {
  options_.count = std::clamp(options_.count, 1, std::max(1, static_cast<int>(dirs_.size())));
  seed_ = FarthestPointLights(dirs_, LightChoiceSeedCount(options_));
}

Result<LightChooser::Proposal> LightChooser::Propose() const {
  Proposal out;
  const int n = static_cast<int>(dirs_.size());
  if (taken() >= n) {
    out.stop = true;
    out.stop_reason = fmt::format("every one of the {} lights is taken", n);
    return out;
  }
  if (taken() >= options_.count) {
    out.stop = true;
    out.stop_reason = fmt::format("the count: {} lights taken, as many as allowed", taken());
    return out;
  }
  LightChoiceStep& step = out.step;
  // The seed, while a seed light is left untaken and the seed's size is not reached.
  if (taken() < static_cast<int>(seed_.size())) {
    for (int light : seed_) {
      if (std::find(chosen_.begin(), chosen_.end(), light) != chosen_.end()) continue;
      step.light = light;
      step.seed = true;
      step.gap_deg = chosen_.empty() ? 0 : kDeg * NearestAngle(dirs_, chosen_, dirs_[light], -1);
      step.reason = chosen_.empty()
                        ? "seed: the highest light"
                        : fmt::format("seed: the light farthest from those taken ({:.1f} deg)",
                                      step.gap_deg);
      return out;
    }
  }
  const ChosenModel model = FitChosen(dirs_, chosen_, values_, options_.ridge);
  const Pick pick = NextLight(dirs_, chosen_, model, options_.criterion, options_.cost_s,
                              options_.region);
  const Prediction& best = pick.prediction;
  step.remaining_rms = std::sqrt(pick.remaining_mse);
  step.region_rms = std::sqrt(pick.region_mse);
  step.floor_rms = std::sqrt(pick.floor_mse);
  // The stop at the target: the region's predicted error within the target of what every
  // candidate taken would leave.
  const double enough = (1 + options_.target) * step.floor_rms + kChoiceNoiseCodes;
  if (options_.target > 0 && step.region_rms <= enough) {
    out.stop = true;
    out.stop_reason = fmt::format(
        "the target: the predicted RMS error over the {} is {:.2f} codes, within {:.0f}% (+{} "
        "code) of the {:.2f} that taking all {} would leave",
        options_.region.empty() ? "lights not taken" : "region", step.region_rms,
        100 * options_.target, kChoiceNoiseCodes, step.floor_rms, n);
    return out;
  }
  const auto driver = std::find(chosen_.begin(), chosen_.end(), best.driver) - chosen_.begin();
  step.light = pick.light;
  step.gap_deg = kDeg * best.gap;
  step.predicted_rms = std::sqrt(best.mse);
  const std::string per = options_.cost_s ? " per second of the rig's time" : "";
  auto name = [&](int i) {
    return i >= 0 && i < static_cast<int>(options_.names.size()) ? options_.names[i]
                                                                 : fmt::format("light {}", i + 1);
  };
  const std::string over = options_.region.empty() ? "the lights not chosen" : "the region";
  const std::string why =
      options_.criterion == LightCriterion::kLargestError
          ? fmt::format("largest predicted error{} (next: {} at {:.1f})", per,
                        name(pick.runner_up), std::sqrt(std::max(0.0, pick.runner_up_score)))
          : fmt::format("largest predicted reduction of the error summed over {}{}, {:.0f} "
                        "codes² (next: {} at {:.0f})",
                        over, per, pick.score, name(pick.runner_up), pick.runner_up_score);
  step.reason = fmt::format(
      "{}; its own predicted RMS {:.1f} codes = gap {:.1f} deg (to {}) x local roughness "
      "{:.2f} codes/deg, mostly from {} (leave-one-out RMS {:.1f} codes at a gap of {:.1f} deg)",
      why, step.predicted_rms, step.gap_deg, name(best.nearest), std::sqrt(best.roughness) / kDeg,
      name(best.driver), std::sqrt(model.loo_mse[driver]), kDeg * model.gap[driver]);
  return out;
}

Status LightChooser::Take(int light, const cv::Mat& img, LightChoiceStep step) {
  if (light < 0 || light >= static_cast<int>(dirs_.size()) ||
      std::find(chosen_.begin(), chosen_.end(), light) != chosen_.end()) {
    return MakeError(ErrorCode::kInvalidInput, fmt::format("light {}", light),
                     "not a light of the {} or already taken", dirs_.size());
  }
  choice_.images_read.push_back(light);
  if (img.type() != CV_8UC3 || !img.isContinuous()) {
    return MakeError(ErrorCode::kInvalidInput, fmt::format("light {}", light),
                     "the choice reads 8-bit colour images");
  }
  if (pixels_.empty()) {
    choice_.working_width = img.cols;
    choice_.working_height = img.rows;
    const int total = img.cols * img.rows;
    const double stride = std::max(1.0, static_cast<double>(total) / std::max(1, options_.pixels));
    for (double p = 0; p < total; p += stride) pixels_.push_back(static_cast<int>(p));
  } else if (img.cols != choice_.working_width || img.rows != choice_.working_height) {
    return MakeError(ErrorCode::kInvalidInput, fmt::format("light {}", light),
                     "size {}x{} differs from the first image's {}x{}", img.cols, img.rows,
                     choice_.working_width, choice_.working_height);
  }
  values_.conservativeResize(values_.rows() + 1, static_cast<Eigen::Index>(pixels_.size()) * 3);
  values_.row(values_.rows() - 1) = WorkingRow(img, pixels_);
  chosen_.push_back(light);
  step.light = light;
  choice_.steps.push_back(std::move(step));
  return Ok();
}

Result<LightChoice> ChooseLights(const std::vector<Vec3>& dirs, const LightImageReader& read,
                                 const LightChoiceOptions& options) {
  const int lights = static_cast<int>(dirs.size());
  if (options.count < 1 || options.count > lights) {
    return MakeError(ErrorCode::kInvalidInput, "--choose", "{} lights asked of {}", options.count,
                     lights);
  }
  LightChooser chooser(dirs, options);
  for (;;) {
    RIG_ASSIGN_OR_RETURN(LightChooser::Proposal next, chooser.Propose());
    if (next.stop) break;
    RIG_ASSIGN_OR_RETURN(cv::Mat img, read(next.step.light));
    RIG_TRY(chooser.Take(next.step.light, img, next.step));
  }
  return chooser.choice();
}

Result<LightChoice> ChooseLpLights(const std::vector<LpEntry>& entries,
                                   const LightChoiceOptions& options) {
  std::vector<Vec3> dirs;
  for (const auto& e : entries) dirs.push_back(e.direction);
  int downsample = 0;
  auto read = [&](int light) -> Result<cv::Mat> {
    const LpEntry& e = entries[light];
    cv::Mat img;
    try {
      img = cv::imread(e.image, cv::IMREAD_COLOR);
    } catch (const cv::Exception& ex) {
      return MakeError(ErrorCode::kIo, e.image, "cannot read: {}", ex.what());
    }
    if (img.empty()) {
      return MakeError(ErrorCode::kNotFound, fmt::format("{} (.lp line {})", e.image, e.line),
                       "cannot read the image");
    }
    if (downsample == 0) {  // the first image read sets the working size
      downsample = 1;
      while (static_cast<int64_t>(img.cols / downsample) * (img.rows / downsample) >
             options.max_working_pixels)
        ++downsample;
    }
    if (downsample > 1) {
      cv::Mat small;
      cv::resize(img, small, cv::Size(img.cols / downsample, img.rows / downsample), 0, 0,
                 cv::INTER_AREA);
      img = small;
    }
    return img;
  };
  auto choice = ChooseLights(dirs, read, options);
  if (!choice.ok()) return choice.error();
  choice->downsample = downsample;
  return choice;
}

std::string LightChoiceMarkdown(const std::vector<LpEntry>& entries, const LightChoice& choice,
                                const LightChoiceOptions& options) {
  std::string md = fmt::format(
      "# Lights chosen: {} of {}\n\nWorking copy {}x{} (images shrunk {}x), {} pixels at a fixed "
      "stride; seed of {} spread by farthest point; then by {} (docs/lights.md \"Choosing the "
      "lights\"). Images read, in order: only the {} "
      "chosen.\n\n| # | light | image | elevation deg | azimuth deg | gap deg | predicted RMS "
      "| predicted RMS of the rest | why |\n|---|---|---|---|---|---|---|---|---|\n",
      choice.steps.size(), entries.size(), choice.working_width, choice.working_height,
      choice.downsample, std::min(options.pixels, choice.working_width * choice.working_height),
      LightChoiceSeedCount(options),
      options.criterion == LightCriterion::kLargestError
          ? "the largest predicted 8-bit error"
          : "the largest predicted reduction of the 8-bit error over the lights not chosen",
      choice.images_read.size());
  for (size_t i = 0; i < choice.steps.size(); ++i) {
    const auto& s = choice.steps[i];
    const Vec3& d = entries[s.light].direction;
    md += fmt::format(
        "| {} | {} | {} | {:.1f} | {:.1f} | {:.1f} | {} | {} | {} |\n", i + 1, s.light + 1,
        std::filesystem::path(entries[s.light].image).filename().string(),
        kDeg * std::asin(std::clamp(d[2], -1.0, 1.0)), kDeg * std::atan2(d[1], d[0]), s.gap_deg,
        s.seed ? "—" : fmt::format("{:.1f}", s.predicted_rms),
        s.remaining_rms < 0 ? "—" : fmt::format("{:.1f}", s.remaining_rms), s.reason);
  }
  return md;
}

}  // namespace rig
