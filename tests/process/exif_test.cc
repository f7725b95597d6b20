// The lens from a photograph's EXIF: JPEGs whose EXIF the test writes with libexif (focal length
// with the focal plane's resolution; with a 35 mm equivalent only), one without EXIF, a missing
// file.
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>
#include <libexif/exif-data.h>
#include <opencv2/imgcodecs.hpp>

#include "process/io/exif.h"
#include "tests/support/exif_jpeg.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

TEST(Exif, FocalLengthAndSensorWidthFromTheFocalPlanesResolution) {
  const std::string dir = testing::FreshTempDir("exif");
  const std::string path = dir + "/a.jpg";
  // A 23.5 mm wide APS-C sensor, 6000 px across: 6000 / 23.5 px/mm, written per inch.
  testing::ExifTags tags;
  tags.focal_mm = 35;
  tags.focal_plane_x_res = 6000 / 23.5 * 25.4;
  tags.focal_plane_unit = 2;
  tags.pixel_x_dimension = 6000;
  ASSERT_TRUE(testing::WriteJpegWithExif(path, cv::Mat(200, 300, CV_8UC3, cv::Scalar(90, 90, 90)),
                                         tags));
  auto lens = ReadExifLens(path);
  ASSERT_TRUE(lens.ok()) << lens.error().ToString();
  EXPECT_TRUE(lens->has_exif);
  EXPECT_NEAR(lens->focal_mm, 35, 1e-6);
  EXPECT_EQ(lens->exif_width_px, 6000);
  const ExifFocal f = FocalFromExif(*lens, 300, 200);
  EXPECT_NEAR(f.focal_mm, 35, 1e-6);
  EXPECT_NEAR(f.sensor_width_mm, 23.5, 1e-3);
  EXPECT_NE(f.how.find("FocalPlaneXResolution"), std::string::npos) << f.how;
  // The same sensor given in centimetres.
  tags.focal_plane_x_res = 6000 / 2.35;
  tags.focal_plane_unit = 3;
  ASSERT_TRUE(testing::WriteJpegWithExif(path, cv::Mat(200, 300, CV_8UC3, cv::Scalar(90, 90, 90)),
                                         tags));
  auto cm = ReadExifLens(path);
  ASSERT_TRUE(cm.ok());
  EXPECT_NEAR(FocalFromExif(*cm, 300, 200).sensor_width_mm, 23.5, 1e-3);
  fs::remove_all(dir);
}

TEST(Exif, SensorWidthFromThe35mmEquivalent) {
  const std::string dir = testing::FreshTempDir("exif");
  const std::string path = dir + "/b.jpg";
  // 3:2 image: the 35 mm frame's width is 36 mm, so the sensor is 36 * f / f35 wide.
  testing::ExifTags tags;
  tags.focal_mm = 35;
  tags.focal_35mm = 52;
  ASSERT_TRUE(testing::WriteJpegWithExif(path, cv::Mat(200, 300, CV_8UC3, cv::Scalar(90, 90, 90)),
                                         tags));
  auto lens = ReadExifLens(path);
  ASSERT_TRUE(lens.ok()) << lens.error().ToString();
  EXPECT_NEAR(lens->focal_35mm, 52, 1e-9);
  EXPECT_EQ(lens->x_res_per_mm, 0);
  const ExifFocal f = FocalFromExif(*lens, 300, 200);
  EXPECT_NEAR(f.focal_mm, 35, 1e-9);
  EXPECT_NEAR(f.sensor_width_mm, 36.0 * 35 / 52, 1e-9);
  EXPECT_NE(f.how.find("FocalLengthIn35mmFilm"), std::string::npos) << f.how;
  // A focal length alone cannot place the sensor.
  testing::ExifTags bare;
  bare.focal_mm = 35;
  ASSERT_TRUE(testing::WriteJpegWithExif(path, cv::Mat(200, 300, CV_8UC3, cv::Scalar(90, 90, 90)),
                                         bare));
  auto b = ReadExifLens(path);
  ASSERT_TRUE(b.ok());
  EXPECT_TRUE(b->has_exif);
  EXPECT_EQ(FocalFromExif(*b, 300, 200).focal_mm, 0);
  fs::remove_all(dir);
}

TEST(Exif, AJpegWithoutExifAndAMissingFile) {
  const std::string dir = testing::FreshTempDir("exif");
  const std::string path = dir + "/plain.jpg";
  ASSERT_TRUE(cv::imwrite(path, cv::Mat(20, 30, CV_8UC3, cv::Scalar(1, 2, 3))));
  auto lens = ReadExifLens(path);
  ASSERT_TRUE(lens.ok()) << lens.error().ToString();
  EXPECT_FALSE(lens->has_exif);
  EXPECT_EQ(FocalFromExif(*lens, 30, 20).focal_mm, 0);
  auto missing = ReadExifLens(dir + "/none.jpg");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  EXPECT_NE(missing.error().ToString().find("none.jpg"), std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig


namespace rig {
namespace {

// Tags are untrusted: a focal length or sensor no camera has is refused, said so, never used.
TEST(Exif, ValuesOutsideAnyCameraAreNotUsed) {
  ExifLens lens;
  lens.has_exif = true;
  lens.focal_mm = 1e6;  // a kilometre-long lens
  lens.x_res_per_mm = 100;
  ExifFocal f = FocalFromExif(lens, 6000, 4000);
  EXPECT_EQ(f.focal_mm, 0);
  EXPECT_NE(f.how.find("outside any camera"), std::string::npos) << f.how;

  lens.focal_mm = 50;
  lens.x_res_per_mm = 1e9;  // a sensor 6 nm wide
  f = FocalFromExif(lens, 6000, 4000);
  EXPECT_EQ(f.focal_mm, 0);
  EXPECT_NE(f.how.find("outside any camera"), std::string::npos) << f.how;

  lens.x_res_per_mm = 250;  // 24 mm over 6000 px: a real camera, used
  f = FocalFromExif(lens, 6000, 4000);
  EXPECT_NEAR(f.focal_mm, 50, 1e-9);
  EXPECT_NEAR(f.sensor_width_mm, 24, 1e-9);
}

}  // namespace
}  // namespace rig
