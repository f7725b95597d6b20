// `rig hdr` and `rig ratio-check` on a simulated session's real frames: a list with relative
// paths merges into an EXR with its header; bad lists fail with exit 2 naming the file; the
// paper's Fig. 6 check (intensity ratio varies, radiance ratio constant). `rig process`:
// tests/rig/process_command_test.cc.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <ImfCompression.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

#include "process/io/exr_io.h"
#include "tests/support/dry_session.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

class HdrCommands : public testing::DrySessionSuite<HdrCommands> {
 protected:
  static void SetUpTestSuite() {
    Capture("hdr_commands", "[sim]\nwidth = 96\nheight = 72\n");
  }
  // A bracket list of pose h040_v20 with paths relative to the list's folder.
  static std::string WriteList(const std::string& name, const std::string& extra = "") {
    const fs::path list = fs::path(*session_) / "frames" / (name + ".txt");
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(fs::path(*session_) / "frames" / "h040_v20")) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    std::ofstream out(list);
    out << "# pose h040_v20\n";
    for (const auto& f : files) {
      const std::string stem = f.stem().string();
      out << "h040_v20/" << f.filename().string() << " " << stem.substr(stem.find('_') + 1) << "\n";
    }
    out << extra;
    return list.string();
  }
};

TEST_F(HdrCommands, MergesAListWithRelativePathsIntoAnExrWithItsHeader) {
  const std::string out = *dir_ + "/merged.exr";
  auto r = RunRig("hdr --list " + WriteList("ok") + " --out " + out);
  ASSERT_EQ(r.status, 0) << r.output;
  auto img = ReadExr(out);
  ASSERT_TRUE(img.ok()) << img.error().ToString();
  bool exposures = false, response = false;
  for (const auto& [k, v] : img->attributes) {
    exposures = exposures || k.find("exposure") != std::string::npos;
    response = response || k.find("response") != std::string::npos;
  }
  EXPECT_TRUE(exposures);
  EXPECT_TRUE(response);
  // Close to the radiance map the session merged from the same frames (same data; the
  // response is recovered from this one bracket instead of four).
  auto mine = ReadRgbExr(out), session = ReadRgbExr(*session_ + "/hdr/h040_v20.exr");
  ASSERT_TRUE(mine.ok() && session.ok());
  // Relative RMS difference after the one scale that relates two recovered responses.
  const double k = session->dot(*mine) / mine->dot(*mine);
  const double rel = cv::norm(*mine * k, *session, cv::NORM_L2) / cv::norm(*session, cv::NORM_L2);
  std::printf("rig hdr vs the session's radiance map: relative RMS difference %.4f\n", rel);
  EXPECT_LT(rel, 0.05);
  // The weighting is recorded in the header: by default the fitted noise model, with its terms.
  EXPECT_THAT(img->attributes.at("merge_weighting"), HasSubstr("inverse variance"));
  const std::string hat = *dir_ + "/hat.exr";
  auto h = RunRig("hdr --list " + WriteList("ok") + " --out " + hat + " --weighting hat");
  ASSERT_EQ(h.status, 0) << h.output;
  auto hat_img = ReadExr(hat);
  ASSERT_TRUE(hat_img.ok());
  EXPECT_EQ(hat_img->attributes.at("merge_weighting"), "hat");
  EXPECT_EQ(RunRig("hdr --list " + WriteList("ok") + " --out " + hat + " --weighting best").status, 2);
}

TEST_F(HdrCommands, CompressionOptionIsTheFilesAndLeavesThePixelsAlone) {
  auto stored = [](const std::string& path) {
    Imf::InputFile in(path.c_str());
    return in.header().compression();
  };
  const std::string list = WriteList("compression");
  const std::string def = *dir_ + "/default.exr";
  auto r = RunRig("hdr --list " + list + " --out " + def);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(stored(def), Imf::RLE_COMPRESSION);  // the command's default (docs/hdr.md)
  auto reference = ReadExr(def);
  ASSERT_TRUE(reference.ok());
  for (auto [name, imf] : {std::pair{"zip", Imf::ZIP_COMPRESSION},
                           std::pair{"none", Imf::NO_COMPRESSION},
                           std::pair{"piz", Imf::PIZ_COMPRESSION}}) {
    const std::string out = *dir_ + "/c_" + name + ".exr";
    auto c = RunRig("hdr --list " + list + " --out " + out + " --compression " + name);
    ASSERT_EQ(c.status, 0) << c.output;
    EXPECT_EQ(stored(out), imf) << name;
    auto img = ReadExr(out);
    ASSERT_TRUE(img.ok());
    ASSERT_EQ(img->channel_names, reference->channel_names);
    for (size_t i = 0; i < img->channels.size(); ++i) {  // lossless: the same pixels, bit for bit
      EXPECT_EQ(cv::norm(img->channels[i], reference->channels[i], cv::NORM_INF), 0.0)
          << name << " " << img->channel_names[i];
    }
  }
  auto bad = RunRig("hdr --list " + list + " --out " + *dir_ + "/bad.exr --compression lzw");
  EXPECT_EQ(bad.status, 2);
  EXPECT_THAT(bad.output, HasSubstr("--compression"));
  EXPECT_FALSE(fs::exists(*dir_ + "/bad.exr"));
}

TEST_F(HdrCommands, BadListsFailWithExitTwoNamingTheFile) {
  // A missing image.
  auto r = RunRig("hdr --list " + WriteList("missing", "h040_v20/nope.jpg 0.5\n") + " --out " + *dir_ + "/x.exr");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("nope.jpg"));
  // A duplicate exposure time.
  const std::string dup = WriteList("dup");
  {
    std::ifstream in(dup);
    std::string first, line;
    std::getline(in, first);
    std::getline(in, line);
    std::ofstream(dup, std::ios::app) << line << "\n";
  }
  r = RunRig("hdr --list " + dup + " --out " + *dir_ + "/y.exr");
  EXPECT_EQ(r.status, 2) << r.output;
  // A truncated file.
  const fs::path cut = fs::path(*session_) / "frames" / "cut.jpg";
  {
    std::ifstream in(fs::path(*session_) / "frames" / "h040_v20" / "3_0.02000.jpg", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  }
  const fs::path list = fs::path(*session_) / "frames" / "cut.txt";
  std::ofstream(list) << "h040_v20/0_0.00250.jpg 0.0025\ncut.jpg 0.02\n";
  r = RunRig("hdr --list " + list.string() + " --out " + *dir_ + "/z.exr");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("cut.jpg"));
  EXPECT_FALSE(fs::exists(*dir_ + "/z.exr"));
}

TEST_F(HdrCommands, RatioCheckShowsTheIntensityRatioDriftingAndTheRadianceRatioConstant) {
  const std::string out = *dir_ + "/ratio";
  auto r = RunRig("ratio-check --list " + WriteList("ratio") + " --out " + out);
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(out + "/ratio_table.csv");
  std::string line;
  std::getline(in, line);
  double i_min = 1e300, i_max = 0, r_min = 1e300, r_max = 0;
  int rows = 0;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::vector<double> v;
    for (std::string c; std::getline(ss, c, ',');) v.push_back(c.empty() ? 0 : std::stod(c));
    if (v.size() == 4) v.push_back(0);  // no valid radiance in this frame (an empty last field)
    ASSERT_EQ(v.size(), 5u) << line;
    if (v[3] > 0) i_min = std::min(i_min, v[3]), i_max = std::max(i_max, v[3]);
    if (v[4] > 0) r_min = std::min(r_min, v[4]), r_max = std::max(r_max, v[4]);
    ++rows;
  }
  EXPECT_EQ(rows, 7);
  std::printf("intensity ratio %.3f .. %.3f, radiance ratio %.3f .. %.3f\n", i_min, i_max, r_min, r_max);
  EXPECT_GT(i_max / i_min, 1.15);  // drifts with the exposure
  EXPECT_LT(r_max / r_min, 1.10);  // constant up to noise (3% at 320x240, 8% at 96x72)
  EXPECT_GT(i_max / i_min - 1, 2 * (r_max / r_min - 1));
  EXPECT_FALSE(cv::imread(out + "/ratio_plot.png").empty());
}

}  // namespace
}  // namespace rig
