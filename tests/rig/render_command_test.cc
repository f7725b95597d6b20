// `rig render` on a simulated session: additivity of lamps, exact colour scaling, refusal
// outside the sampled region, off-grid renders against the simulator's truth, an --exposure
// render against the frame the camera captured, and a sweep.
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "process/io/exr_io.h"
#include "sim/truth.h"
#include "tests/support/dry_session.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

class RenderCommand : public testing::DrySessionSuite<RenderCommand> {
 protected:
  // One small dry-run session (a matte scene plus broad gloss, no cast shadow) for all tests.
  static void SetUpTestSuite() {
    Capture("render", R"([sim]
width = 96
height = 72
scene = 'gloss'
)");
  }

  static cv::Mat Render(const std::string& lights, const std::string& name) {
    const std::string out = *dir_ + "/" + name + ".exr";
    auto r = RunRig("render " + *session_ + " " + lights + " --out " + out);
    EXPECT_EQ(r.status, 0) << r.output;
    auto img = ReadRgbExr(out);
    EXPECT_TRUE(img.ok());
    return img.ok() ? *img : cv::Mat();
  }

};

TEST_F(RenderCommand, TwoLampsRenderTheSumOfTheirSingleRenders) {
  cv::Mat a = Render("--light 20,10", "a"), b = Render("--light 75,25", "b");
  cv::Mat ab = Render("--light 20,10 --light 75,25", "ab");
  ASSERT_FALSE(ab.empty());
  const double scale = cv::norm(ab, cv::NORM_INF);
  ASSERT_GT(scale, 0);
  EXPECT_LT(cv::norm(a + b, ab, cv::NORM_INF), 1e-5 * scale);
}

TEST_F(RenderCommand, LampColourAndIntensityScaleEachChannelExactly) {
  cv::Mat white = Render("--light 45,20", "white");
  cv::Mat coloured = Render("--light 45,20,2,1,0.25,1.5", "coloured");  // R, G, B, intensity
  std::vector<cv::Mat> w, c;
  cv::split(white, w);
  cv::split(coloured, c);
  const double factor[3] = {0.25 * 1.5, 1 * 1.5, 2 * 1.5};  // B, G, R
  for (int ch = 0; ch < 3; ++ch) {
    const double scale = cv::norm(w[ch], cv::NORM_INF);
    ASSERT_GT(scale, 0);
    EXPECT_LT(cv::norm(c[ch], w[ch] * factor[ch], cv::NORM_INF), 1e-5 * scale * factor[ch]) << ch;
  }
}

TEST_F(RenderCommand, LampsOutsideTheSampledRegionAreRefusedUnlessAskedFor) {
  auto r = RunRig("render " + *session_ + " --light 150,60 --out " + *dir_ + "/out.png");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("outside the sampled region"));
  EXPECT_FALSE(fs::exists(*dir_ + "/out.png"));
  r = RunRig("render " + *session_ + " --light 150,60 --extrapolate --out " + *dir_ + "/out.png");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("warning"));
  // Nothing is overwritten.
  r = RunRig("render " + *session_ + " --light 45,20 --out " + *dir_ + "/out.png");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("exists"));
}

// Relative RMS error of a render against the true radiance, after the one global scale the
// HDR merge cannot know (the response curve is recovered up to a constant factor).
double RelativeRmsAgainstTruth(const cv::Mat& render, const cv::Mat& truth) {
  const double scale = render.dot(truth) / render.dot(render);
  return cv::norm(render * scale, truth, cv::NORM_L2) / cv::norm(truth, cv::NORM_L2);
}

TEST_F(RenderCommand, OffGridRendersAgreeWithTheSimulatorsTruth) {
  auto truth = LoadTruth(*session_ + "/truth");
  ASSERT_TRUE(truth.ok()) << truth.error().ToString();
  const std::array<double, 3> lamp = truth->lamp_radiance_rgb;
  double worst = 0;
  // On-grid poses first (for reference: the fit's own residual), then off-grid ones.
  for (auto [h, v] : {std::pair{40.0, 20.0}, {90.0, 0.0}, {15.0, 5.0}, {45.0, 15.0}, {65.0, 25.0},
                      {85.0, 5.0}}) {
    cv::Mat render = Render(fmt::format("--light {},{}", h, v), fmt::format("off_{}_{}", h, v));
    cv::Mat rho = truth->BrdfAtAngles(h, v);
    cv::Mat radiance;
    cv::multiply(rho, cv::Scalar(lamp[2], lamp[1], lamp[0]), radiance);
    const double err = RelativeRmsAgainstTruth(render, radiance);
    std::printf("off-grid lamp %g,%g: relative RMS error against truth %.4f\n", h, v, err);
    worst = std::max(worst, err);
  }
  EXPECT_LT(worst, 0.10);
  // For reference: the radiance map merged from the captured bracket against the truth.
  auto hdr = ReadRgbExr(*session_ + "/hdr/h040_v20.exr");
  auto exact = ReadRgbExr(*session_ + "/truth/radiance/h040_v20.exr");
  ASSERT_TRUE(hdr.ok() && exact.ok());
  std::printf("radiance map h040_v20 (merged from the bracket): relative RMS error %.4f\n",
              RelativeRmsAgainstTruth(*hdr, *exact));
}

TEST_F(RenderCommand, ExposureRenderOfAnOnGridPoseMatchesTheCapturedFrame) {
  // The captured frame of pose h040_v20 whose exposure is nearest 1/50 s.
  fs::path captured;
  double exposure = 0;
  for (const auto& e : fs::directory_iterator(*session_ + "/frames/h040_v20")) {
    const std::string name = e.path().stem().string();  // <index>_<exposure>
    const double t = std::stod(name.substr(name.find('_') + 1));
    if (captured.empty() || std::abs(std::log(t / 0.02)) < std::abs(std::log(exposure / 0.02)))
      captured = e.path(), exposure = t;
  }
  ASSERT_FALSE(captured.empty());
  const std::string out = *dir_ + "/exposure.png";
  auto r = RunRig(fmt::format("render {} --light 40,20 --exposure {} --out {}", *session_, exposure, out));
  ASSERT_EQ(r.status, 0) << r.output;
  cv::Mat rendered = cv::imread(out), frame = cv::imread(captured.string());
  ASSERT_EQ(rendered.size(), frame.size());
  cv::Mat diff;
  cv::absdiff(rendered, frame, diff);
  const double mean_abs = cv::mean(cv::mean(diff))[0];
  std::vector<uchar> d(diff.begin<uchar>(), diff.end<uchar>());
  std::nth_element(d.begin(), d.begin() + d.size() * 9 / 10, d.end());
  const int p90 = d[d.size() * 9 / 10];
  std::printf("exposure %g s render vs captured %s: mean |difference| %.2f levels, 90th "
              "percentile %d\n",
              exposure, captured.filename().c_str(), mean_abs, p90);
  // Sensor noise, JPEG and 8-bit quantisation, and the model's own fit error.
  EXPECT_LT(mean_abs, 4.0);
  EXPECT_LE(p90, 8);
  // And a different exposure gives a clearly different picture (the test can fail).
  const std::string out2 = *dir_ + "/exposure4.png";
  r = RunRig(fmt::format("render {} --light 40,20 --exposure {} --out {}", *session_, exposure * 4, out2));
  ASSERT_EQ(r.status, 0) << r.output;
  cv::absdiff(cv::imread(out2), frame, diff);
  EXPECT_GT(cv::mean(cv::mean(diff))[0], 3 * mean_abs);
}

TEST_F(RenderCommand, SweepWritesEveryFrameAndAVideo) {
  const std::string out = *dir_ + "/sweep.avi";
  auto r = RunRig("render " + *session_ + " --sweep 0,15:90,15:90,0 --frames 9 --out " + out);
  ASSERT_EQ(r.status, 0) << r.output;
  int frames = 0;
  for (const auto& e : fs::directory_iterator(*dir_ + "/sweep")) frames += e.path().extension() == ".png";
  EXPECT_EQ(frames, 9);
  cv::VideoCapture video(out);
  ASSERT_TRUE(video.isOpened());
  int read = 0;
  cv::Mat f;
  while (video.read(f)) ++read;
  EXPECT_EQ(read, 9);
  // The lamp moves: the first and last frames differ.
  cv::Mat first = cv::imread(*dir_ + "/sweep/frame_0000.png"), last = cv::imread(*dir_ + "/sweep/frame_0008.png");
  EXPECT_GT(cv::norm(first, last, cv::NORM_L1) / first.total(), 1.0);
}

TEST_F(RenderCommand, BadInputIsRefusedWithExitTwo) {
  EXPECT_EQ(RunRig("render " + *session_ + " --light 45 --out " + *dir_ + "/x.png").status, 2);
  EXPECT_EQ(RunRig("render " + *session_ + " --light 45,20 --out " + *dir_ + "/x.bmp").status, 2);
  EXPECT_EQ(RunRig("render " + *session_ + " --light 45,20 --exposure 0.1 --tonemap ward --out " +
                   *dir_ + "/x.png").status, 2);
  auto r = RunRig("render " + *dir_ + "/nope --light 45,20 --out " + *dir_ + "/x.png");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("nope"));
}

}  // namespace
}  // namespace rig
