// The model EXR header is untrusted input: every number finite and in range, no cast before
// the check, and `rig render` answers a damaged header with exit 2, not an internal check.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "process/io/exr_io.h"
#include "process/model/harmonic/model.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;

Model TinyModel() {
  auto basis = Basis::Create("sh", 1);
  EXPECT_TRUE(basis.ok());
  ModelInfo info;
  info.lamp_radiance_rgb = {1, 1, 1};
  info.lamp_directions = {{0, 0, 1}, {0.5, 0, 0.866}};
  Model m(*basis, info, 8, 6);
  for (int k = 0; k < basis->size(); ++k) m.coefficients().push_back(cv::Mat(6, 8, CV_32FC3, cv::Scalar(0.1, 0.2, 0.3)));
  return m;
}

TEST(ModelHeader, NonFiniteAndOutOfRangeNumbersAreRefusedNamingTheKey) {
  const auto good = ModelHeaderAttributes(TinyModel());
  ASSERT_TRUE(ModelFromHeader(good, 8, 6, "m.exr").ok());
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"light_frame.h_offset_deg", "inf"}, {"light_frame.h_offset_deg", "nan"},
      {"light_frame.h_sign", "0"},         {"light_frame.h_sign", "1e300"},
      {"light_frame.v_sign", "-2"},        {"order", "1e300"},
      {"order", "1.5"},                    {"order", "nan"},
      {"flagged_pixels", "1e300"},         {"flagged_pixels", "-1"}, {"flagged_pixels", "12x"},
      {"lamp_radiance_rgb", "1 inf 1"},    {"lamp_radiance_rgb", "1 0 1"},
      {"fit_space_log_epsilon", "inf"},    {"light_frame.v_offset_deg", "12abc"},
      {"lamp_directions", "0 0 1;nan 0 1"},
  };
  for (const auto& [key, value] : cases) {
    auto a = good;
    a[key] = value;
    auto m = ModelFromHeader(a, 8, 6, "m.exr");
    ASSERT_FALSE(m.ok()) << key << " = " << value;
    EXPECT_EQ(m.error().ExitCode(), 2) << key;
    EXPECT_THAT(m.error().ToString(), HasSubstr("m.exr")) << key;
    EXPECT_THAT(m.error().ToString(), HasSubstr(key.substr(0, key.find('.') == std::string::npos ? key.size() : key.find('.')))) << key << ": " << m.error().ToString();
  }
}

TEST(ModelHeader, RenderOfAModelWithAnInfiniteOffsetExits2) {
  const std::string dir = testing::FreshTempDir("model_header");
  const std::string path = dir + "/model.exr";
  ASSERT_TRUE(SaveModel(path, TinyModel(), ExrPixelType::kFloat).ok());
  auto img = ReadExr(path);
  ASSERT_TRUE(img.ok());
  img->attributes["light_frame.h_offset_deg"] = "inf";
  ASSERT_TRUE(WriteExr(dir + "/bad.exr", *img).ok());
  auto r = testing::RunRig("render " + dir + "/bad.exr --light 0,45 --extrapolate --out " + dir + "/out.png");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("light_frame.h_offset_deg"));
  EXPECT_THAT(r.output, ::testing::Not(HasSubstr("internal error")));
  // The undamaged model renders.
  r = testing::RunRig("render " + path + " --light 0,45 --extrapolate --out " + dir + "/ok.png");
  EXPECT_EQ(r.status, 0) << r.output;
}

}  // namespace
}  // namespace rig
