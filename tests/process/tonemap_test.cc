// Tests of process/tonemap: Ward's ceiling on constructed histograms, monotonic mapping,
// linear fallback, full display range, colour ratios, encoding, and the real HDR images.
#include "process/render/tonemap.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"
#include "process/render/tonemap_compare.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

constexpr double kDisplayLogRange = 4.605170185988091;  // ln(100 / 1)

// A histogram with a spike: 80% of the samples at one luminance, the rest spread evenly in
// log over 1e-3 .. 1e3 (a range of ln 1e6 = 13.8, three times the display's).
std::vector<float> SpikySamples() {
  std::vector<float> s;
  for (int i = 0; i < 2000; ++i) s.push_back(static_cast<float>(std::pow(10.0, -3 + 6.0 * i / 1999)));
  for (int i = 0; i < 8000; ++i) s.push_back(2.5f);
  return s;
}

TEST(WardHistogram, BinsNaturalLogOfPositiveSamplesOnly) {
  WardHistogram h = BuildLogHistogram({1.0f, std::exp(1.2f), std::exp(2.0f), 0.0f, -3.0f,
                                       std::numeric_limits<float>::quiet_NaN()},
                                      4);
  EXPECT_NEAR(h.log_min, 0.0, 1e-6);
  EXPECT_NEAR(h.log_max, 2.0, 1e-6);
  EXPECT_NEAR(h.bin_width, 0.5, 1e-6);
  EXPECT_DOUBLE_EQ(h.original_total, 3);
  EXPECT_EQ(h.counts, (std::vector<double>{1, 0, 1, 1}));  // the maximum lands in the last bin
}

TEST(WardHistogram, CeilingHoldsAfterTrimmingWithinTolerance) {
  WardHistogram h = BuildLogHistogram(SpikySamples(), 100);
  const double tolerance = 0.025;
  const double spike_before = *std::max_element(h.counts.begin(), h.counts.end());
  CeilingOutcome c = ApplyLinearCeiling(&h, kDisplayLogRange, tolerance);
  ASSERT_TRUE(c.converged);
  EXPECT_GE(c.iterations, 2);  // the first pass trims the spike, a later one finds little left
  EXPECT_LE(c.last_trimmed, tolerance * h.original_total);
  const double total = h.Total();
  // The last pass clipped every bin to the ceiling of the total it started from.
  const double last_ceiling = (total + c.last_trimmed) * h.bin_width / kDisplayLogRange;
  for (double count : h.counts) EXPECT_LE(count, last_ceiling * (1 + 1e-12));
  // And against the final total, no bin is over by more than the tolerance allows.
  EXPECT_LE(*std::max_element(h.counts.begin(), h.counts.end()),
            CeilingValue(h, kDisplayLogRange) + tolerance * h.original_total);
  EXPECT_LT(*std::max_element(h.counts.begin(), h.counts.end()), spike_before / 10);
}

TEST(WardHistogram, TrimmedMappingNeverExaggeratesContrastBeyondLinear) {
  ToneMapOptions o;
  o.ward_variant = WardVariant::kPaper;  // the bound is the paper's (cumulative after the trim)
  WardMapping m = ComputeWardMapping(SpikySamples(), o);
  ASSERT_FALSE(m.linear);
  // The bound: a bin's slope is ln-display-range · f_i / (T Δb), and f_i is at most the
  // ceiling of the total the last pass started from, T + last_trimmed.
  WardHistogram h = BuildLogHistogram(SpikySamples(), o.bins);
  CeilingOutcome c = ApplyLinearCeiling(&h, kDisplayLogRange, o.ceiling_tolerance);
  const double bound = 1 + c.last_trimmed / h.Total();
  EXPECT_LT(bound, 1.15);
  // Slope dB_d / db of the mapping, bin by bin: at most 1 (+ the tolerance's slack).
  double worst = 0;
  for (double b = m.log_min + 0.005; b < m.log_max - 0.01; b += 0.01) {
    const double slope =
        (m.DisplayLogLuminance(std::exp(b + 0.005)) - m.DisplayLogLuminance(std::exp(b - 0.005))) /
        0.01;
    worst = std::max(worst, slope);
  }
  EXPECT_LE(worst, bound + 1e-9);
  EXPECT_GT(worst, 0.9);  // around the spike the mapping is as steep as linear allows
}

TEST(WardHistogram, CumulativeRunsFromZeroToOneAndIsMonotonic) {
  WardHistogram h = BuildLogHistogram(SpikySamples(), 50);
  std::vector<double> p = CumulativeDistribution(h);
  ASSERT_EQ(p.size(), 51u);
  EXPECT_EQ(p.front(), 0.0);
  EXPECT_EQ(p.back(), 1.0);
  for (size_t i = 1; i < p.size(); ++i) EXPECT_GE(p[i], p[i - 1]);
}

TEST(WardHistogram, TwoValuedSceneJustOverTheDisplayRangeEmptiesAndFallsBackToLinear) {
  // Two luminances 105:1 apart (display 100:1): every pass trims nearly everything.
  std::vector<float> s(500, 1.0f);
  s.insert(s.end(), 500, 105.0f);
  WardHistogram h = BuildLogHistogram(s, 100);
  CeilingOutcome c = ApplyLinearCeiling(&h, kDisplayLogRange, 0.025);
  EXPECT_FALSE(c.converged);
  EXPECT_GE(c.iterations, 1);
  ToneMapReport report;
  WardMapping m = ComputeWardMapping(s, ToneMapOptions{}, &report);
  EXPECT_TRUE(m.linear);
  EXPECT_TRUE(report.linear_fallback);
  EXPECT_GE(report.trim_iterations, 1);
  // Log-average (sqrt(105)) to the display's geometric middle (10 cd/m²).
  EXPECT_NEAR(m.DisplayLuminance(std::sqrt(105.0)), 10.0, 1e-9);
}

TEST(WardMapping, MonotonicNonDecreasingInSceneLuminance) {
  WardMapping m = ComputeWardMapping(SpikySamples(), ToneMapOptions{});
  double previous = -1;
  for (double lb = -6; lb <= 6; lb += 0.001) {  // well beyond the histogram at both ends
    const double v = m.PixelLuminance(std::pow(10.0, lb));
    ASSERT_GE(v, previous) << "at log10 L = " << lb;
    ASSERT_GE(v, 0.0);
    ASSERT_LE(v, 1.0);
    previous = v;
  }
  EXPECT_EQ(m.PixelLuminance(1e-6), 0.0);
  EXPECT_NEAR(m.PixelLuminance(1e6), 1.0, 1e-12);
}

// A horizontal ramp of grey radiance, log-spaced from lo to hi.
cv::Mat LogRamp(int width, int height, double lo, double hi) {
  cv::Mat img(height, width, CV_32FC3);
  for (int x = 0; x < width; ++x) {
    const float v = static_cast<float>(lo * std::pow(hi / lo, x / (width - 1.0)));
    img.col(x).setTo(cv::Scalar::all(v));
  }
  return img;
}

TEST(ToneMap, WardImageIsMonotonicAlongALuminanceRamp) {
  cv::Mat ramp = LogRamp(2000, 8, 1e-3, 1e4);
  ToneMapReport report;
  auto out = ToneMap(ramp, ToneMapOptions{}, &report);
  ASSERT_TRUE(out.ok()) << out.error().ToString();
  EXPECT_FALSE(report.linear_fallback);
  for (int x = 1; x < ramp.cols; ++x) {
    ASSERT_GE(out->at<cv::Vec3b>(4, x)[1], out->at<cv::Vec3b>(4, x - 1)[1]) << "x = " << x;
  }
}

TEST(ToneMap, ExtremeRangeSceneUsesTheFullDisplayRange) {
  cv::Mat ramp = LogRamp(1200, 60, 1e-4, 1e4);
  ToneMapReport report;
  ToneMapOptions paper;
  paper.ward_variant = WardVariant::kPaper;
  {
    // pcond pads the range: the darkest pixel sits one bin above the bottom, with half of
    // bin 1's samples under it, so it is dark but not black; the brightest is white.
    auto pcond = ToneMap(ramp, ToneMapOptions{}, &report);
    ASSERT_TRUE(pcond.ok());
    double lo, hi;
    cv::minMaxLoc(pcond->reshape(1), &lo, &hi);
    EXPECT_GT(lo, 0);
    EXPECT_LE(lo, 8);
    EXPECT_EQ(hi, 255);
    EXPECT_GT(report.point_samples, 0);
  }
  auto out = ToneMap(ramp, paper, &report);
  ASSERT_TRUE(out.ok());
  EXPECT_FALSE(report.linear_fallback);
  EXPECT_NEAR(report.scene_log_range, std::log(1e8), 0.5);  // foveal averaging trims the ends
  double lo, hi;
  cv::minMaxLoc(out->reshape(1), &lo, &hi);
  EXPECT_EQ(lo, 0);
  EXPECT_EQ(hi, 255);
  // A flat log histogram needs no trimming: the mapping is linear in log, so the middle of
  // the ramp (1 cd/m² scene) lands at the display's geometric middle, 10 cd/m²:
  // pixel = ((10 - 1) / 99)^(1/2.2).
  const int mid = out->at<cv::Vec3b>(30, 600)[1];
  EXPECT_NEAR(mid, 255 * std::pow(9.0 / 99.0, 1 / 2.2), 3);
}

TEST(ToneMap, LowRangeSceneMapsLinearly) {
  cv::Mat ramp = LogRamp(400, 30, 0.37, 3.7);  // 10:1 on a 100:1 display
  ToneMapReport report;
  auto pixels = ToneMapLinearPixels(ramp, ToneMapOptions{}, &report);
  ASSERT_TRUE(pixels.ok());
  EXPECT_TRUE(report.linear_fallback);
  EXPECT_EQ(report.trim_iterations, 0);  // decided from the range, before any trimming
  const double k = pixels->at<cv::Vec3f>(0, 0)[1] / ramp.at<cv::Vec3f>(0, 0)[1];
  for (int x = 0; x < ramp.cols; x += 7) {
    EXPECT_NEAR(pixels->at<cv::Vec3f>(15, x)[1] / ramp.at<cv::Vec3f>(15, x)[1], k, k * 1e-6);
  }
  // Nothing clips: the whole scene fits.
  double hi;
  cv::minMaxLoc(pixels->reshape(1), nullptr, &hi);
  EXPECT_LT(hi, 1.0);
}

TEST(ToneMap, ColourRatiosArePreservedBeforeGamma) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> chroma(0.2f, 1.0f), decade(-3, 3);
  cv::Mat img(64, 256, CV_32FC3);
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const float s = std::pow(10.0f, decade(rng));
      img.at<cv::Vec3f>(y, x) = cv::Vec3f(chroma(rng), chroma(rng), chroma(rng)) * s;
    }
  }
  for (ToneMapMethod method : {ToneMapMethod::kWard, ToneMapMethod::kLinear}) {
    ToneMapOptions o;
    o.method = method;
    o.gamut = GamutMapping::kClip;  // desaturation changes the ratios of what is out of gamut
    auto pixels = ToneMapLinearPixels(img, o);
    ASSERT_TRUE(pixels.ok());
    int checked = 0;
    for (int y = 0; y < img.rows; ++y) {
      for (int x = 0; x < img.cols; ++x) {
        const cv::Vec3f in = img.at<cv::Vec3f>(y, x), out = pixels->at<cv::Vec3f>(y, x);
        if (out[0] <= 1e-4f || out[2] >= 1.0f || out[1] >= 1.0f) continue;  // black or clipped
        EXPECT_NEAR(out[2] / out[1], in[2] / in[1], 1e-4 * in[2] / in[1]);
        EXPECT_NEAR(out[0] / out[1], in[0] / in[1], 1e-4 * in[0] / in[1]);
        ++checked;
      }
    }
    EXPECT_GT(checked, img.total() / 2) << ToneMapMethodName(method);
  }
}

TEST(ToneMap, LinearMethodSendsThePercentileToWhite) {
  cv::Mat ramp(1, 10000, CV_32FC3);
  for (int x = 0; x < ramp.cols; ++x) ramp.at<cv::Vec3f>(0, x) = cv::Vec3f::all(x + 1.0f);
  ToneMapOptions o;
  o.method = ToneMapMethod::kLinear;
  o.gamut = GamutMapping::kClip;  // over-white values stay for the encoding to clip
  ToneMapReport report;
  auto out = ToneMapLinearPixels(ramp, o, &report);
  ASSERT_TRUE(out.ok());
  EXPECT_NEAR(report.linear_scale, 1.0 / 9901, 1e-7);
  EXPECT_EQ(cv::countNonZero(out->reshape(1) > 1.0f), 3 * 99);  // 9902 .. 10000 over white
  o.linear_scale = 1.0 / 5000;  // a fixed exposure instead
  out = ToneMapLinearPixels(ramp, o, &report);
  ASSERT_TRUE(out.ok());
  EXPECT_EQ(cv::countNonZero(out->reshape(1) > 1.0f), 3 * 5000);
  EXPECT_FLOAT_EQ(out->at<cv::Vec3f>(0, 2499)[1], 0.5f);
}

TEST(ToneMap, EncodingMatchesTheGammaAndSrgbCurves) {
  cv::Mat v(1, 20001, CV_32FC3);
  for (int x = 0; x < v.cols; ++x) v.at<cv::Vec3f>(0, x) = cv::Vec3f::all(x / 20000.0f);
  for (bool srgb : {false, true}) {
    ToneMapOptions o;
    o.srgb = srgb;
    cv::Mat enc = EncodeForDisplay(v, o);
    for (int x = 0; x < v.cols; ++x) {
      const double lin = v.at<cv::Vec3f>(0, x)[0];
      const double e = srgb ? (lin <= 0.0031308 ? 12.92 * lin : 1.055 * std::pow(lin, 1 / 2.4) - 0.055)
                            : std::pow(lin, 1 / 2.2);
      const int want = static_cast<int>(std::lround(255 * e));
      const int got = enc.at<cv::Vec3b>(0, x)[0];
      ASSERT_EQ(got, want) << "v = " << lin << (srgb ? " sRGB" : " gamma 2.2");
    }
  }
  ToneMapOptions o;
  cv::Mat special(1, 4, CV_32FC3);
  special.at<cv::Vec3f>(0, 0) = cv::Vec3f::all(-1);
  special.at<cv::Vec3f>(0, 1) = cv::Vec3f::all(std::numeric_limits<float>::quiet_NaN());
  special.at<cv::Vec3f>(0, 2) = cv::Vec3f::all(7);
  special.at<cv::Vec3f>(0, 3) = cv::Vec3f::all(0.5f);
  cv::Mat enc = EncodeForDisplay(special, o);
  EXPECT_EQ(enc.at<cv::Vec3b>(0, 0)[0], 0);
  EXPECT_EQ(enc.at<cv::Vec3b>(0, 1)[0], 0);
  EXPECT_EQ(enc.at<cv::Vec3b>(0, 2)[0], 255);
  EXPECT_EQ(enc.at<cv::Vec3b>(0, 3)[0], 186);  // 255 · 0.5^(1/2.2) = 186.08
}

TEST(ToneMap, FovealSamplesAreOnePerDegree) {
  cv::Mat lum(676, 1024, CV_32FC1, cv::Scalar(1));
  cv::Mat f = FovealLuminance(lum, 40);
  EXPECT_EQ(f.cols, 40);
  EXPECT_EQ(f.rows, 26);
  EXPECT_NEAR(FieldOfViewDeg(50, 36), 39.5978, 1e-3);  // a 50 mm lens on a full-frame sensor
  ToneMapReport report;
  cv::Mat img(676, 1024, CV_32FC3, cv::Scalar::all(1));
  ToneMapOptions paper;
  paper.ward_variant = WardVariant::kPaper;
  ASSERT_TRUE(ToneMap(img, paper, &report).ok());
  EXPECT_EQ(report.foveal_width, 40);
  EXPECT_EQ(report.foveal_height, 26);
  // pcond: 2·tan(20°) / 1° = 41.7 samples across the larger side, rounded; the other side
  // 41.7 · 676 / 1024 = 27.5 → 28. A portrait image turns the grid, not the field of view.
  ASSERT_TRUE(ToneMap(img, ToneMapOptions{}, &report).ok());
  EXPECT_EQ(report.foveal_width, 42);
  EXPECT_EQ(report.foveal_height, 28);
  // 256 stratified points per foveal sample: a 16 × 16 grid of cells in each.
  EXPECT_EQ(report.point_samples, 256 * 42 * 28);
  cv::Mat portrait(1024, 676, CV_32FC3, cv::Scalar::all(1));
  ASSERT_TRUE(ToneMap(portrait, ToneMapOptions{}, &report).ok());
  EXPECT_EQ(report.foveal_width, 28);
  EXPECT_EQ(report.foveal_height, 42);
  ASSERT_TRUE(ToneMap(portrait, paper, &report).ok());
  EXPECT_EQ(report.foveal_width, 40);  // the paper's: horizontal on every image
  EXPECT_EQ(report.foveal_height, 61);
}

TEST(WardPcond, RandomPixelsAreDistinctSeededAndEveryPixelWhenAskedForMore) {
  const auto a = RandomPixelIndices(1000, 300, 7), b = RandomPixelIndices(1000, 300, 7);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, RandomPixelIndices(1000, 300, 8));
  std::vector<int64_t> sorted = a;
  std::sort(sorted.begin(), sorted.end());
  EXPECT_EQ(std::unique(sorted.begin(), sorted.end()), sorted.end());
  EXPECT_GE(sorted.front(), 0);
  EXPECT_LT(sorted.back(), 1000);
  EXPECT_EQ(RandomPixelIndices(50, 80, 1).size(), 50u);
}

TEST(WardPcond, HistogramIsPaddedAndPointSamplesWeighAsMuchAsTheFovealOnes) {
  // Foveal: 4 samples at 1 and 4 at e^4; points: 16 at e^2.
  std::vector<float> foveal(4, 1.0f), points(16, std::exp(2.0f));
  foveal.insert(foveal.end(), 4, std::exp(4.0f));
  WardHistogram h = BuildPcondHistogram(foveal, points, 10);
  const double top = 4 + std::log(1.01);
  EXPECT_NEAR(h.log_max, top, 1e-6);  // e^4 as a float
  EXPECT_NEAR(h.log_min, top - top * 10 / 9, 1e-6);  // one bin below ln 1 = 0
  EXPECT_DOUBLE_EQ(h.original_total, 16);            // 8 foveal + 16 points of weight 1/2
  EXPECT_NEAR(h.Total(), 16, 1e-12);
  // ln 1 = 0 is bin 1's lower edge: half of its 4 samples moved to the padding bin 0.
  EXPECT_DOUBLE_EQ(h.counts[0], 2);
  EXPECT_DOUBLE_EQ(h.counts[1], 2);
  EXPECT_NEAR(h.mean_log, (4 * 0 + 4 * 4 + 8 * 2) / 16.0, 1e-9);
}

TEST(WardPcond, StopTestUsesTheCurrentTotalAndTheCumulativeBeforeTheLastTrim) {
  WardHistogram h = BuildPcondHistogram(SpikySamples(), {}, 100);
  WardHistogram before = h;
  std::vector<double> cumulative;
  CeilingOutcome c = ApplyPcondCeiling(&h, kDisplayLogRange, 0.025, &cumulative);
  ASSERT_TRUE(c.converged);
  // The last pass trimmed at most 2.5% of the total it started from ...
  EXPECT_LE(c.last_trimmed, 0.025 * (h.Total() + c.last_trimmed) + 1e-9);
  // ... and the mapping's cumulative is that total's, not the trimmed one's.
  ASSERT_EQ(cumulative.size(), 101u);
  EXPECT_NE(cumulative, CumulativeDistribution(h));
  EXPECT_NE(cumulative, CumulativeDistribution(before));
  EXPECT_EQ(cumulative.front(), 0.0);
  EXPECT_EQ(cumulative.back(), 1.0);
}

TEST(ToneMap, OpenCvOperatorsProduceFiniteMidRangePictures) {
  cv::Mat ramp = LogRamp(300, 40, 1e-2, 1e3);
  for (ToneMapMethod method :
       {ToneMapMethod::kReinhard, ToneMapMethod::kDrago, ToneMapMethod::kMantiuk}) {
    ToneMapOptions o;
    o.method = method;
    auto out = ToneMap(ramp, o);
    ASSERT_TRUE(out.ok()) << out.error().ToString();
    EXPECT_EQ(out->type(), CV_8UC3);
    const double mean = cv::mean(*out)[1];
    EXPECT_GT(mean, 30) << ToneMapMethodName(method);
    EXPECT_LT(mean, 230) << ToneMapMethodName(method);
    EXPECT_LT(out->at<cv::Vec3b>(20, 0)[1], out->at<cv::Vec3b>(20, 299)[1]);
  }
}

TEST(ToneMap, RejectsBadInputAndOptions) {
  EXPECT_EQ(ToneMap(cv::Mat(), ToneMapOptions{}).error().code, ErrorCode::kInvalidInput);
  EXPECT_EQ(ToneMap(cv::Mat(4, 4, CV_8UC3), ToneMapOptions{}).error().code,
            ErrorCode::kInvalidInput);
  ToneMapOptions o;
  o.display_min_cd_m2 = 200;
  EXPECT_FALSE(ToneMap(cv::Mat(4, 4, CV_32FC3, cv::Scalar::all(1)), o).ok());
  EXPECT_FALSE(ParseToneMapMethod("hable").ok());
  EXPECT_EQ(ParseToneMapMethod("drago").value(), ToneMapMethod::kDrago);
}

// ---- the real HDR images ----------------------------------------------------------------

fs::path SharedDir() {
  if (const char* d = std::getenv("RIG_SHARED_DIR")) return d;
  if (const char* d = std::getenv("RIG_SOURCE_DIR")) return fs::path(d) / ".." / "shared";
  return "../shared";
}

class RealHdr : public ::testing::TestWithParam<const char*> {};

TEST_P(RealHdr, WardShowsBrightAndDarkWithFewClippedPixels) {
  const fs::path path = SharedDir() / "data" / "hdr" / GetParam();
  if (!fs::exists(path)) GTEST_SKIP() << path << " is not there";
  cv::Mat radiance;
  if (path.extension() == ".exr") {
    auto r = ReadRgbExr(path.string());
    ASSERT_TRUE(r.ok()) << r.error().ToString();
    radiance = *r;
  } else {
    radiance = cv::imread(path.string(), cv::IMREAD_ANYDEPTH | cv::IMREAD_COLOR);
    ASSERT_FALSE(radiance.empty());
  }
  ASSERT_EQ(radiance.type(), CV_32FC3);
  ToneMapReport report;
  auto out = ToneMap(radiance, ToneMapOptions{}, &report);
  ASSERT_TRUE(out.ok());
  EXPECT_FALSE(report.linear_fallback);
  EXPECT_GT(report.scene_log_range, std::log(100.0));  // these are real HDR scenes
  cv::Mat grey;
  cv::extractChannel(*out, grey, 1);
  // Black pixels, and pixels white in green (the channel that carries most luminance), are
  // few. Any channel at 255 is more common: colour is kept by scaling RGB, so a bright
  // saturated colour (the yellow glass of Desk.exr) clips in its strongest channel first.
  EXPECT_LT(report.clipped_low_fraction, 0.03);
  EXPECT_LT(cv::countNonZero(grey == 255), 0.03 * grey.total());
  EXPECT_LT(report.clipped_high_fraction, 0.08);
  const double mean = cv::mean(grey)[0];
  EXPECT_GT(mean, 60);
  EXPECT_LT(mean, 190);
  // Detail in the dark quarter and in the bright quarter of the scene: the tone-mapped
  // levels there are spread, not crushed to one value.
  cv::Mat lum = Luminance(radiance);
  std::vector<float> sorted(lum.begin<float>(), lum.end<float>());
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 4, sorted.end());
  const float q1 = sorted[sorted.size() / 4];
  std::nth_element(sorted.begin(), sorted.begin() + 3 * sorted.size() / 4, sorted.end());
  const float q3 = sorted[3 * sorted.size() / 4];
  cv::Scalar dark_mean, dark_sd, bright_mean, bright_sd;
  cv::meanStdDev(grey, dark_mean, dark_sd, lum < q1);
  cv::meanStdDev(grey, bright_mean, bright_sd, lum > q3);
  EXPECT_GT(dark_sd[0], 5) << "dark quarter crushed";
  EXPECT_GT(bright_sd[0], 5) << "bright quarter crushed";
  EXPECT_LT(dark_mean[0], bright_mean[0]);
  RecordProperty("mean", std::to_string(mean));
  std::printf("%s: foveal %dx%d, ln range %.2f, %d trims, clipped %.2f%% / %.2f%%, mean %.1f, "
              "dark sd %.1f, bright sd %.1f\n",
              GetParam(), report.foveal_width, report.foveal_height, report.scene_log_range,
              report.trim_iterations, 100 * report.clipped_low_fraction,
              100 * report.clipped_high_fraction, mean, dark_sd[0], bright_sd[0]);
}

INSTANTIATE_TEST_SUITE_P(SharedData, RealHdr, ::testing::Values("mpi_atrium_3.hdr", "Desk.exr"));

TEST(ToneMapCompare, EveryMethodSideBySideAtTheGivenWidthWithItsReport) {
  cv::Mat radiance(60, 80, CV_32FC3);
  for (int y = 0; y < radiance.rows; ++y)
    for (int x = 0; x < radiance.cols; ++x)
      radiance.at<cv::Vec3f>(y, x) = cv::Vec3f::all(static_cast<float>(std::exp(0.1 * x - 2)));
  ToneMapOptions o;
  std::vector<ToneMapPanel> panels;
  auto all = ToneMapSideBySide(radiance, o, ComparedToneMapMethods(), 40, true, &panels);
  ASSERT_TRUE(all.ok()) << all.error().ToString();
  ASSERT_EQ(panels.size(), 5u);
  EXPECT_EQ(all->cols, 5 * 40);
  EXPECT_EQ(all->rows, 30);
  EXPECT_EQ(panels[0].options.method, ToneMapMethod::kWard);
  EXPECT_NE(DescribeToneMapPanel(panels[0]).find("foveal"), std::string::npos);
  EXPECT_NE(DescribeToneMapPanel(panels[1]).find("scale"), std::string::npos);
  // One method, unlabelled, as is: the same picture ToneMap gives.
  o.method = ToneMapMethod::kWard;
  auto one = ToneMapSideBySide(radiance, o, {ToneMapMethod::kWard}, 0, false, nullptr);
  auto direct = ToneMap(radiance, o);
  ASSERT_TRUE(one.ok() && direct.ok());
  EXPECT_EQ(cv::norm(*one, *direct, cv::NORM_INF), 0);
}

}  // namespace
}  // namespace rig
