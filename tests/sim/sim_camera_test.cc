// The simulated camera against its own truth: response, merge accuracy, noise, determinism,
// shutter speeds, faults and the rig-rule violations it counts.
#include "sim/sim_camera.h"

#include <cmath>
#include <set>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "capture/plan/bracket.h"
#include "process/model/light_direction.h"

namespace rig {
namespace {

Config SmallConfig() {
  Config c;
  c.sim.width = 160;
  c.sim.height = 120;
  c.bracket.center_s = 0.02;
  c.bracket.ev_step = 1;
  c.bracket.count = 7;
  return c;
}

struct Rig {
  std::shared_ptr<SimWorld> world = std::make_shared<SimWorld>();
  std::unique_ptr<SimCamera> camera;
};

Rig MakeRig(const Config& config, double h = 30, double v = 10) {
  Rig r;
  auto cam = SimCamera::Create(config, r.world);
  EXPECT_TRUE(cam.ok()) << cam.error().ToString();
  r.camera = std::move(cam).value();
  EXPECT_TRUE(r.camera->Open().ok());
  r.world->SetPose(h, v);
  r.world->SetLamp(true);
  r.world->SetLampReady();
  return r;
}

std::vector<Seconds> Bracket(SimCamera& cam, const BracketConfig& b) {
  auto speeds = cam.ShutterSpeeds();
  EXPECT_TRUE(speeds.ok());
  auto snapped = SnapToShutterSpeeds(WantedExposures(b), *speeds);
  EXPECT_TRUE(snapped.ok()) << snapped.error().ToString();
  return *snapped;
}

cv::Mat Decode(const CapturedFrame& f) {
  return cv::imdecode(f.files.at(0).bytes, cv::IMREAD_UNCHANGED);
}

TEST(SimResponse, EveryCurveIsIncreasingAndQuantizeAgreesWithItsBins) {
  for (const char* kind : {"filmic", "gamma", "linear"}) {
    SimCameraConfig k;
    k.response = kind;
    auto r = SimResponse::Create(k);
    ASSERT_TRUE(r.ok());
    for (int c = 0; c < 3; ++c) {
      for (int z = 1; z < 256; ++z) ASSERT_GT(r->LogExposure(c, z), r->LogExposure(c, z - 1));
      for (int z = 0; z < 256; ++z) {
        const double x = std::exp(r->LogExposure(c, z)) / r->saturation_exposure();
        // g(z) is the exposure of level z, and lies inside its own bin.
        ASSERT_EQ(r->Quantize(c, static_cast<float>(x)), z) << kind << " c" << c << " z" << z;
        ASSERT_LE(r->LogExposureLow(c, z), r->LogExposure(c, z));
        ASSERT_GE(r->LogExposureHigh(c, z), r->LogExposure(c, z));
        // Just inside each edge of the bin the level is z.
        if (z > 0) {
          float lo = static_cast<float>(std::exp(r->LogExposureLow(c, z)) / r->saturation_exposure());
          ASSERT_EQ(r->Quantize(c, lo), z);
          ASSERT_EQ(r->Quantize(c, std::nextafter(lo, 0.f)), z - 1);
        }
      }
    }
    EXPECT_NEAR(r->LogExposure(1, 255), std::log(20000.0), 1e-12);
  }
}

TEST(SimResponse, FilmicIsNotAGammaCurveAndDiffersPerChannel) {
  SimCameraConfig k;
  auto r = SimResponse::Create(k);
  ASSERT_TRUE(r.ok());
  // A gamma curve is a straight line in (ln x, ln f); the filmic toe and shoulder bend it.
  auto slope = [&](int c, double x0, double x1) {
    return (std::log(r->Encode(c, x1)) - std::log(r->Encode(c, x0))) / std::log(x1 / x0);
  };
  for (int c = 0; c < 3; ++c) EXPECT_GT(slope(c, 1e-4, 2e-4) / slope(c, 0.5, 1.0), 2.0);
  EXPECT_GT(std::fabs(r->Encode(0, 0.01) - r->Encode(1, 0.01)), 0.005);
  EXPECT_GT(std::fabs(r->Encode(2, 0.01) - r->Encode(1, 0.01)), 0.005);
  auto again = SimResponse::FromJson(r->ToJson());
  ASSERT_TRUE(again.ok());
  for (int z = 0; z < 256; ++z) EXPECT_EQ(again->LogExposure(2, z), r->LogExposure(2, z));
}

// Noise off and PNG: the merge of the bracket through the KNOWN inverse response (the
// Debevec-Malik weighted average of g(z) - ln t with hat weights) recovers the true radiance
// to quantisation accuracy: for every pixel, |ln merged - ln true| is at most the weighted
// mean of the half-widths of the level bins it was recorded in.
void CheckMergeRecoversRadiance(const std::string& response) {
  Config config = SmallConfig();
  config.sim.camera.shot_noise = false;
  config.sim.camera.read_noise_e = 0;
  config.sim.camera.format = "png";
  config.sim.camera.response = response;
  Rig rig = MakeRig(config, 30, 10);
  std::vector<Seconds> times = Bracket(*rig.camera, config.bracket);
  std::vector<cv::Mat> frames;
  for (Seconds t : times) {
    auto f = rig.camera->Capture(t);
    ASSERT_TRUE(f.ok()) << f.error().ToString();
    EXPECT_EQ(f->exposure, t);
    frames.push_back(Decode(*f));
    ASSERT_EQ(frames.back().type(), CV_8UC3);
  }
  const SimResponse& g = rig.camera->response();
  cv::Mat truth = rig.camera->scene().Radiance(LightDirection(30, 10, config.light_frame),
                                               config.lamp.radiance_rgb);
  int merged = 0, well = 0;
  double sum_rel = 0, max_rel = 0;
  for (int j = 0; j < truth.rows; ++j)
    for (int i = 0; i < truth.cols; ++i)
      for (int c = 0; c < 3; ++c) {
        double num = 0, den = 0, bound = 0, best_w = 0;
        for (size_t k = 0; k < frames.size(); ++k) {
          const int z = frames[k].at<cv::Vec3b>(j, i)[c];
          const double w = std::min(z, 255 - z);
          if (w <= 0) continue;
          const double gz = g.LogExposure(c, z);
          num += w * (gz - std::log(times[k].count()));
          den += w;
          bound += w * std::max(gz - g.LogExposureLow(c, z), g.LogExposureHigh(c, z) - gz);
          best_w = std::max(best_w, w);
        }
        const double l_true = truth.at<cv::Vec3f>(j, i)[c];
        if (den == 0) continue;
        ASSERT_GT(l_true, 0) << "a black pixel got a level";
        const double err = std::fabs(num / den - std::log(l_true));
        ASSERT_LE(err, bound / den + 1e-4) << response << " " << i << "," << j << " c" << c;
        ++merged;
        if (best_w >= 40) {  // well exposed: some frame put it at a level in [40, 215]
          const double rel = std::fabs(std::exp(num / den) / l_true - 1);
          sum_rel += rel;
          max_rel = std::max(max_rel, rel);
          ++well;
        }
      }
  EXPECT_GT(well, truth.rows * truth.cols * 3 * 8 / 10) << response;
  EXPECT_LT(sum_rel / well, 0.005) << response;
  EXPECT_LT(max_rel, 0.03) << response;
  std::printf("[ %s ] merged %d, well exposed %d: mean rel. error %.4f%%, max %.3f%%\n",
              response.c_str(), merged, well, 100 * sum_rel / well, 100 * max_rel);
}

TEST(SimCamera, MergeThroughKnownFilmicResponseRecoversRadianceToQuantisationAccuracy) {
  CheckMergeRecoversRadiance("filmic");
}
TEST(SimCamera, MergeThroughKnownGammaResponseRecoversRadianceToQuantisationAccuracy) {
  CheckMergeRecoversRadiance("gamma");
}

TEST(SimCamera, SameSeedAndCaptureSequenceGiveIdenticalBytes) {
  Config config = SmallConfig();
  Rig a = MakeRig(config), b = MakeRig(config);
  config.sim.seed = 2;
  Rig c = MakeRig(config);
  std::vector<Seconds> times = Bracket(*a.camera, config.bracket);
  int differ_seed = 0;
  for (Seconds t : times) {
    auto fa = a.camera->Capture(t), fb = b.camera->Capture(t), fc = c.camera->Capture(t);
    ASSERT_TRUE(fa.ok() && fb.ok() && fc.ok());
    EXPECT_EQ(fa->files[0].bytes, fb->files[0].bytes);
    differ_seed += fa->files[0].bytes != fc->files[0].bytes;
    EXPECT_EQ(fa->files[0].extension, "jpg");
    ASSERT_GE(fa->files[0].bytes.size(), 2u);
    EXPECT_EQ(fa->files[0].bytes[0], 0xff);
    EXPECT_EQ(fa->files[0].bytes[1], 0xd8);
    ASSERT_TRUE(fa->exif_exposure.has_value());
    EXPECT_EQ(*fa->exif_exposure, t);
  }
  EXPECT_EQ(differ_seed, static_cast<int>(times.size()));
}

TEST(SimCamera, NoiseHasTheShotAndReadNoiseVariance) {
  Config config = SmallConfig();
  config.sim.camera.response = "linear";
  config.sim.camera.format = "png";
  config.sim.camera.full_well = 2000;
  config.sim.camera.read_noise_e = 10;
  Rig rig = MakeRig(config);
  // A flat 800-electron field (level 102.0): sigma = sqrt(800 + 10^2) e = 30 e = 3.8 levels.
  cv::Mat flat(120, 160, CV_32FC3, cv::Scalar::all(800.0 / 0.01));
  cv::Mat img = rig.camera->Expose(flat, Seconds(0.01), 7);
  cv::Scalar mean, sd;
  cv::meanStdDev(img.reshape(1), mean, sd);
  const double want = std::sqrt(900.0) / 2000 * 255;
  EXPECT_NEAR(mean[0], 102.0, 0.1);
  EXPECT_NEAR(sd[0], std::sqrt(want * want + 1.0 / 12), 0.03 * want);
  // Without noise the field is one level.
  config.sim.camera.shot_noise = false;
  config.sim.camera.read_noise_e = 0;
  Rig quiet = MakeRig(config);
  cv::meanStdDev(quiet.camera->Expose(flat, Seconds(0.01), 7).reshape(1), mean, sd);
  EXPECT_EQ(sd[0], 0.0);
  EXPECT_EQ(mean[0], 102.0);  // 255 * 0.4
}

TEST(SimCamera, DefaultBracketSaturatesTheGlossAndRecordsTheDarkestLitTexture) {
  Config config = SmallConfig();  // the default camera and the default bracket
  Rig rig = MakeRig(config, 0, 0);
  std::vector<Seconds> times = Bracket(*rig.camera, config.bracket);
  ASSERT_EQ(times.size(), 7u);
  EXPECT_NEAR(times.front().count(), 1.0 / 400, 1e-12);
  EXPECT_NEAR(times.back().count(), 1.0 / 6, 1e-12);
  cv::Mat truth = rig.camera->scene().Radiance({0, 0, 1}, {1, 1, 1});
  cv::Point peak;
  double max_l;
  cv::minMaxLoc(truth.reshape(1), nullptr, &max_l, nullptr, &peak);
  const int pi = peak.x / 3, pj = peak.y, pc = peak.x % 3;
  auto shortest = rig.camera->Capture(times.front()), longest = rig.camera->Capture(times.back());
  ASSERT_TRUE(shortest.ok() && longest.ok());
  cv::Mat s = Decode(*shortest), l = Decode(*longest);
  EXPECT_EQ(l.at<cv::Vec3b>(pj, pi)[pc], 255) << "gloss peak saturates the longest exposure";
  EXPECT_LT(s.at<cv::Vec3b>(pj, pi)[pc], 240) << "and is recorded by the shortest";

  // Grazing light from the right: the dark checker texture of the plane is the darkest lit
  // surface; the longest exposure records it well above the read noise.
  Rig grazing = MakeRig(config, 90, 0);
  cv::Mat rho = grazing.camera->scene().Radiance(LightDirection(90, 0), {1, 1, 1});
  cv::Mat ids = grazing.camera->scene().MaterialIds();
  double min_plane = 1e30;
  cv::Point dark;
  for (int j = 0; j < rho.rows; ++j)
    for (int i = 0; i < rho.cols; ++i)
      if (ids.at<uint8_t>(j, i) == 0 && rho.at<cv::Vec3f>(j, i)[1] > 0 &&
          rho.at<cv::Vec3f>(j, i)[1] < min_plane)
        min_plane = rho.at<cv::Vec3f>(j, i)[1], dark = {i, j};
  auto frame = grazing.camera->Capture(times.back());
  ASSERT_TRUE(frame.ok());
  EXPECT_GE(Decode(*frame).at<cv::Vec3b>(dark)[1], 20);
  // ~3.5 decades between the gloss peak and the darkest lit texture.
  EXPECT_GT(std::log10(max_l / min_plane), 3.0);
}

TEST(SimCamera, OffersThirdStopSpeedsAndRefusesOthers) {
  Config config = SmallConfig();
  Rig rig = MakeRig(config);
  auto speeds = rig.camera->ShutterSpeeds();
  ASSERT_TRUE(speeds.ok());
  EXPECT_NEAR(speeds->front().count(), 1.0 / 8000, 1e-12);
  EXPECT_NEAR(speeds->back().count(), 30, 1e-12);
  EXPECT_EQ(speeds->size(), 55u);  // 1/8000 .. 30 s in third stops
  auto bad = rig.camera->Capture(Seconds(0.021));
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code, ErrorCode::kInvalidInput);
  EXPECT_NE(bad.error().ToString().find("sim camera"), std::string::npos);
  EXPECT_NE(bad.error().message.find("0.021"), std::string::npos);
  EXPECT_EQ(rig.camera->stats().attempts, 0);
  EXPECT_TRUE(rig.camera->Capture(Seconds(1.0 / 125)).ok());
  rig.camera->Close();
  auto closed = rig.camera->Capture(Seconds(1.0 / 125));
  ASSERT_FALSE(closed.ok());
  EXPECT_EQ(closed.error().code, ErrorCode::kDevice);
}

// Runs `n` captures; returns the numbers (from 1) that failed, with their codes.
std::map<int, ErrorCode> Failures(const Config& config, int n, bool reopen_after_failure = false) {
  Rig rig = MakeRig(config);
  std::map<int, ErrorCode> out;
  for (int k = 1; k <= n; ++k) {
    auto f = rig.camera->Capture(Seconds(1.0 / 125));
    if (!f.ok()) {
      out[k] = f.error().code;
      EXPECT_EQ(f.error().context, "sim camera");
      if (reopen_after_failure) {
        EXPECT_TRUE(rig.camera->Open().ok());
      }
    }
  }
  EXPECT_EQ(rig.camera->stats().faults, static_cast<int64_t>(out.size()));
  EXPECT_EQ(rig.camera->stats().captures, n - static_cast<int64_t>(out.size()));
  return out;
}

TEST(SimCamera, EachConfiguredFaultFiresThenAndAtNoOtherTime) {
  Config config = SmallConfig();
  config.sim.width = 32;
  config.sim.height = 24;
  EXPECT_TRUE(Failures(config, 20).empty());

  Config at = config;
  at.sim.camera.fail_capture_at = {2, 5};
  EXPECT_EQ(Failures(at, 20), (std::map<int, ErrorCode>{{2, ErrorCode::kDevice}, {5, ErrorCode::kDevice}}));

  Config every = config;
  every.sim.camera.fail_capture_every = 7;
  EXPECT_EQ(Failures(every, 20),
            (std::map<int, ErrorCode>{{7, ErrorCode::kTimeout}, {14, ErrorCode::kTimeout}}));

  Config forever = config;
  forever.sim.camera.fail_forever_after = 18;
  EXPECT_EQ(Failures(forever, 20),
            (std::map<int, ErrorCode>{{18, ErrorCode::kDevice}, {19, ErrorCode::kDevice},
                                      {20, ErrorCode::kDevice}}));

  Config disconnect = config;
  disconnect.sim.camera.disconnect_at = 4;
  disconnect.sim.camera.disconnect_captures = 3;
  auto d = Failures(disconnect, 20, /*reopen_after_failure=*/true);
  EXPECT_EQ(d, (std::map<int, ErrorCode>{{4, ErrorCode::kDevice}, {5, ErrorCode::kDevice},
                                         {6, ErrorCode::kDevice}}));
  // Without reopening the body comes back too.
  EXPECT_EQ(Failures(disconnect, 20).size(), 3u);
  Rig rig = MakeRig(disconnect);
  for (int k = 1; k < 4; ++k) ASSERT_TRUE(rig.camera->Capture(Seconds(0.01)).ok());
  auto e = rig.camera->Capture(Seconds(0.01));
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.error().message.find("disconnected"), std::string::npos);
}

TEST(SimCamera, CaptureWithTheLampOffIsDarkAndCountedAsAViolation) {
  Config config = SmallConfig();
  Rig rig = MakeRig(config);
  auto lit = rig.camera->Capture(Seconds(0.02));
  ASSERT_TRUE(lit.ok());
  EXPECT_EQ(rig.world->State().violations(), 0);
  rig.world->SetLamp(false);
  auto dark = rig.camera->Capture(Seconds(0.02));
  ASSERT_TRUE(dark.ok());
  EXPECT_EQ(rig.world->State().captures_lamp_off, 1);
  cv::Mat img = Decode(*dark);
  double max_v;
  cv::minMaxLoc(img.reshape(1), nullptr, &max_v);
  EXPECT_LT(cv::mean(img.reshape(1))[0], 10);  // read noise only
  EXPECT_LT(max_v, 40);
  EXPECT_GT(cv::mean(Decode(*lit).reshape(1))[0], 60);
  // Firing while the arm moves or before the lamp warmed up counts too.
  rig.world->SetLamp(true);
  ASSERT_TRUE(rig.camera->Capture(Seconds(0.02)).ok());
  EXPECT_EQ(rig.world->State().captures_during_warmup, 1);
  rig.world->SetLampReady();
  rig.world->SetMoving(true);
  ASSERT_TRUE(rig.camera->Capture(Seconds(0.02)).ok());
  rig.world->SetMoving(false);
  const SimWorldState s = rig.world->State();
  EXPECT_EQ(s.captures_while_moving, 1);
  EXPECT_EQ(s.violations(), 3);
  EXPECT_EQ(s.captures, 4);
}

TEST(SimCamera, RendersTheWorldsPoseThroughTheLightFrame) {
  Config config = SmallConfig();
  config.sim.camera.shot_noise = false;
  config.sim.camera.read_noise_e = 0;
  config.sim.camera.format = "png";
  config.light_frame.h_sign = -1;
  config.light_frame.h_offset_deg = 60;  // commanded h 20 is physical h 40
  Rig rig = MakeRig(config, 20, 10);
  auto f = rig.camera->Capture(Seconds(0.02));
  ASSERT_TRUE(f.ok());
  cv::Mat want = rig.camera->Expose(
      rig.camera->scene().Radiance(LightDirection(40, 10), config.lamp.radiance_rgb),
      Seconds(0.02), 0);
  EXPECT_EQ(cv::norm(Decode(*f), want, cv::NORM_INF), 0.0);
}

}  // namespace
}  // namespace rig

namespace rig {
namespace {

// Live view: auto-exposed (the brightest 1% near 80% of full well: bright but hardly
// clipped), at most kPreviewLongSide on the long side, deterministic, and not a capture.
TEST(SimCameraPreview, IsAutoExposedSmallDeterministicAndNotCounted) {
  Config c = SmallConfig();
  c.sim.width = 1280;
  c.sim.height = 960;
  c.sim.camera.fail_capture_at = {1};  // a capture fault must not touch the preview
  Rig r = MakeRig(c);
  auto a = r.camera->CapturePreview();
  ASSERT_TRUE(a.ok()) << a.error().ToString();
  auto b = r.camera->CapturePreview();
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(a->bytes, b->bytes);
  EXPECT_EQ(a->extension, "jpg");
  cv::Mat img = cv::imdecode(a->bytes, cv::IMREAD_COLOR);
  ASSERT_EQ(img.cols, SimCamera::kPreviewLongSide);
  EXPECT_EQ(img.rows, SimCamera::kPreviewLongSide * 3 / 4);
  std::vector<uint8_t> brightest;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const auto p = img.at<cv::Vec3b>(y, x);
      brightest.push_back(std::max({p[0], p[1], p[2]}));
    }
  std::sort(brightest.begin(), brightest.end());
  const int p99 = brightest[brightest.size() * 99 / 100];
  EXPECT_GT(p99, 200);  // the filmic curve puts 80% of full well high, below the clip
  EXPECT_LT(p99, 255);
  EXPECT_EQ(r.camera->stats().attempts, 0);
  EXPECT_EQ(r.camera->stats().captures, 0);

  r.world->SetLamp(false);
  auto dark = r.camera->CapturePreview();
  ASSERT_TRUE(dark.ok());
  cv::Mat d = cv::imdecode(dark->bytes, cv::IMREAD_GRAYSCALE);
  EXPECT_LT(cv::mean(d)[0], 10);
}

TEST(SimCameraPreview, IsRefusedBeforeOpen) {
  auto world = std::make_shared<SimWorld>();
  auto cam = SimCamera::Create(SmallConfig(), world);
  ASSERT_TRUE(cam.ok());
  auto p = (*cam)->CapturePreview();
  ASSERT_FALSE(p.ok());
  EXPECT_NE(p.error().ToString().find("sim camera"), std::string::npos) << p.error().ToString();
}

}  // namespace
}  // namespace rig
