// RAW frames through LibRaw: DNG files from the simulator's writer (a Bayer mosaic and
// LinearRaw) decode to the linear values they hold; clipped photosites are masked; a RAW
// bracket merges without response recovery, close to a maximum-likelihood merge through the
// true noise and well ahead of the JPEG path of the same scene.
#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgcodecs.hpp>

#include "process/hdr/hdr.h"
#include "process/io/image_io.h"
#include "process/io/raw_io.h"
#include "sim/bracket_synth.h"
#include "sim/dng_writer.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

cv::Mat Flat(int w, int h, uint16_t b, uint16_t g, uint16_t r) {
  return cv::Mat(h, w, CV_16UC3, cv::Scalar(b, g, r));
}

cv::Mat Decode(const cv::Mat& sensor, const DngOptions& o, const RawDecodeOptions& ro = {},
               RawInfo* info = nullptr) {
  auto bytes = EncodeDng(sensor, o);
  EXPECT_TRUE(bytes.ok()) << bytes.error().ToString();
  auto img = DecodeRawBytes(*bytes, "frame.dng", ro, info);
  EXPECT_TRUE(img.ok()) << img.error().ToString();
  return img.ok() ? *img : cv::Mat();
}

TEST(RawDecode, LinearRawValuesAreBlackSubtractedAndScaledToTheWhiteLevel) {
  DngOptions o;
  o.mosaic = false;
  o.black = 512;
  o.white = 15000;
  RawDecodeOptions none;
  none.white_balance = RawWhiteBalance::kNone;
  RawInfo info;
  const cv::Mat img = Decode(Flat(64, 48, 1000, 4000, 9000), o, none, &info);
  ASSERT_EQ(img.type(), CV_16UC3);
  EXPECT_EQ(info.black, 512);
  EXPECT_EQ(info.white, 15000);
  EXPECT_FALSE(info.mosaic);
  const cv::Vec3w p = img.at<cv::Vec3w>(20, 30);
  const double scale = 65535.0 / (15000 - 512);
  EXPECT_NEAR(p[0], (1000 - 512) * scale, 2);
  EXPECT_NEAR(p[1], (4000 - 512) * scale, 2);
  EXPECT_NEAR(p[2], (9000 - 512) * scale, 2);
}

TEST(RawDecode, CameraWhiteBalanceComesFromAsShotNeutral) {
  DngOptions o;
  o.mosaic = false;
  o.as_shot_neutral[0] = 0.5;  // red records half of a neutral: x2
  o.as_shot_neutral[2] = 0.8;  // blue: x1.25
  const cv::Mat img = Decode(Flat(32, 32, 8000, 10000, 5000), o);
  const cv::Vec3w p = img.at<cv::Vec3w>(16, 16);
  EXPECT_NEAR(double(p[2]) / p[1], 2 * 0.5, 0.01);   // red: 5000 x 2 against green 10000
  EXPECT_NEAR(double(p[0]) / p[1], 1.25 * 0.8, 0.01);
}

TEST(RawDecode, BayerMosaicDemosaicsAndMasksClippedPhotosites) {
  DngOptions o;
  o.black = 256;
  o.white = 16383;
  cv::Mat sensor = Flat(64, 64, 3000, 5000, 7000);
  sensor(cv::Rect(40, 40, 8, 8)).setTo(cv::Scalar(16383, 16383, 16383));  // a clipped highlight
  RawDecodeOptions none;
  none.white_balance = RawWhiteBalance::kNone;
  RawInfo info;
  const cv::Mat img = Decode(sensor, o, none, &info);
  EXPECT_TRUE(info.mosaic);
  EXPECT_NEAR(info.clipped_fraction, 64.0 / (64 * 64), 1e-9);
  const double scale = 65535.0 / (16383 - 256);
  const cv::Vec3w flat = img.at<cv::Vec3w>(10, 10);  // far from the highlight: exact colours
  EXPECT_NEAR(flat[0], (3000 - 256) * scale, 0.01 * (3000 - 256) * scale);
  EXPECT_NEAR(flat[1], (5000 - 256) * scale, 0.01 * (5000 - 256) * scale);
  EXPECT_NEAR(flat[2], (7000 - 256) * scale, 0.01 * (7000 - 256) * scale);
  // Inside the highlight and one pixel around it: every channel at the top.
  for (int y : {39, 44, 48}) {
    for (int x : {39, 44, 48}) {
      const cv::Vec3w p = img.at<cv::Vec3w>(y, x);
      EXPECT_EQ(p[0], 65535) << x << "," << y;
      EXPECT_EQ(p[1], 65535) << x << "," << y;
      EXPECT_EQ(p[2], 65535) << x << "," << y;
    }
  }
  EXPECT_LT(img.at<cv::Vec3w>(36, 36)[1], 65535);
}

TEST(RawDecode, DamagedFilesAreErrorsNamingTheFile) {
  DngOptions o;
  auto bytes = EncodeDng(Flat(32, 32, 100, 200, 300), o);
  ASSERT_TRUE(bytes.ok());
  std::vector<uint8_t> cut(bytes->begin(), bytes->begin() + 200);
  auto r = DecodeRawBytes(cut, "cut.dng");
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().ToString().find("cut.dng"), std::string::npos) << r.error().ToString();
  EXPECT_EQ(r.error().ExitCode(), 2);
  std::vector<uint8_t> junk(4096, 0x5a);
  auto j = DecodeRawBytes(junk, "junk.nef");
  ASSERT_FALSE(j.ok());
  EXPECT_NE(j.error().ToString().find("junk.nef"), std::string::npos);
  // By name: a .dng goes to LibRaw even through the generic decoder.
  std::vector<uchar> generic(bytes->begin(), bytes->end());
  auto g = DecodeImageBytes(generic, "frame.DNG");
  ASSERT_TRUE(g.ok()) << g.error().ToString();
  EXPECT_EQ(g->type(), CV_16UC3);
}

// A simulated RAW sensor: electrons X = E t k with shot and read noise, DN = X / gain + black,
// clipped at white; written as DNG and decoded back.
struct Sensor {
  double k = 2000;         // electrons per unit radiance-second
  double gain = 2.0;       // electrons per DN
  double read_e = 6.0;     // read noise, electrons
  uint16_t black = 512, white = 16383;
};

Bracket RawBracket(const cv::Mat& radiance, const std::vector<double>& times, const Sensor& s,
                   bool mosaic, uint64_t seed) {
  Bracket frames;
  for (size_t j = 0; j < times.size(); ++j) {
    cv::RNG rng(seed * 131 + j);
    cv::Mat dn(radiance.size(), CV_16UC3);
    for (int y = 0; y < radiance.rows; ++y) {
      const float* e = radiance.ptr<float>(y);
      uint16_t* o = dn.ptr<uint16_t>(y);
      for (int i = 0; i < radiance.cols * 3; ++i) {
        const double x = e[i] * times[j] * s.k;
        const double n = rng.gaussian(std::sqrt(x + s.read_e * s.read_e));
        o[i] = uint16_t(std::clamp(std::round((x + n) / s.gain + s.black), 0.0, double(s.white)));
      }
    }
    DngOptions o;
    o.mosaic = mosaic;
    o.black = s.black;
    o.white = s.white;
    o.exposure_s = times[j];
    auto bytes = EncodeDng(dn, o);
    EXPECT_TRUE(bytes.ok());
    RawDecodeOptions none;
    none.white_balance = RawWhiteBalance::kNone;
    auto img = DecodeRawBytes(*bytes, "f" + std::to_string(j) + ".dng", none);
    EXPECT_TRUE(img.ok()) << img.error().ToString();
    frames.push_back({*img, Seconds(times[j]), "f" + std::to_string(j) + ".dng"});
  }
  return frames;
}

// Maximum likelihood through the true noise (Gaussian, variance a*mu + (a*read)^2 in decoded
// units): iteratively reweighted least squares per pixel-channel, clipped and zero samples
// (censored) left out.
cv::Mat MaximumLikelihoodMerge(const Bracket& b, const Sensor& s) {
  const double a = 65535.0 / ((s.white - s.black) * s.gain);  // decoded units per electron
  cv::Mat out(b[0].image.size(), CV_32FC3, cv::Scalar::all(0));
  for (int y = 0; y < out.rows; ++y) {
    float* o = out.ptr<float>(y);
    for (int i = 0; i < out.cols * 3; ++i) {
      double r = -1;
      for (int iter = 0; iter < 6; ++iter) {
        double num = 0, den = 0;
        for (const auto& f : b) {
          const double d = f.image.ptr<uint16_t>(y)[i];
          if (d >= 65535 || d <= 0) continue;
          const double t = f.exposure.count();
          const double mu = r > 0 ? r * t : d;
          const double var = a * std::max(mu, 1.0) + a * a * s.read_e * s.read_e;
          num += t * d / var;
          den += t * t / var;
        }
        if (den <= 0) break;
        r = num / den;
      }
      o[i] = float(std::max(r, 1e-12));
    }
  }
  return out;
}

TEST(RawBracket, MergesWithoutResponseRecoveryNearTheMaximumLikelihoodMerge) {
  const cv::Mat truth = synth::SyntheticRadiance(192, 144);
  const std::vector<double> times = synth::ExposuresFor(0.01, 300.0, 5);
  const Sensor s;
  for (bool mosaic : {false, true}) {
    const Bracket raw = RawBracket(truth, times, s, mosaic, 3);
    MergeOptions mo;
    mo.weighting = MergeWeighting::kNoise;
    mo.max_unrecorded_fraction = 1.0;
    auto map = MergeBracket(raw, LinearResponse(65536), mo);
    ASSERT_TRUE(map.ok()) << map.error().ToString();
    const double ours = synth::LogRmsError(map->radiance, truth, raw);
    const double ml = synth::LogRmsError(MaximumLikelihoodMerge(raw, s), truth, raw);
    std::printf("RAW %s: log-radiance RMS, noise-model merge %.4f, ML through the true noise %.4f\n",
                mosaic ? "Bayer" : "LinearRaw", ours, ml);
    if (!mosaic) {
      EXPECT_LE(ours, 1.05 * ml);  // the response-free merge within 5% of maximum likelihood
    } else {
      EXPECT_LE(ours, 1.25 * ml);  // demosaicing adds the same error to both (edges)
    }
    // The JPEG path of the same scene and exposures: 8 bits through a recovered response.
    if (!mosaic) {
      const synth::FilmicResponse film;
      const Bracket jpeg = synth::RenderBracket(truth, times, film, 3);
      const Bracket one[1] = {jpeg};
      auto resp = RecoverResponse(one, ResponseOptions{});
      ASSERT_TRUE(resp.ok());
      auto jmap = MergeBracket(jpeg, *resp, mo);
      ASSERT_TRUE(jmap.ok());
      const double j = synth::LogRmsError(jmap->radiance, truth, jpeg);
      std::printf("8-bit path of the same scene: %.4f\n", j);
      EXPECT_LT(ours, j);
    }
  }
}

TEST(RawBracket, RigHdrMergesADngBracketWithoutResponseRecovery) {
  const std::string dir = testing::FreshTempDir("raw_hdr");
  const cv::Mat truth = synth::SyntheticRadiance(96, 64);
  const std::vector<double> times = synth::ExposuresFor(0.01, 300.0, 4);
  std::string list;
  for (size_t j = 0; j < times.size(); ++j) {
    cv::Mat dn(truth.size(), CV_16UC3);
    truth.convertTo(dn, CV_16UC3, times[j] * 1000, 512);
    DngOptions o;
    o.black = 512;
    o.white = 16383;
    cv::min(dn, cv::Scalar::all(16383), dn);
    auto bytes = EncodeDng(dn, o);
    ASSERT_TRUE(bytes.ok());
    const std::string name = dir + "/f" + std::to_string(j) + ".dng";
    FILE* f = std::fopen(name.c_str(), "wb");
    ASSERT_NE(f, nullptr);
    std::fwrite(bytes->data(), 1, bytes->size(), f);
    std::fclose(f);
    list += name + " " + std::to_string(times[j]) + "\n";
  }
  FILE* l = std::fopen((dir + "/list.txt").c_str(), "w");
  std::fputs(list.c_str(), l);
  std::fclose(l);
  auto r = testing::RunRig("hdr --list " + dir + "/list.txt --out " + dir + "/out.exr 2>&1");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("linear"), std::string::npos) << r.output;
  // A bracket mixing RAW and (16-bit) PNG frames has no one response.
  cv::Mat png(truth.size(), CV_16UC3, cv::Scalar::all(10000));
  ASSERT_TRUE(cv::imwrite(dir + "/x.png", png));
  FILE* m = std::fopen((dir + "/mixed.txt").c_str(), "w");
  std::fprintf(m, "%s/f0.dng 0.01\n%s/x.png 0.02\n", dir.c_str(), dir.c_str());
  std::fclose(m);
  auto mixed = testing::RunRig("hdr --list " + dir + "/mixed.txt --out " + dir + "/m.exr 2>&1");
  EXPECT_EQ(mixed.status, 2) << mixed.output;
  EXPECT_NE(mixed.output.find("all RAW or none"), std::string::npos) << mixed.output;
}

}  // namespace
}  // namespace rig
