// A dry-run session with [process] model_family = "pca": the model written to model/pca/ with
// the HDR values block, its choice in model/report.md, and `rig render SESSION` giving the
// session's HDR radiance from it (against the simulator's truth and the session's own map at
// a sampled pose) — and `rig view SESSION` writing its page.
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "capture/daemon/session_model.h"
#include "capture/session/session_store.h"
#include "process/io/exr_io.h"
#include "tests/support/dry_session.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using testing::RunRig;

class PcaSession : public testing::DrySessionSuite<PcaSession> {
 protected:
  static void SetUpTestSuite() {
    Capture("pca_session", R"([process]
model_family = 'pca'
[sim]
width = 160
height = 120
scene = 'gloss'
)");
  }
};

// Relative RMS of `a` against `truth` with one scale per channel removed.
double Relative(const cv::Mat& a, const cv::Mat& truth) {
  double err = 0, ref = 0;
  std::vector<cv::Mat> pa, pt;
  cv::split(a, pa);
  cv::split(truth, pt);
  for (int c = 0; c < 3; ++c) {
    const double s = pa[c].dot(pt[c]) / std::max(1e-30, pa[c].dot(pa[c]));
    err += cv::norm(pa[c] * s, pt[c], cv::NORM_L2SQR);
    ref += pt[c].dot(pt[c]);
  }
  return std::sqrt(err / ref);
}

TEST_F(PcaSession, TheModelIsThePcaFolderWithItsValuesAndChoice) {
  const fs::path model = fs::path(*session_) / "model";
  EXPECT_FALSE(fs::exists(model / "model.exr"));
  std::ifstream f(model / "pca" / "info.json");
  ASSERT_TRUE(f.good());
  const auto info = nlohmann::json::parse(f);
  EXPECT_EQ(info.at("type"), "bilinear");
  EXPECT_EQ(info.at("rig").at("values").at("encoding"), "power");
  EXPECT_GT(info.at("rig").at("values").at("max").get<double>(), 0);
  std::ifstream r(model / "report.md");
  std::string report((std::istreambuf_iterator<char>(r)), std::istreambuf_iterator<char>());
  EXPECT_NE(report.find("**chosen**"), std::string::npos) << report;
  EXPECT_FALSE(fs::exists(model / ".pca-choice"));
}

TEST_F(PcaSession, RenderGivesTheSessionsRadiance) {
  const std::string out = *dir_ + "/at.exr";
  auto run = RunRig("render " + *session_ + " --light 40,10 --out " + out);
  ASSERT_EQ(run.status, 0) << run.output;
  auto img = ReadRgbExr(out);
  ASSERT_TRUE(img.ok());
  auto truth = ReadRgbExr(*session_ + "/truth/radiance/h040_v10.exr");
  ASSERT_TRUE(truth.ok());
  EXPECT_LT(Relative(*img, *truth), 0.10);
  // Radiance in the session's own units, not codes: against the session's radiance map of
  // that pose with no scale removed (a code-valued render would be off by orders of magnitude).
  auto map = ReadRgbExr(*session_ + "/hdr/h040_v10.exr");
  ASSERT_TRUE(map.ok());
  EXPECT_LT(cv::norm(*img, *map, cv::NORM_L2) / cv::norm(*map, cv::NORM_L2), 0.10);
}

std::string Bytes(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

TEST_F(PcaSession, TheModelFromTheFilesEqualsTheCapturesFromMemoryByteForByte) {
  EXPECT_NE(Bytes(fs::path(*session_) / "log.txt").find("model fitted from the maps in memory"),
            std::string::npos);
  const fs::path copy = fs::path(*dir_) / "copy";
  fs::copy(*session_, copy, fs::copy_options::recursive);
  fs::remove_all(copy / "model");
  auto session = Session::OpenExisting(copy);
  ASSERT_TRUE(session.ok()) << session.error().ToString();
  ASSERT_TRUE(FitSessionModel(*session).ok());  // no maps held: from the files
  int files = 0;
  for (const auto& e : fs::directory_iterator(fs::path(*session_) / "model" / "pca")) {
    EXPECT_EQ(Bytes(e.path()), Bytes(copy / "model" / "pca" / e.path().filename())) << e.path();
    ++files;
  }
  EXPECT_GE(files, 2);
}

// relight's readers do not know rig.values (the HDR curve): the session's PCA model is refitted
// into relight's 8-bit display values, as a harmonic session's model is, never copied as codes.
TEST_F(PcaSession, ExportToRelightRefitsTheHdrModelIntoDisplayValues) {
  const std::string out = *dir_ + "/relight";
  auto run = RunRig("export " + *session_ + " --format relight --out " + out);
  ASSERT_EQ(run.status, 0) << run.output;
  EXPECT_NE(run.output.find("refitted"), std::string::npos) << run.output;
  EXPECT_NE(run.output.find("pca"), std::string::npos) << run.output;  // names the source
  std::ifstream f(fs::path(out) / "info.json");
  const std::string info((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_NE(info.find("\"hsh\""), std::string::npos) << info;
  EXPECT_EQ(info.find("values"), std::string::npos) << info;  // no HDR curve: display values
}

TEST_F(PcaSession, ViewWritesThePage) {
  const std::string out = *dir_ + "/view";
  auto run = RunRig("view " + *session_ + " --out " + out);
  ASSERT_EQ(run.status, 0) << run.output;
  EXPECT_TRUE(fs::exists(fs::path(out) / "index.html"));
}

}  // namespace
}  // namespace rig
