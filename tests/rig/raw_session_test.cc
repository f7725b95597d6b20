// A dry-run session with camera.format = "raw+jpeg": the simulated body hands out a DNG beside
// each JPEG (14-bit sensor values from the same electrons), both are stored, and processing
// merges the RAW frames without response recovery — more accurate against the scene's exact
// radiance than the JPEG path of the same session.
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "process/io/exr_io.h"
#include "capture/plan/pose.h"
#include "process/model/light_direction.h"
#include "sim/sim_camera.h"
#include "sim/world.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

int Count(const fs::path& dir, const std::string& ext) {
  int n = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir)) n += e.path().extension() == ext;
  return n;
}

// Log-radiance RMS against the truth over pixel-channels with truth above `floor`, the mean
// log offset per channel removed (a merge's radiance is relative).
double LogRms(const cv::Mat& est, const cv::Mat& truth, double floor) {
  std::array<std::vector<double>, 3> d;
  for (int y = 0; y < truth.rows; ++y) {
    for (int k = 0; k < truth.cols * 3; ++k) {
      const double t = truth.ptr<float>(y)[k], e = est.ptr<float>(y)[k];
      if (t > floor && e > 0) d[k % 3].push_back(std::log(e / t));
    }
  }
  double sum = 0;
  size_t n = 0;
  for (auto& ch : d) {
    double m = 0;
    for (double v : ch) m += v;
    m /= std::max<size_t>(ch.size(), 1);
    for (double v : ch) sum += (v - m) * (v - m);
    n += ch.size();
  }
  return n ? std::sqrt(sum / n) : 1e9;
}

TEST(RawSession, StoresDngBesideJpegAndMergesTheRawFramesLinearly) {
  const std::string dir = testing::FreshTempDir("raw_session");
  const std::string grid =
      "[sim]\nwidth = 96\nheight = 72\n[grid]\nh_min_deg = 20\nh_max_deg = 40\nv_max_deg = 10\n";
  // WriteSimConfig writes into an existing folder: make the two config folders first.
  fs::create_directories(dir + "/raw");
  fs::create_directories(dir + "/jpg");
  const std::string raw_cfg =
      testing::WriteSimConfig(dir + "/raw", grid + "[camera]\nformat = \"raw+jpeg\"\n");
  const std::string jpg_cfg = testing::WriteSimConfig(dir + "/jpg", grid);
  auto r = RunRig("capture --config " + raw_cfg + " --out " + dir + "/R --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("RAW frames are linear"));
  auto j = RunRig("capture --config " + jpg_cfg + " --out " + dir + "/J --dry-run --no-progress");
  ASSERT_EQ(j.status, 0) << j.output;
  const fs::path R = dir + "/R", J = dir + "/J";
  const int poses = 3 * 2, exposures = 7;
  EXPECT_EQ(Count(R / "frames", ".dng"), poses * exposures);
  EXPECT_EQ(Count(R / "frames", ".jpg"), poses * exposures);
  EXPECT_EQ(Count(J / "frames", ".dng"), 0);
  EXPECT_EQ(Count(R / "hdr", ".exr"), poses);
  EXPECT_FALSE(fs::exists(R / "calib" / "response.csv"));  // no response recovered

  auto cfg = LoadConfigOrError(raw_cfg);
  ASSERT_TRUE(cfg.ok());
  cfg->sim.width = 96;
  cfg->sim.height = 72;
  auto cam = SimCamera::Create(*cfg, std::make_shared<SimWorld>());
  ASSERT_TRUE(cam.ok());
  double raw_sum = 0, jpg_sum = 0;
  for (const char* pose : {"h020_v00", "h030_v10", "h040_v00"}) {
    auto p = ParsePoseName(pose);
    const cv::Mat truth = (*cam)->scene().Radiance(
        LightDirection(p->h_deg, p->v_deg, cfg->light_frame), cfg->lamp.radiance_rgb);
    auto rm = ReadRgbExr((R / "hdr" / (std::string(pose) + ".exr")).string());
    auto jm = ReadRgbExr((J / "hdr" / (std::string(pose) + ".exr")).string());
    ASSERT_TRUE(rm.ok() && jm.ok());
    // Above the level the longest exposure records usefully (20 electrons).
    const double floor = 20.0 / (0.32 * cfg->sim.camera.gain);
    const double er = LogRms(*rm, truth, floor), ej = LogRms(*jm, truth, floor);
    std::printf("%s: log-radiance RMS, RAW %.4f, JPEG %.4f\n", pose, er, ej);
    raw_sum += er;
    jpg_sum += ej;
  }
  EXPECT_LT(raw_sum, 0.8 * jpg_sum);
}

TEST(RawSession, RawOnlyStoresNoJpegAndAnUnknownFormatIsRefused) {
  const std::string dir = testing::FreshTempDir("raw_only");
  const std::string cfg = testing::WriteSimConfig(
      dir, "[sim]\nwidth = 64\nheight = 48\n[grid]\nh_max_deg = 10\nv_max_deg = 0\n"
           "[camera]\nformat = \"raw\"\n");
  auto r = RunRig("capture --config " + cfg + " --out " + dir + "/S --dry-run --no-progress");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(Count(fs::path(dir) / "S" / "frames", ".jpg"), 0);
  EXPECT_EQ(Count(fs::path(dir) / "S" / "frames", ".dng"), 2 * 7);
  EXPECT_EQ(Count(fs::path(dir) / "S" / "hdr", ".exr"), 2);
  fs::create_directories(dir + "/bad");
  const std::string bad = testing::WriteSimConfig(dir + "/bad", "[camera]\nformat = \"tiff\"\n");
  auto b = RunRig("check-config " + bad);
  EXPECT_EQ(b.status, 2) << b.output;
  EXPECT_THAT(b.output, HasSubstr("format"));
}

}  // namespace
}  // namespace rig
