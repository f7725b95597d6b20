// Tests of process/exr_io: round trips (half, float), attributes, errors naming the file.
#include "process/io/exr_io.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <ImfCompression.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>

namespace rig {
namespace {

namespace fs = std::filesystem;

fs::path TempDir() {
  fs::path d = fs::temp_directory_path() /
               ("rig_exr_io_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
                "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  fs::create_directories(d);
  return d;
}

cv::Mat TestImage(int w, int h) {
  cv::Mat img(h, w, CV_32FC3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      // Values over several decades, as a radiance map has.
      img.at<cv::Vec3f>(y, x) = cv::Vec3f(0.001f * (1 + x), 0.5f + y, 1000.0f / (1 + x + y));
    }
  }
  return img;
}

TEST(ExrIo, FloatRoundTripIsExactAndKeepsAttributes) {
  fs::path dir = TempDir();
  cv::Mat img = TestImage(37, 21);
  std::map<std::string, std::string> attrs = {{"pose", "h030_v10"},
                                              {"exposures_s", "0.01 0.1 1"}};
  std::string path = (dir / "a.exr").string();
  ASSERT_TRUE(WriteRgbExr(path, img, attrs, ExrPixelType::kFloat, 2).ok());
  std::map<std::string, std::string> read_attrs;
  auto r = ReadRgbExr(path, &read_attrs, 2);
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  EXPECT_EQ(cv::norm(*r, img, cv::NORM_INF), 0.0);
  EXPECT_EQ(read_attrs, attrs);
  // No temporary file is left beside the result.
  int files = 0;
  for (auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
  fs::remove_all(dir);
}

TEST(ExrIo, HalfRoundTripWithinHalfPrecision) {
  fs::path dir = TempDir();
  cv::Mat img = TestImage(16, 9);
  std::string path = (dir / "h.exr").string();
  auto w = WriteRgbExr(path, img, {{"k", "v"}}, ExrPixelType::kHalf, 1);
  ASSERT_TRUE(w.ok()) << w.error().ToString();
  auto r = ReadRgbExr(path);
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  cv::Mat rel;
  cv::divide(cv::abs(*r - img), img, rel);
  double max_rel = 0;
  cv::minMaxLoc(rel.reshape(1), nullptr, &max_rel);
  EXPECT_GT(max_rel, 0.0);       // it really was stored as half
  EXPECT_LT(max_rel, 1.0 / 1024);  // 10-bit mantissa
  fs::remove_all(dir);
}

// The compression the file's header says its pixels are stored with.
Imf::Compression StoredCompression(const std::string& path) {
  Imf::InputFile in(path.c_str());
  return in.header().compression();
}

TEST(ExrIo, EveryCompressionIsLosslessAndIsTheOneInTheHeader) {
  fs::path dir = TempDir();
  // Several decades times noise (no easy case for the predictors), an odd width and a height
  // that is no multiple of any codec's block of lines (16 for ZIP, 32 for PIZ).
  cv::Mat img = TestImage(203, 71), noise(71, 203, CV_32FC3);
  cv::randu(noise, 0.5, 1.5);
  img = img.mul(noise);
  cv::Mat as_half, half_rounded;  // what a half file must read back as: the nearest half
  img.convertTo(as_half, CV_16F);
  as_half.convertTo(half_rounded, CV_32F);
  ASSERT_GT(cv::norm(half_rounded, img, cv::NORM_INF), 0.0);
  const std::map<std::string, Imf::Compression> expected = {
      {"none", Imf::NO_COMPRESSION}, {"rle", Imf::RLE_COMPRESSION},
      {"zips", Imf::ZIPS_COMPRESSION}, {"zip", Imf::ZIP_COMPRESSION},
      {"zip-fast", Imf::ZIP_COMPRESSION}, {"piz", Imf::PIZ_COMPRESSION}};
  ASSERT_EQ(ExrCompressionNames().size(), expected.size());
  std::map<std::string, uintmax_t> float_size;
  for (const std::string& name : ExrCompressionNames()) {
    auto c = ParseExrCompression(name);
    ASSERT_TRUE(c.ok()) << name;
    EXPECT_STREQ(ExrCompressionName(*c), name.c_str());
    for (auto type : {ExrPixelType::kFloat, ExrPixelType::kHalf}) {
      const bool half = type == ExrPixelType::kHalf;
      const std::string path = (dir / (name + (half ? "_half.exr" : "_float.exr"))).string();
      auto w = WriteRgbExr(path, img, {{"k", "v"}}, type, 2, *c);
      ASSERT_TRUE(w.ok()) << name << ": " << w.error().ToString();
      EXPECT_EQ(StoredCompression(path), expected.at(name)) << name;
      std::map<std::string, std::string> attrs;
      auto r = ReadRgbExr(path, &attrs, 2);
      ASSERT_TRUE(r.ok()) << name << ": " << r.error().ToString();
      EXPECT_EQ(cv::norm(*r, half ? half_rounded : img, cv::NORM_INF), 0.0)
          << name << (half ? " half" : " float");
      EXPECT_EQ(attrs.at("k"), "v");
      if (!half) float_size[name] = fs::file_size(path);
    }
  }
  // The codecs really differ: noisy floats barely shrink without compression; zlib level 1 is
  // another encoding of the same pixels than level 6.
  EXPECT_GT(float_size["none"], 203u * 71 * 3 * 4);
  EXPECT_LT(float_size["zip"], float_size["none"]);
  EXPECT_LT(float_size["piz"], float_size["none"]);
  EXPECT_NE(float_size["zip-fast"], float_size["zip"]);
  fs::remove_all(dir);
}

TEST(ExrIo, UnknownCompressionIsAnErrorListingTheChoices) {
  auto c = ParseExrCompression("lzw");
  ASSERT_FALSE(c.ok());
  EXPECT_THAT(c.error().ToString(), ::testing::HasSubstr("'lzw'"));
  EXPECT_THAT(c.error().ToString(),
              ::testing::HasSubstr("none, rle, zips, zip, zip-fast, piz"));
}

// DWA, the lossy codec a model file may use: named only where lossy is asked for; the file says
// DWAA/DWAB; a model's half coefficient planes come back close (not exactly), its 'valid' plane
// exactly (DWA codes only channels named R, G, B), and the file is smaller than uncompressed.
TEST(ExrIo, DwaIsLossyForModelPlanesOnlyWhenAskedAndKeepsTheValidPlaneExact) {
  for (const char* name : {"dwaa", "dwab"}) {
    auto refused = ParseExrCompression(name);
    ASSERT_FALSE(refused.ok()) << name;
    EXPECT_THAT(refused.error().ToString(),
                ::testing::HasSubstr("(expected one of none, rle, zips, zip, zip-fast, piz)"));
    auto c = ParseExrCompression(name, /*lossy=*/true);
    ASSERT_TRUE(c.ok()) << name;
    EXPECT_TRUE(ExrCompressionIsLossy(*c));
  }
  EXPECT_THAT(ParseExrCompression("lzw", true).error().ToString(),
              ::testing::HasSubstr("none, rle, zips, zip, zip-fast, piz, dwaa, dwab"));
  for (const std::string& name : ExrCompressionNames())
    EXPECT_FALSE(ExrCompressionIsLossy(*ParseExrCompression(name))) << name;

  fs::path dir = TempDir();
  const int w = 96, h = 64;
  ExrImage img;
  img.width = w;
  img.height = h;
  cv::Mat valid(h, w, CV_32FC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) valid.at<float>(y, x) = ((x * 7 + y * 3) % 5) != 0 ? 1.f : 0.f;
  for (int k = 0; k < 4; ++k) {
    for (const char* ch : {"R", "G", "B"}) {
      // A smooth coefficient field over two decades, as a model's planes are across a scene.
      cv::Mat m(h, w, CV_32FC1);
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          m.at<float>(y, x) = static_cast<float>((0.05 + 0.9 * (x + y) / (w + h)) *
                                                 std::pow(0.3, k) * (1 + 0.2 * std::sin(0.2 * x)));
      img.channel_names.push_back("c0" + std::to_string(k) + "." + ch);
      img.channels.push_back(m);
    }
  }
  img.channel_names.push_back("valid");
  img.channels.push_back(valid);
  std::map<std::string, uintmax_t> size;
  for (const std::string name : {"none", "dwaa", "dwab"}) {
    const std::string path = (dir / (name + ".exr")).string();
    auto c = ParseExrCompression(name, true);
    ASSERT_TRUE(c.ok());
    auto wr = WriteExr(path, img, ExrPixelType::kHalf, 2, *c);
    ASSERT_TRUE(wr.ok()) << name << ": " << wr.error().ToString();
    size[name] = fs::file_size(path);
    const Imf::Compression stored = StoredCompression(path);
    EXPECT_EQ(stored, name == "dwaa"   ? Imf::DWAA_COMPRESSION
                      : name == "dwab" ? Imf::DWAB_COMPRESSION
                                       : Imf::NO_COMPRESSION)
        << name;
    auto r = ReadExr(path);
    ASSERT_TRUE(r.ok()) << name << ": " << r.error().ToString();
    double err2 = 0, ref2 = 0;
    bool changed = false;
    for (size_t i = 0; i < img.channel_names.size(); ++i) {
      const size_t j =
          std::find(r->channel_names.begin(), r->channel_names.end(), img.channel_names[i]) -
          r->channel_names.begin();
      ASSERT_LT(j, r->channel_names.size()) << img.channel_names[i];
      if (img.channel_names[i] == "valid") {
        EXPECT_EQ(cv::norm(r->channels[j], valid, cv::NORM_INF), 0.0) << name;
        continue;
      }
      cv::Mat as_half, rounded;
      img.channels[i].convertTo(as_half, CV_16F);
      as_half.convertTo(rounded, CV_32F);
      const double e = cv::norm(r->channels[j], rounded, cv::NORM_L2);
      changed |= e > 0;
      err2 += e * e;
      ref2 += std::pow(cv::norm(rounded, cv::NORM_L2), 2);
    }
    if (name == "none") {
      EXPECT_EQ(err2, 0.0);
    } else {
      EXPECT_TRUE(changed) << name << " stored the planes exactly: not the lossy codec";
      EXPECT_LT(std::sqrt(err2 / ref2), 0.02) << name;
    }
  }
  EXPECT_LT(size["dwaa"], size["none"] / 2);
  EXPECT_LT(size["dwab"], size["none"] / 2);
  fs::remove_all(dir);
}

TEST(ExrIo, GenericChannelsKeepNamesAndValues) {
  fs::path dir = TempDir();
  ExrImage img;
  img.width = 5;
  img.height = 3;
  for (int i = 0; i < 3; ++i) {
    img.channel_names.push_back("c0" + std::to_string(i) + ".R");
    img.channels.push_back(cv::Mat(3, 5, CV_32FC1, cv::Scalar(i * 1.5 - 1)));
  }
  img.channel_names.push_back("flags");
  img.channels.push_back(cv::Mat(3, 5, CV_32FC1, cv::Scalar(2)));
  std::string path = (dir / "g.exr").string();
  ASSERT_TRUE(WriteExr(path, img).ok());
  auto r = ReadExr(path);
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  ASSERT_EQ(r->channel_names.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    // Channels come back sorted by name (EXR's order); find each by name.
    size_t j = std::find(r->channel_names.begin(), r->channel_names.end(), img.channel_names[i]) -
               r->channel_names.begin();
    ASSERT_LT(j, 4u);
    EXPECT_EQ(cv::norm(r->channels[j], img.channels[i], cv::NORM_INF), 0.0);
  }
  fs::remove_all(dir);
}

TEST(ExrIo, MissingFileErrorNamesFile) {
  auto r = ReadExr("/nonexistent/dir/x.exr");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().code, ErrorCode::kNotFound);
  EXPECT_NE(r.error().ToString().find("/nonexistent/dir/x.exr"), std::string::npos);
}

TEST(ExrIo, TruncatedFileErrorNamesFile) {
  fs::path dir = TempDir();
  std::string path = (dir / "t.exr").string();
  ASSERT_TRUE(WriteRgbExr(path, TestImage(64, 64)).ok());
  fs::resize_file(path, fs::file_size(path) / 2);
  auto r = ReadRgbExr(path);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().ToString().find(path), std::string::npos);
  std::ofstream(dir / "junk.exr") << "not an exr file";
  auto j = ReadExr((dir / "junk.exr").string());
  ASSERT_FALSE(j.ok());
  EXPECT_NE(j.error().ToString().find("junk.exr"), std::string::npos);
  fs::remove_all(dir);
}

TEST(ExrIo, WriteWhereNoFolderCanBeMadeFailsNamingFile) {
  // A missing folder is made (a removed hdr/ forces a re-merge); under a file it cannot be.
  auto s = WriteRgbExr("/dev/null/dir/out.exr", TestImage(4, 4));
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().ToString().find("/dev/null/dir/out.exr"), std::string::npos);
}

TEST(ExrIo, RejectsWrongChannelType) {
  ExrImage img;
  img.width = 2;
  img.height = 2;
  img.channel_names = {"Y"};
  img.channels = {cv::Mat(2, 2, CV_8UC1, cv::Scalar(1))};
  auto s = WriteExr("/tmp/never_written.exr", img);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidInput);
}

TEST(ExrIo, ReadsSharedDeskExr) {
  const char* shared = std::getenv("RIG_SHARED_DIR");
  fs::path p = fs::path(shared ? shared : "/work/shared") / "data/hdr/Desk.exr";
  if (!fs::exists(p)) GTEST_SKIP() << p << " not present";
  auto r = ReadRgbExr(p.string());
  ASSERT_TRUE(r.ok()) << r.error().ToString();
  EXPECT_GT(r->cols, 100);
  EXPECT_GT(r->rows, 100);
  double mn, mx;
  cv::minMaxLoc(r->reshape(1), &mn, &mx);
  EXPECT_GT(mn, -1.0);  // the file holds a few small negative values
  EXPECT_GT(mx, 1.0);
}

}  // namespace
}  // namespace rig
