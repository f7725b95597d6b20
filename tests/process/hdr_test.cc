// HDR radiance maps against known truth: response recovery (Debevec–Malik) against the true
// curve, the merge against the true radiance (and against OpenCV's on the same bracket),
// masks for what no exposure records, linear input, λ and sampling, and bad input.
#include "process/hdr/hdr.h"

#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/photo.hpp>

#include "process/io/image_io.h"
#include "sim/bracket_synth.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

struct Scene {
  cv::Mat truth;
  cv::Rect hot, black;
  Bracket bracket;
};

const synth::FilmicResponse& Response() {
  static const synth::FilmicResponse f;
  return f;
}

Scene MakeScene(int frames = 7, double noise = 1, int w = 240, int h = 180) {
  Scene s;
  s.truth = synth::SyntheticRadiance(w, h, &s.hot, &s.black);
  s.bracket = synth::RenderBracket(s.truth, synth::ExposuresFor(1e-2, 10.0 * std::pow(10.0, 0.5), frames),
                                   Response(), 7, 5e-5 * noise * noise, 2.5e-4 * noise);
  return s;
}

ResponseCurve Recover(const Bracket& b, ResponseOptions o = {}) {
  const Bracket one[1] = {b};
  auto r = RecoverResponse(one, o);
  EXPECT_TRUE(r.ok()) << r.error().ToString();
  return r.ok() ? *r : ResponseCurve{};
}

double ResponseError(const ResponseCurve& r) {
  return synth::MaxResponseError([&](int c, int z) { return r.log_exposure[c][z]; }, Response(), 13, 242);
}

std::vector<cv::Mat> Images(const Bracket& b) {
  std::vector<cv::Mat> v;
  for (const auto& f : b) v.push_back(f.image);
  return v;
}

cv::Mat Times(const Bracket& b) {
  cv::Mat t(static_cast<int>(b.size()), 1, CV_32F);
  for (size_t i = 0; i < b.size(); ++i) t.at<float>(static_cast<int>(i)) = static_cast<float>(b[i].exposure.count());
  return t;
}

TEST(ResponseRecovery, RecoversTheFilmicCurveWithinTwoHundredthsOverTheWellExposedRange) {
  const Scene s = MakeScene();
  const ResponseCurve r = Recover(s.bracket);
  const double err = ResponseError(r);
  std::printf("max |g - g_true| over levels 13..242: %.4f (natural log)\n", err);
  EXPECT_LT(err, 0.02);
  // The anchor g(mid) = 0 and a monotonic curve in every channel.
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(r.log_exposure[c][128], 0.0, 1e-9);
    for (int z = 14; z < 242; ++z) EXPECT_GT(r.log_exposure[c][z + 1], r.log_exposure[c][z]) << c << " " << z;
  }
}

TEST(ResponseRecovery, ChosenSamplesBeatAPlainGridAndLambdaSmoothsTheCurve) {
  const Scene s = MakeScene();
  ResponseOptions chosen, grid;
  grid.grid_sampling = true;
  const double e_chosen = ResponseError(Recover(s.bracket, chosen));
  const double e_grid = ResponseError(Recover(s.bracket, grid));
  std::printf("response error: chosen samples %.4f, plain grid %.4f\n", e_chosen, e_grid);
  EXPECT_LT(e_chosen, e_grid);
  // Roughness (sum of squared second differences) falls as λ grows.
  auto roughness = [](const ResponseCurve& r) {
    double s2 = 0;
    for (int c = 0; c < 3; ++c)
      for (int z = 14; z < 241; ++z) {
        const double d = r.log_exposure[c][z - 1] - 2 * r.log_exposure[c][z] + r.log_exposure[c][z + 1];
        s2 += d * d;
      }
    return s2;
  };
  const Scene noisy = MakeScene(7, 8);
  ResponseOptions low, high;
  low.lambda = 0.1;
  high.lambda = 1000;
  const double r_low = roughness(Recover(noisy.bracket, low)), r_high = roughness(Recover(noisy.bracket, high));
  std::printf("roughness: lambda 0.1 %.3g, lambda 1000 %.3g\n", r_low, r_high);
  EXPECT_LT(r_high, 0.5 * r_low);
}

TEST(RadianceMerge, RecoversTheTrueRadianceAndBeatsOpenCvByFiveTimesOnTheSameBracket) {
  const Scene s = MakeScene();
  const ResponseCurve r = Recover(s.bracket);
  MergeOptions mo;
  mo.max_unrecorded_fraction = 1.0;
  auto map = MergeBracket(s.bracket, r, mo);
  ASSERT_TRUE(map.ok()) << map.error().ToString();
  const double ours = synth::LogRmsError(map->radiance, s.truth, s.bracket);
  cv::Mat cv_response, cv_hdr;
  cv::createCalibrateDebevec()->process(Images(s.bracket), cv_response, Times(s.bracket));
  cv::createMergeDebevec()->process(Images(s.bracket), cv_hdr, Times(s.bracket), cv_response);
  const double opencv = synth::LogRmsError(cv_hdr, s.truth, s.bracket);
  std::printf("log-radiance RMS error: ours %.4f, OpenCV Debevec %.4f (%.1fx)\n", ours, opencv, opencv / ours);
  EXPECT_LT(ours, 0.03);
  EXPECT_LT(5 * ours, opencv);
}

// The bracket's own noise, fitted from neighbouring frames, against the noise it was rendered
// with: through the true response g(z) = ln X, a frame's log-radiance variance is
// shot * X / X^2 + read^2 / X^2 + g'^2 / 12 (8-bit quantisation), i.e. in NoiseModel's terms
// shot e^-g_mid, read^2 e^-2 g_mid and 1/12.
TEST(NoiseModel, FittedFromTheBracketItselfMatchesTheNoiseItWasRenderedWith) {
  const double shot = 5e-5, read = 2.5e-4;
  cv::Mat truth = synth::SyntheticRadiance(400, 300);
  const Bracket b = synth::RenderBracket(truth, synth::ExposuresFor(1e-2, 300.0, 10), Response(), 5, shot, read);
  ResponseCurve g;
  for (int c = 0; c < 3; ++c)
    for (int z = 0; z < 256; ++z) g.log_exposure[c].push_back(Response().TrueG(c, std::max(z, 1)));
  const NoiseModel m = FitNoise(b, g, {-1, -1, -1}, {-1, -1, -1});
  ASSERT_TRUE(m.ok);
  // The three terms are nearly collinear over a filmic curve (the fit may trade one for
  // another); what the weights use is their sum, the variance of each level.
  for (int c = 0; c < 3; ++c) {
    const auto& gc = g.log_exposure[c];
    double worst = 0;
    int worst_z = 0;
    for (int z = 16; z <= 240; ++z) {
      const double slope = 0.5 * (gc[z + 1] - gc[z - 1]), x = std::exp(gc[z]);
      const double truth_v = slope * slope / 12 + (shot * x + read * read) / (x * x);
      const double dev = std::abs(m.Variance(g, c, z) / truth_v - 1);
      if (dev > worst) worst = dev, worst_z = z;
    }
    std::printf("channel %c: variance per level within %.0f%% of the truth over 16..240 (worst at %d), "
                "%lld pairs\n", "BGR"[c], 100 * worst, worst_z, static_cast<long long>(m.pairs[c]));
    EXPECT_LT(worst, 0.15) << "BGR"[c];
    EXPECT_GT(m.pairs[c], 10000);
  }
  // Weighted by it, the merge through the true response beats the photon weighting's.
  MergeOptions photon, fitted;
  photon.max_unrecorded_fraction = fitted.max_unrecorded_fraction = 1.0;
  photon.weighting = MergeWeighting::kPhoton;
  fitted.weighting = MergeWeighting::kNoise;
  auto a = MergeBracket(b, g, photon);
  auto n = MergeBracket(b, g, fitted);
  ASSERT_TRUE(a.ok() && n.ok());
  const double ea = synth::LogRmsError(a->radiance, truth, b), en = synth::LogRmsError(n->radiance, truth, b);
  std::printf("through the true response: photon weights %.4f, fitted noise %.4f\n", ea, en);
  EXPECT_LT(en, 0.97 * ea);
  EXPECT_THAT(n->attributes.at("merge_weighting"), HasSubstr("inverse variance"));
  // Too little to fit (two frames that share no well-recorded pixel): the photon weighting.
  const Bracket apart = synth::RenderBracket(truth, {1e-3, 1e3}, Response(), 5);
  EXPECT_FALSE(FitNoise(apart, g, {-1, -1, -1}, {-1, -1, -1}).ok);
}

TEST(RadianceMerge, TheVectorAndScalarPathsGiveTheSameRadiance) {
  const Scene s = MakeScene(5, 1, 203, 61);  // a width that leaves a scalar tail
  const ResponseCurve r = Recover(s.bracket);
  MergeOptions mo;
  mo.max_unrecorded_fraction = 1.0;
  auto simd = MergeBracket(s.bracket, r, mo);
  setenv("RIG_NO_SIMD", "1", 1);
  auto scalar = MergeBracket(s.bracket, r, mo);
  unsetenv("RIG_NO_SIMD");
  ASSERT_TRUE(simd.ok() && scalar.ok());
  // Sums in a different order: equal to float rounding.
  EXPECT_LT(cv::norm(simd->radiance, scalar->radiance, cv::NORM_RELATIVE | cv::NORM_INF), 1e-5);
  EXPECT_EQ(cv::countNonZero(simd->flags != scalar->flags), 0);
}

TEST(RadianceMerge, PixelsNoExposureRecordsAreFlaggedNotInvented) {
  const Scene s = MakeScene();
  const ResponseCurve r = Recover(s.bracket);
  MergeOptions mo;
  mo.max_unrecorded_fraction = 1.0;
  auto map = MergeBracket(s.bracket, r, mo);
  ASSERT_TRUE(map.ok());
  const cv::Point hot = (s.hot.tl() + s.hot.br()) / 2, black = (s.black.tl() + s.black.br()) / 2;
  EXPECT_EQ(map->flags.at<uint8_t>(hot), kFlagSaturated);
  EXPECT_EQ(map->flags.at<uint8_t>(black), kFlagBlack);
  EXPECT_GE(map->saturated_pixels, s.hot.area() * 8 / 10);
  EXPECT_GE(map->black_pixels, s.black.area() * 8 / 10);
  // The saturated value is a lower bound, far below the true 1e6; the black one is 0.
  EXPECT_LT(map->radiance.at<cv::Vec3f>(hot)[1], 1e4);
  EXPECT_EQ(map->radiance.at<cv::Vec3f>(black)[1], 0.0f);
  // A well-recorded pixel is not flagged.
  EXPECT_EQ(map->flags.at<uint8_t>(s.truth.rows * 3 / 4, s.truth.cols / 2), kFlagOk);
}

TEST(RadianceMerge, LinearFramesMergeThroughTheLinearResponse) {
  // Linear 16-bit frames of a radiance ramp: the merge gives the radiance up to one scale.
  cv::Mat truth(60, 80, CV_32FC3);
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x)
      truth.at<cv::Vec3f>(y, x) = cv::Vec3f(1, 1.5f, 2) * static_cast<float>(std::pow(10.0, 3.0 * x / truth.cols));
  Bracket b;
  for (double t : {0.01, 0.04, 0.16}) {
    cv::Mat x = truth * t * 60000 / 2 / 160;  // brightest of the longest well below full
    cv::Mat frame;
    x.convertTo(frame, CV_16UC3);
    b.push_back({frame, Seconds(t), fmt::format("linear_{}.png", t)});
  }
  auto map = MergeBracket(b, LinearResponse(65536), MergeOptions{});
  ASSERT_TRUE(map.ok()) << map.error().ToString();
  const double err = synth::LogRmsError(map->radiance, truth, b);
  EXPECT_LT(err, 0.01);
}

TEST(BracketValidation, BadBracketsAreRefusedNamingTheFile) {
  const Scene s = MakeScene(3);
  Bracket sizes = s.bracket;
  cv::resize(sizes[1].image, sizes[1].image, cv::Size(100, 80));
  auto st = ValidateBracket(sizes);
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr(sizes[1].source));
  Bracket dup = s.bracket;
  dup[2].exposure = dup[1].exposure;
  st = ValidateBracket(dup);
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr(dup[2].source));
  Bracket order = s.bracket;
  std::swap(order[0].exposure, order[2].exposure);
  EXPECT_FALSE(ValidateBracket(order).ok());
  Bracket one(s.bracket.begin(), s.bracket.begin() + 1);
  EXPECT_FALSE(ValidateBracket(one).ok());
}

TEST(BracketValidation, ABracketTooShortForTheSceneIsAnErrorNamingTheFrame) {
  // Every exposure far too long: most pixels saturate in all of them.
  cv::Mat truth = synth::SyntheticRadiance(120, 90);
  const Bracket b = synth::RenderBracket(truth, {10, 20, 40}, Response(), 3);
  auto map = MergeBracket(b, Recover(MakeScene().bracket), MergeOptions{});
  ASSERT_FALSE(map.ok());
  EXPECT_THAT(map.error().ToString(), HasSubstr(b[0].source));
}

TEST(ImageDecoding, TruncatedAndUnreadableFilesAreErrorsNamingTheFile) {
  const fs::path dir = fs::temp_directory_path() / ("rig_hdr_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  cv::Mat img(40, 50, CV_8UC3, cv::Scalar(10, 100, 200));
  const std::string good = (dir / "good.jpg").string(), cut = (dir / "cut.jpg").string(),
                    junk = (dir / "junk.jpg").string();
  ASSERT_TRUE(cv::imwrite(good, img));
  std::ifstream in(good, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), {});
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() * 2 / 3);
  std::ofstream(junk, std::ios::binary) << "not an image at all";
  EXPECT_TRUE(DecodeImage(good).ok());
  for (const std::string& p : {cut, junk, (dir / "missing.jpg").string()}) {
    auto r = DecodeImage(p);
    ASSERT_FALSE(r.ok()) << p;
    EXPECT_THAT(r.error().ToString(), HasSubstr(p));
  }
  fs::remove_all(dir);
}

TEST(ResponseStorage, SavedCurveLoadsBackWithItsIdAndATamperedOneIsRefused) {
  const ResponseCurve r = Recover(MakeScene(5).bracket);
  const fs::path p = fs::temp_directory_path() / ("rig_response_" + std::to_string(::getpid()) + ".csv");
  ASSERT_TRUE(SaveResponse(r, p.string()).ok());
  auto back = LoadResponse(p.string());
  ASSERT_TRUE(back.ok()) << back.error().ToString();
  EXPECT_EQ(back->id, r.id);
  EXPECT_EQ(back->id, ResponseId(r));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(back->log_exposure[c][200], r.log_exposure[c][200], 1e-9);
  // Change one value: the id no longer matches.
  std::ifstream in(p);
  std::string text((std::istreambuf_iterator<char>(in)), {});
  in.close();
  const size_t at = text.find("\n200,");
  ASSERT_NE(at, std::string::npos);
  const size_t digit = text.find(',', at + 5) - 6;  // a digit that matters
  text[digit] = text[digit] == '5' ? '6' : '5';
  std::ofstream(p, std::ios::trunc) << text;
  auto tampered = LoadResponse(p.string());
  ASSERT_FALSE(tampered.ok()) << text.substr(at, 60);
  EXPECT_EQ(tampered.error().code, ErrorCode::kCorrupt);
  fs::remove(p);
}

}  // namespace
}  // namespace rig
