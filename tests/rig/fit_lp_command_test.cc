// `rig fit --lp` as a user runs it: on a small synthetic multi-light capture written as JPEGs
// with an .lp file, the default writes relight's web format and says what it chose; the model
// renders; bad light files and bad images are refused naming the .lp line; on the shared real
// capture (when present) the default fits in the byte budget.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "process/export/load_any.h"
#include "process/export/relight_coefficients.h"
#include "process/model/harmonic/fit.h"
#include "tests/support/lp_capture.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

// The suite's capture: tests/support/lp_capture.h.
std::string WriteCapture(const std::string& dir, int width, int height) {
  return testing::WriteLpCapture(dir, width, height);
}

TEST(FitLpCommand, DefaultWritesRelightsWebFormatSaysWhatItChoseAndRenders) {
  const std::string dir = testing::FreshTempDir("fit-lp");
  const std::string lp = WriteCapture(dir, 80, 64);
  // A tiny image: the basis (a fixed cost) is large per pixel; a budget that leaves the
  // choice to the error.
  auto r = RunRig("fit --lp " + lp + " --max-bytes-per-pixel 40 --out " + dir + "/model --report " +
                  dir + "/report.md");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("pca-bilinear"));
  EXPECT_THAT(r.output, HasSubstr("the smallest of"));
  EXPECT_TRUE(fs::exists(dir + "/model/info.json"));
  EXPECT_TRUE(fs::exists(dir + "/model/plane_0.jpg"));
  std::ifstream rep(dir + "/report.md");
  const std::string report((std::istreambuf_iterator<char>(rep)), {});
  EXPECT_THAT(report, HasSubstr("**chosen**"));
  EXPECT_THAT(report, HasSubstr("masked"));

  // It renders (as the photographs: no tone mapping), close to a photograph at its own light.
  // The first image's light: elevation 25°, azimuth 0.
  const double e = 25 * M_PI / 180;
  const double h = std::atan2(std::cos(e), std::sin(e)) * 180 / M_PI;
  const double v = std::asin(0.0) * 180 / M_PI;
  r = RunRig("render " + dir + "/model --light " + std::to_string(h) + "," + std::to_string(v) +
             " --out " + dir + "/relit.png");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("as the photographs"));
  const cv::Mat relit = cv::imread(dir + "/relit.png"), photo = cv::imread(dir + "/img0.jpg");
  ASSERT_EQ(relit.size(), photo.size());
  cv::Mat diff;
  cv::absdiff(relit, photo, diff);
  EXPECT_LT(cv::mean(diff)[0], 6.0);

  // Exported to relight's web format, the PCA model is its own files, byte for byte.
  r = RunRig("export " + dir + "/model --format relight --out " + dir + "/exported");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("nothing refitted"));
  for (const auto& e : fs::directory_iterator(dir + "/model")) {
    std::ifstream a(e.path(), std::ios::binary), b(dir + "/exported/" + e.path().filename().string(),
                                                     std::ios::binary);
    const std::string sa((std::istreambuf_iterator<char>(a)), {}),
        sb((std::istreambuf_iterator<char>(b)), {});
    EXPECT_EQ(sa, sb) << e.path().filename();
  }

  // An EXR name for a folder model is refused with the reason; sh still writes an EXR.
  r = RunRig("fit --lp " + lp + " --out " + dir + "/m.exr");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("is a folder"));
  r = RunRig("fit --lp " + lp + " --basis hsh --order 2 --out " + dir + "/m.exr");
  EXPECT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir + "/m.exr"));
  fs::remove_all(dir);
}

// A capture that is exactly a relight basis: each pixel's code value a known combination of
// the basis at the image's light (PNG: no JPEG loss), 28 lights on rings at 20..75°.
struct ExactCapture {
  std::string lp;
  std::vector<Vec3> lights;
};
ExactCapture WriteExactCapture(const std::string& dir, RelightType type, int terms, bool lrgb) {
  ExactCapture c;
  std::ofstream lp(dir + "/dirs.lp");
  lp << "28\n";
  const int w = 40, h = 30;
  int index = 0;
  for (double elev : {20.0, 38.0, 56.0, 75.0})
    for (int i = 0; i < 7; ++i, ++index) {
      const double az = (i + 0.37 * index) * 2 * M_PI / 7, e = elev * M_PI / 180;
      const Vec3 l = {std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e)};
      c.lights.push_back(l);
      double wt[kMaxRelightTerms];
      RelightWeights(type, terms, l, wt);
      cv::Mat img(h, w, CV_8UC3);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          for (int ch = 0; ch < 3; ++ch) {
            // coefficients smooth over the image; lrgb: one luminance polynomial × an albedo
            double v = 0;
            for (int k = 0; k < terms; ++k) {
              const double base = k == 0 ? 130 : 40.0 / k;
              const double chan = lrgb ? 1.0 : 1 + 0.1 * ch;
              v += wt[k] * base * chan * (1 + 0.2 * std::sin(0.2 * x + k) * std::cos(0.15 * y));
            }
            if (lrgb) v *= (0.5 + 0.2 * ch + 0.2 * std::sin(0.3 * x)) ;
            img.at<cv::Vec3b>(y, x)[2 - ch] = static_cast<uint8_t>(std::clamp(std::lround(v), 5L, 250L));
          }
      const std::string name = "img" + std::to_string(index) + ".png";
      cv::imwrite(dir + "/" + name, img);
      lp << name << " " << l[0] << " " << l[1] << " " << l[2] << "\n";
    }
  c.lp = dir + "/dirs.lp";
  return c;
}

double HeldOutDb(const std::string& output) {
  std::smatch m;
  const std::regex re("refitted without them and written: ([0-9.]+) dB");
  return std::regex_search(output, m, re) ? std::stod(m[1]) : 0;
}

// One step from photographs to RTIViewer's files: .ptm (rgb, lrgb) and .rti (HSH 9, 4) fitted
// straight from the images, the held-out error of the file as written printed; on a capture
// that is exactly such a model, that error is the 8-bit quantisation's alone.
TEST(FitLpCommand, PtmAndRtiFilesFittedStraightFromThePhotographs) {
  struct Case {
    const char* name;
    RelightType type;
    int terms;
    bool lrgb;
    const char* args;
  };
  for (const Case& k : {Case{"ptm-rgb", RelightType::kPtm, 6, false, ""},
                        Case{"ptm-lrgb", RelightType::kPtm, 6, true, " --ptm-variant lrgb"},
                        Case{"hsh9", RelightType::kHsh, 9, false, ""},
                        Case{"hsh4", RelightType::kHsh, 4, false, " --hsh-terms 4"},
                        Case{"hsh16", RelightType::kHsh, 16, false, " --hsh-terms 16"}}) {
    const std::string dir = testing::FreshTempDir(std::string("fit-relight-") + k.name);
    const ExactCapture cap = WriteExactCapture(dir, k.type, k.terms, k.lrgb);
    const std::string out = dir + (k.type == RelightType::kPtm ? "/m.ptm" : "/m.rti");
    auto r = RunRig("fit --lp " + cap.lp + " --out " + out + k.args + " --report " + dir + "/r.md");
    ASSERT_EQ(r.status, 0) << k.name << "\n" << r.output;
    EXPECT_THAT(r.output, HasSubstr("held out 5 images (every 6th)")) << k.name;
    const double db = HeldOutDb(r.output);
    // 8-bit photographs and 8-bit coefficients: ~50 dB; a wrong basis or order would be < 35
    EXPECT_GT(db, 42) << k.name << "\n" << r.output;
    auto m = LoadAnyModel(out);
    ASSERT_TRUE(m.ok()) << m.error().ToString();
    const RelightCoefficients* c = RelightCoefficientsOf(**m);
    ASSERT_NE(c, nullptr);
    EXPECT_EQ(c->terms, k.terms);
    EXPECT_EQ(c->lrgb, k.lrgb);
    if (k.type == RelightType::kPtm) {
      // the header's biases are bytes (strict readers refuse others)
      std::ifstream f(out);
      std::string line;
      for (int i = 0; i < 5; ++i) std::getline(f, line);
      std::getline(f, line);
      std::istringstream bs(line);
      for (int i = 0; i < 6; ++i) {
        long b = -1;
        bs >> b;
        EXPECT_GE(b, 0) << k.name << " bias " << i;
        EXPECT_LE(b, 255) << k.name << " bias " << i;
      }
    }
    EXPECT_THAT(testing::ReadText(dir + "/r.md"), HasSubstr("held out 5 images"));
  }
  // The held-out figure can be false: a PTM of an HSH-only scene holds it less well.
  const std::string dir = testing::FreshTempDir("fit-relight-mismatch");
  const ExactCapture cap = WriteExactCapture(dir, RelightType::kHsh, 9, false);
  auto ptm = RunRig("fit --lp " + cap.lp + " --out " + dir + "/m.ptm");
  auto rti = RunRig("fit --lp " + cap.lp + " --out " + dir + "/m.rti");
  ASSERT_EQ(ptm.status, 0) << ptm.output;
  ASSERT_EQ(rti.status, 0) << rti.output;
  EXPECT_LT(HeldOutDb(ptm.output) + 3, HeldOutDb(rti.output)) << ptm.output << rti.output;
  // RTIViewer's third order is more than its second where the scene has it; relight's web
  // format stops at 9 terms, so a web export of a 16-term .rti is refitted to 9 (and a web
  // export asked for 16 is refused naming the way out).
  const std::string dir16 = testing::FreshTempDir("fit-relight-hsh16");
  const ExactCapture cap16 = WriteExactCapture(dir16, RelightType::kHsh, 16, false);
  auto nine = RunRig("fit --lp " + cap16.lp + " --out " + dir16 + "/m9.rti");
  auto sixteen = RunRig("fit --lp " + cap16.lp + " --hsh-terms 16 --out " + dir16 + "/m16.rti");
  ASSERT_EQ(nine.status, 0) << nine.output;
  ASSERT_EQ(sixteen.status, 0) << sixteen.output;
  EXPECT_THAT(sixteen.output, HasSubstr("HSH, 16 terms per channel"));
  EXPECT_LT(HeldOutDb(nine.output) + 3, HeldOutDb(sixteen.output)) << nine.output << sixteen.output;
  auto web = RunRig("export " + dir16 + "/m16.rti --format relight --out " + dir16 + "/web");
  EXPECT_EQ(web.status, 0) << web.output;  // refitted to 9 terms, the loss stated
  // rig view of it shows it refitted to 9 terms, not an error.
  auto view = RunRig("view " + dir16 + "/m16.rti --out " + dir16 + "/view");
  EXPECT_EQ(view.status, 0) << view.output;
  EXPECT_THAT(testing::ReadText(dir16 + "/view/info.json"), HasSubstr("\"nplanes\":27"));
  auto web16 = RunRig("export " + dir16 + "/m16.rti --format relight --hsh-terms 16 --out " + dir16 + "/web16");
  EXPECT_NE(web16.status, 0) << web16.output;
  EXPECT_THAT(web16.output, HasSubstr("16 only with --format rti"));
  EXPECT_FALSE(fs::exists(dir16 + "/web16"));
  // A .rti holds an HSH, a .ptm a PTM.
  auto bad = RunRig("fit --lp " + cap.lp + " --basis hsh --out " + dir + "/x.ptm");
  EXPECT_NE(bad.status, 0);
  EXPECT_THAT(bad.output, HasSubstr("--basis"));
}

TEST(FitLpCommand, BadLightFilesAndImagesAreRefusedNamingTheLine) {
  const std::string dir = testing::FreshTempDir("fit-lp-bad");
  const std::string lp = WriteCapture(dir, 24, 16);
  std::ifstream in(lp);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  auto write = [&](const std::string& name, std::vector<std::string> l) {
    std::ofstream f(dir + "/" + name);
    for (const auto& s : l) f << s << "\n";
    return dir + "/" + name;
  };
  auto lines2 = lines;
  lines2[1] = "36.5";
  auto r = RunRig("fit --lp " + write("count.lp", lines2) + " --out " + dir + "/m");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("count.lp:2"));
  EXPECT_THAT(r.output, HasSubstr("whole number"));

  lines2 = lines;
  lines2[5] = "missing.jpg 0.1 0.2 0.97";
  r = RunRig("fit --lp " + write("missing.lp", lines2) + " --out " + dir + "/m");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("missing.lp:6"));
  EXPECT_THAT(r.output, HasSubstr("missing.jpg"));

  // A truncated JPEG is refused, not read as grey.
  {
    std::ifstream src(dir + "/img3.jpg", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(src)), {});
    std::ofstream(dir + "/cut.jpg", std::ios::binary) << bytes.substr(0, bytes.size() - 60);
  }
  lines2 = lines;
  lines2[5] = "cut.jpg" + lines[5].substr(lines[5].find(' '));
  r = RunRig("fit --lp " + write("cut.lp", lines2) + " --out " + dir + "/m");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("cut.lp:6"));
  EXPECT_THAT(r.output, HasSubstr("truncated"));

  // A light below the horizon: refused by the hemispherical default, naming the line.
  lines2 = lines;
  lines2[7] = lines[7].substr(0, lines[7].find(' ')) + " 0.6 0.0 -0.8";
  r = RunRig("fit --lp " + write("below.lp", lines2) + " --out " + dir + "/m");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("below.lp:8"));
  EXPECT_THAT(r.output, HasSubstr("below the horizon"));

  // Too few lines for the count.
  lines2 = lines;
  lines2.pop_back();
  r = RunRig("fit --lp " + write("short.lp", lines2) + " --out " + dir + "/m");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("36 images, 35 are listed"));
  fs::remove_all(dir);
}

TEST(EvaluateLpCommand, EveryFamilyIsRefittedPerHeldOutImageAndCharted) {
  const std::string dir = testing::FreshTempDir("evaluate-lp");
  const std::string lp = WriteCapture(dir, 32, 24);
  // Progress lines as under Snakemake or nohup (off a terminal), here at every step: the
  // table's rows and each row's folds.
  setenv("RIG_PROGRESS_EVERY_S", "0.000001", 1);
  auto r = RunRig("evaluate --lp " + lp + " --lp-every 12 --out " + dir + "/report");
  setenv("RIG_PROGRESS_EVERY_S", "100000", 1);  // as tests/test_env.cc sets it
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("progress: pca refitted without each held-out image 3/3")) << r.output;
  EXPECT_THAT(r.output, HasSubstr("progress: neural refitted without each held-out image")) << r.output;
  EXPECT_THAT(r.output, HasSubstr("progress: leave-one-out table 5/5 (100%), neural done")) << r.output;
  std::ifstream f(dir + "/report/rti-loo.md");
  const std::string md((std::istreambuf_iterator<char>(f)), {});
  for (const char* family : {"| pca-bilinear |", "| ptm |", "| hsh |", "| sh |", "| neural |"})
    EXPECT_THAT(md, HasSubstr(family)) << md;
  // A basis these 36 lights cannot hold (SH order 4, 25 terms, least squares) is listed as
  // refused, with the reason, not dropped.
  EXPECT_THAT(md, HasSubstr("refused:"));
  EXPECT_THAT(md, HasSubstr("3 of 36 refitted"));
  // Not the shared icon: relight's published figures for it are not drawn beside these.
  EXPECT_THAT(md, ::testing::Not(HasSubstr("published")));
  EXPECT_TRUE(fs::exists(dir + "/report/rti-loo-psnr-bytes.png"));
  EXPECT_TRUE(fs::exists(dir + "/report/rti-loo-psnr-time.png"));
  // The default (bold, whichever family its choice took) is a real figure: a smooth
  // synthetic scene is far above 25 dB.
  const auto at = md.find("| **");
  ASSERT_NE(at, std::string::npos);
  const std::string row = md.substr(at, md.find('\n', at) - at);
  const auto db = row.find(" / ");
  ASSERT_NE(db, std::string::npos);
  const double psnr = std::stod(row.substr(row.rfind('|', db) + 1));
  EXPECT_GT(psnr, 25.0) << row;
  EXPECT_LT(psnr, 80.0) << row;
  // A second run into the same folder is refused: nothing is overwritten.
  r = RunRig("evaluate --lp " + lp + " --lp-every 12 --out " + dir + "/report");
  EXPECT_EQ(r.status, 2) << r.output;
  fs::remove_all(dir);
}

// The leave-one-out report's rows and the command are one choice: `rig fit
// --max-bytes-per-pixel B` takes what the report's "auto within B" row says it takes on every
// image, from the same candidates (a large budget adds 24 and 30 components to both).
TEST(FitLpCommand, TheReportsBudgetRowsAndTheCommandMakeTheSameChoice) {
  const std::string dir = testing::FreshTempDir("fit-lp-agree");
  const std::string lp = WriteCapture(dir, 48, 40);
  // What the command chose, as the report states a row's choice on every image.
  auto fit = [&](const std::string& budget, const std::string& extra) {
    auto r = RunRig("fit --lp " + lp + " --max-bytes-per-pixel " + budget + " --out " + dir + "/m" + budget +
                    extra);
    EXPECT_EQ(r.status, 0) << r.output;
    std::smatch m;
    const std::regex re("((pca|hsh|ptm) [^:]+): .*the smallest of (\\d+) candidates");
    if (!std::regex_search(r.output, m, re)) {
      ADD_FAILURE() << r.output;
      return std::string();
    }
    return m[1].str() + " (of " + m[3].str() + " candidates)";
  };
  const std::string at12 = fit("12", "");
  EXPECT_THAT(at12, HasSubstr("(of 105 candidates)"));  // 24 and 30 components join 72 pca and 9 bases
  const std::string report = dir + "/loo.md";
  const std::string at34 =
      fit("3.4", " --loo-every 12 --loo-no-neural --loo-report " + report);
  EXPECT_THAT(at34, HasSubstr("(of 81 candidates)"));
  std::ifstream f(report);
  const std::string md((std::istreambuf_iterator<char>(f)), {});
  EXPECT_THAT(md, HasSubstr("default: auto within 3.4 B/px; all images: " + at34)) << md;
  EXPECT_THAT(md, HasSubstr("auto within 12 B/px; all images: " + at12)) << md;
  fs::remove_all(dir);
}

TEST(FitLpCommand, RealCaptureDefaultFitsWithinTheByteBudget) {
  const std::string lp = testing::SharedDir() + "/data/rti/neuralrti-example/dirs.lp";
  if (!fs::exists(lp)) GTEST_SKIP() << lp << " is not here";
  const std::string dir = testing::FreshTempDir("fit-icon");
  auto r = RunRig("fit --lp " + lp + " --out " + dir + "/icon");
  ASSERT_EQ(r.status, 0) << r.output;
  uint64_t bytes = 0;
  for (const auto& e : fs::directory_iterator(dir + "/icon")) bytes += e.file_size();
  EXPECT_LE(static_cast<double>(bytes) / (402.0 * 395.0), 3.4) << r.output;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig
