// `rig export`: an EXR model to relight's web format, .ptm (RGB, LRGB) and .rti, each rendered
// by `rig render` as the EXR renders; refits print the PSNR lost; refusals exit 2 naming the file.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/harmonic/model.h"
#include "process/model/harmonic/loo.h"
#include "tests/support/run_rig.h"
#include "tests/support/synthetic_model.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

// A smooth 48x32 model in sRGB fit space, sampled on h 0-90, v 0-30 (10° steps).
std::string WriteModel(const std::string& dir, BasisKind kind, int order, FitSpace space) {
  ModelInfo info = testing::DefaultGridInfo();
  info.method = FitMethod::kLs;
  info.transform.space = space;
  Model m(Basis(kind, order), info, 48, 32);
  const double b0 = m.basis().Eval(Vec3{0, 0, 1})[0];
  for (int k = 0; k < m.basis().size(); ++k) {
    cv::Mat c(32, 48, CV_32FC3);
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 48; ++x)
        for (int ch = 0; ch < 3; ++ch)
          c.at<cv::Vec3f>(y, x)[ch] =
              k == 0 ? static_cast<float>((0.4 + 0.2 * std::sin(x / 6.0 + ch) * std::cos(y / 5.0)) / b0)
                     : static_cast<float>(0.05 * std::sin(x / (4.0 + k) + ch) * std::cos(y / 7.0));
    m.coefficients().push_back(c);
  }
  const std::string path = dir + "/" + BasisKindName(kind) + std::to_string(order) + ".exr";
  EXPECT_TRUE(SaveModel(path, m, ExrPixelType::kFloat).ok());
  return path;
}

// The linear radiance `rig render` writes, as 8-bit sRGB values (float, clamped).
cv::Mat RenderSrgb(const std::string& model, const std::string& out) {
  auto r = RunRig("render " + model + " --light 40,15 --out " + out);
  EXPECT_EQ(r.status, 0) << r.output;
  auto img = ReadRgbExr(out);
  EXPECT_TRUE(img.ok());
  if (!img.ok()) return {};
  cv::Mat v = img->clone();
  for (auto it = v.begin<cv::Vec3f>(); it != v.end<cv::Vec3f>(); ++it)
    for (int k = 0; k < 3; ++k) (*it)[k] = std::clamp(255.0f * SrgbEncode((*it)[k]), 0.0f, 255.0f);
  return v;
}

double Psnr8(const cv::Mat& a, const cv::Mat& b) {
  if (a.empty() || b.empty() || a.size() != b.size()) return 0;
  return cv::PSNR(a, b, 255.0);
}

TEST(ExportCommand, EveryFormatRendersAsTheExrModelDoes) {
  const std::string dir = testing::FreshTempDir("export-cmd");
  const std::string ptm = WriteModel(dir, BasisKind::kPtm, 2, FitSpace::kSrgb);
  const std::string hsh = WriteModel(dir, BasisKind::kHsh, 2, FitSpace::kSrgb);
  struct Case { std::string model, args, out; };
  for (const Case& c : {Case{ptm, "--format relight", dir + "/ptm-web"},
                        Case{ptm, "--format ptm", dir + "/m.ptm"},
                        Case{hsh, "--format relight", dir + "/hsh-web"},
                        Case{hsh, "--format rti", dir + "/m.rti"}}) {
    auto r = RunRig("export " + c.model + " " + c.args + " --out " + c.out);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_THAT(r.output, HasSubstr("rig export: wrote " + c.out));
    EXPECT_THAT(r.output, HasSubstr("mapped exactly"));
    EXPECT_THAT(r.output, HasSubstr("as written, read back"));
    const cv::Mat exported = RenderSrgb(c.out, c.out + "-render.exr");
    const cv::Mat original = RenderSrgb(c.model, c.out + "-exr-render.exr");
    const double db = Psnr8(exported, original);
    std::printf("%s: rig render PSNR against the EXR's render %.2f dB\n", c.out.c_str(), db);
    EXPECT_GE(db, 45) << r.output;
  }
}

TEST(ExportCommand, RefitsPrintThePsnrLostAndLrgbIsAVariant) {
  const std::string dir = testing::FreshTempDir("export-cmd-refit");
  const std::string sh = WriteModel(dir, BasisKind::kSh, 2, FitSpace::kSrgb);
  auto r = RunRig("export " + sh + " --format relight --out " + dir + "/sh-web");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("refitted"));
  EXPECT_THAT(r.output, HasSubstr("dB PSNR against the source's render over 40 lights"));
  const std::string ptm = WriteModel(dir, BasisKind::kPtm, 2, FitSpace::kSrgb);
  r = RunRig("export " + ptm + " --format ptm --ptm-variant lrgb --out " + dir + "/l.ptm");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("PTM_FORMAT_LRGB"));
  EXPECT_THAT(r.output, HasSubstr("luminance PTM x RGB albedo"));
  std::ifstream f(dir + "/l.ptm");
  std::string v, fmt;
  std::getline(f, v);
  std::getline(f, fmt);
  EXPECT_EQ(v, "PTM_1.2");
  EXPECT_EQ(fmt, "PTM_FORMAT_LRGB");
}

// The default model of a real capture into RTIViewer's formats: the export says what it is
// about to do and what the target's basis cannot hold before it starts, and a refit rendered on
// several threads writes the same bytes every run.
TEST(ExportCommand, ARefitSaysWhatItWillLoseFirstAndWritesTheSameFileEveryRun) {
  const std::string lp = testing::SharedDir() + "/data/rti/neuralrti-example/dirs.lp";
  if (!fs::exists(lp)) GTEST_SKIP() << lp << " is absent";
  const std::string dir = testing::FreshTempDir("export-cmd-plan");
  auto r = RunRig("fit --lp " + lp + " --downsample 2 --out " + dir + "/pca");
  ASSERT_EQ(r.status, 0) << r.output;
  std::string bytes[2];
  for (int i = 0; i < 2; ++i) {
    const std::string out = dir + "/m" + std::to_string(i) + ".ptm";
    r = RunRig("export " + dir + "/pca --format ptm --out " + out);
    ASSERT_EQ(r.status, 0) << r.output;
    const size_t plan = r.output.find("what the pca-bilinear model holds beyond that");
    const size_t wrote = r.output.find("rig export: wrote");
    ASSERT_NE(plan, std::string::npos) << r.output;
    EXPECT_LT(plan, wrote) << r.output;
    EXPECT_THAT(r.output, HasSubstr("PTM rgb (6 terms per channel) holds a biquadratic"));
    EXPECT_THAT(r.output, HasSubstr("as written, read back: "));
    bytes[i] = testing::ReadText(out);
  }
  EXPECT_FALSE(bytes[0].empty());
  EXPECT_TRUE(bytes[0] == bytes[1]) << "two exports of one model differ";
}

TEST(ExportCommand, RefusesExistingOutputAndBadFilesNamingThem) {
  const std::string dir = testing::FreshTempDir("export-cmd-bad");
  const std::string ptm = WriteModel(dir, BasisKind::kPtm, 2, FitSpace::kSrgb);
  ASSERT_EQ(RunRig("export " + ptm + " --format ptm --out " + dir + "/a.ptm").status, 0);
  auto r = RunRig("export " + ptm + " --format ptm --out " + dir + "/a.ptm");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr(dir + "/a.ptm"));
  r = RunRig("export " + ptm + " --format rti --basis ptm --out " + dir + "/b.rti");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("--basis"));
  // A truncated .ptm: render refuses it, naming the file.
  fs::resize_file(dir + "/a.ptm", fs::file_size(dir + "/a.ptm") / 2);
  r = RunRig("render " + dir + "/a.ptm --light 40,15 --out " + dir + "/x.png");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr(dir + "/a.ptm"));
  EXPECT_THAT(r.output, HasSubstr("truncated"));
}

TEST(ExportCommand, SessionAsAnLpCaptureFitsBackAndRadianceModelsAreScaledToDisplay) {
  const std::string dir = testing::FreshTempDir("export-cmd-session");
  const std::string cfg = testing::WriteSimConfig(dir, "[sim]\nwidth = 64\nheight = 48\n");
  auto r = RunRig("capture --config " + cfg + " --out " + dir + "/S --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  r = RunRig("export " + dir + "/S --format lp --out " + dir + "/lp");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("40 images"));
  auto lp = ReadLp(dir + "/lp/dirs.lp");
  ASSERT_TRUE(lp.ok()) << lp.error().ToString();
  ASSERT_EQ(lp->size(), 40u);
  // JPEG images by default (relight-cli reads *.jpg only), PNG on request.
  EXPECT_TRUE(fs::exists(dir + "/lp/h000_v00.jpg"));
  EXPECT_FALSE(fs::exists(dir + "/lp/h000_v00.png"));
  // The grid's poses at the horizon are lifted off it, named, and every light is above it, so
  // the hemispherical families (hsh, pca) fit the capture.
  size_t at_horizon = 0;
  for (const auto& e : *lp) {
    EXPECT_GT(e.direction[2], 0.0) << e.image;
    if (e.direction[2] < 0.01) ++at_horizon;
  }
  EXPECT_GT(at_horizon, 0u);
  EXPECT_THAT(r.output, HasSubstr(fmt::format("{} pose(s) at the horizon", at_horizon)));
  r = RunRig("fit --lp " + dir + "/lp/dirs.lp --basis ptm --order 2 --out " + dir + "/fit.exr");
  EXPECT_EQ(r.status, 0) << r.output;
  r = RunRig("fit --lp " + dir + "/lp/dirs.lp --basis hsh --order 2 --out " + dir + "/hsh.exr");
  EXPECT_EQ(r.status, 0) << r.output;
  r = RunRig("export " + dir + "/S --format lp --lp-images png --out " + dir + "/lp-png");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir + "/lp-png/h000_v00.png"));
  // The session's own model (linear ρ relative to the lamp) is refitted and scaled to display.
  r = RunRig("export " + dir + "/S --format relight --out " + dir + "/web");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("refitted"));
  EXPECT_THAT(r.output, HasSubstr("rho scaled by"));
  EXPECT_EQ(RunRig("render " + dir + "/web --light 45,20 --out " + dir + "/web.png").status, 0);
}

// The dB figure after `label` in rig export's output (0 when absent).
double DbAfter(const std::string& output, const std::string& label) {
  const auto at = output.find(label);
  if (at == std::string::npos) return 0;
  return std::atof(output.c_str() + at + label.size());
}

// The real icon (72 photographs): PTM and HSH fitted in sRGB space (downsampled by 2), each
// written to every format and read back. The bounds are what this capture measures, less ~1 dB:
// 8-bit raw .ptm/.rti near 60 dB; JPEG planes at the default q98 48.2 dB (PTM, YCbCr) to 51.6
// (HSH); relight's q95 gave 44.1 and 47.6 (scripts/export-psnr.sh).
TEST(ExportCommand, RealCaptureRoundTripsMeasureTheFormatsOwnLoss) {
  const std::string lp = testing::SharedDir() + "/data/rti/neuralrti-example/dirs.lp";
  if (!fs::exists(lp)) GTEST_SKIP() << lp << " is absent";
  const std::string dir = testing::FreshTempDir("export-cmd-icon");
  for (const char* basis : {"ptm", "hsh"}) {
    const std::string model = dir + "/" + basis + ".exr";
    auto r = RunRig(fmt::format("fit --lp {} --basis {} --order 2 --space srgb --method ls "
                                "--downsample 2 --out {}", lp, basis, model));
    ASSERT_EQ(r.status, 0) << r.output;
    struct Case { std::string args; double bound; };
    const bool ptm = std::string(basis) == "ptm";
    int n = 0;
    for (const Case& c : {Case{"--format relight", ptm ? 47.0 : 50.5},
                          Case{"--format relight --jpeg-rgb", ptm ? 45.0 : 48.0},
                          Case{ptm ? "--format ptm" : "--format rti", 58.0}}) {
      const std::string ext = c.args.find("ptm") != std::string::npos   ? ".ptm"
                              : c.args.find("rti") != std::string::npos ? ".rti"
                                                                        : "";
      const std::string out = fmt::format("{}/{}-{}{}", dir, basis, n++, ext);
      r = RunRig("export " + model + " " + c.args + " --out " + out);
      ASSERT_EQ(r.status, 0) << r.output;
      EXPECT_THAT(r.output, HasSubstr("held exactly before quantisation"));
      const double db = DbAfter(r.output, "as written, read back: ");
      std::printf("icon %s %s: %.2f dB over the 72 lights\n", basis, c.args.c_str(), db);
      EXPECT_GE(db, c.bound) << r.output;
    }
  }
}

}  // namespace
}  // namespace rig
