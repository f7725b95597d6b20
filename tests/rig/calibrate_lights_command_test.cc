// `rig calibrate-lights` and `rig normals` on a dry-run session with a chrome and a matte sphere
// and arm offsets the rig does not know: the directions within 0.5 deg of the simulator's truth,
// the offsets within 0.2 deg, the normals within 2 deg on unshadowed surfaces, and the refusals.
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <opencv2/imgcodecs.hpp>
#include <toml++/toml.h>
#include <gtest/gtest.h>

#include "config/config.h"
#include "process/geometry/photometric_stereo.h"
#include "process/geometry/sphere_lights.h"
#include "process/io/exr_io.h"
#include "process/model/harmonic/fit.h"
#include "sim/scene.h"
#include "sim/truth.h"
#include "tests/support/exif_jpeg.h"
#include "tests/support/dry_session.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

class CalibrateLights : public testing::DrySessionSuite<CalibrateLights> {
 protected:
  static void SetUpTestSuite() {
    Capture("lights", R"([light_frame]
h_offset_deg = 2.5
v_offset_deg = -1.5
[sim]
scene = 'matte'
chrome_spheres = 1
matte_sphere = true
)");
  }
};

// The fitted offsets and the .lp's directions against the truth, from a run's files; the
// largest direction error in `worst_out` if given.
void CheckRun(const std::string& calib, double offset_tol, double dir_tol, const char* what,
              double* worst_out = nullptr) {
  toml::table t = toml::parse_file(calib + "/light_frame.toml");
  const double h_off = t["light_frame"]["h_offset_deg"].value_or(1e9);
  const double v_off = t["light_frame"]["v_offset_deg"].value_or(1e9);
  auto truth = LoadTruth(calib + "/../truth");
  ASSERT_TRUE(truth.ok());
  std::ifstream csv(calib + "/lights.csv");
  std::string line;
  std::getline(csv, line);
  double sum = 0, worst = 0;
  int n = 0;
  while (std::getline(csv, line)) {
    std::stringstream ss(line);
    std::string pose, f;
    std::vector<double> v;
    std::getline(ss, pose, ',');
    while (std::getline(ss, f, ',')) v.push_back(std::stod(f));
    ASSERT_EQ(v.size(), 6u);
    const double e = AngleDeg({v[2], v[3], v[4]}, LightDirection(v[0], v[1], truth->light_frame));
    sum += e;
    worst = std::max(worst, e);
    ++n;
  }
  ASSERT_EQ(n, 40);
  std::printf("dry-run session, %s: offsets h %.3f (truth 2.5), v %.3f (truth -1.5); directions "
              "mean %.3f deg, max %.3f deg from truth\n", what, h_off, v_off, sum / n, worst);
  EXPECT_NEAR(h_off, 2.5, offset_tol) << what;
  EXPECT_NEAR(v_off, -1.5, offset_tol) << what;
  EXPECT_EQ(t["light_frame"]["h_sign"].value_or(0), 1);
  EXPECT_EQ(t["light_frame"]["v_sign"].value_or(0), 1);
  EXPECT_LT(sum / n, dir_tol) << what;
  EXPECT_LT(worst, dir_tol) << what;
  if (worst_out) *worst_out = worst;
}

TEST_F(CalibrateLights, RecoversDirectionsAndArmOffsetsFromTheSphere) {
  // The sphere's true circle, as given: the highlights alone meet the goals (0.5 deg, 0.2 deg).
  auto truth = LoadTruth(*session_ + "/truth");
  ASSERT_TRUE(truth.ok());
  const auto c = truth->scene.CalibrationSpheres()[0];
  auto g = RunRig(fmt::format("calibrate-lights {} --sphere {},{},{} --as-given --out {}/calib/given.lp",
                              *session_, c.cx_px, c.cy_px, c.r_px, *session_));
  ASSERT_EQ(g.status, 0) << g.output;
  CheckRun(*session_ + "/calib", 0.2, 0.5, "circle given");
  // Found automatically, through the camera (noise, JPEG, the merge): the same goals. (The
  // sphere's dark limb sits on the merge's noise floor there, which once made a checker edge
  // of the background 2 px outside the limb the steeper one in the log and moved the circle
  // 0.4 px: 1.3 deg of light.)
  auto r = RunRig("calibrate-lights " + *session_ + " --force");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("orthographic"));
  EXPECT_THAT(r.output, HasSubstr("h090_v30"));  // the residual of every pose is printed
  CheckRun(*session_ + "/calib", 0.2, 0.5, "circle found");
  // Never overwritten without --force.
  auto again = RunRig("calibrate-lights " + *session_);
  EXPECT_EQ(again.status, 2) << again.output;
  EXPECT_THAT(again.output, HasSubstr("exists"));
}

TEST_F(CalibrateLights, NormalsOfTheSessionWithinTwoDegreesOnUnshadowedSurfaces) {
  const std::string out = *dir_ + "/n/normals.exr";
  auto r = RunRig("normals " + *session_ + " --out " + out + " --height " + *dir_ + "/n/height.exr");
  ASSERT_EQ(r.status, 0) << r.output;
  for (const char* f : {"normals.png", "normals-albedo.png", "normals-albedo.exr", "height.exr"})
    EXPECT_TRUE(fs::exists(*dir_ + "/n/" + f)) << f;
  auto exr = ReadExr(out);
  ASSERT_TRUE(exr.ok());
  // Channels by name (OpenEXR lists them sorted): R = x, G = y, B = z.
  std::vector<cv::Mat> xyz(3);
  for (size_t c = 0; c < exr->channel_names.size(); ++c)
    for (int k = 0; k < 3; ++k)
      if (exr->channel_names[c] == std::string(1, "RGB"[k])) xyz[k] = exr->channels[c];
  ASSERT_FALSE(xyz[0].empty() || xyz[1].empty() || xyz[2].empty());
  cv::Mat n;
  cv::merge(xyz, n);
  auto truth = LoadTruth(*session_ + "/truth");
  ASSERT_TRUE(truth.ok());
  const SimScene& s = truth->scene;
  // Unshadowed: lit in every pose; and away from the gloss (the matte sphere, the plane).
  cv::Mat mask(s.height(), s.width(), CV_8UC1, cv::Scalar(1));
  for (const Pose& p : truth->poses) {
    const cv::Mat rho = truth->BrdfAtAngles(p.h_deg, p.v_deg);
    for (int y = 0; y < rho.rows; ++y)
      for (int x = 0; x < rho.cols; ++x)
        if (rho.at<cv::Vec3f>(y, x)[1] <= 0) mask.at<uint8_t>(y, x) = 0;
  }
  const cv::Mat ids = s.MaterialIds();
  for (auto [id, name, goal] : {std::tuple{SimMaterialId::kMatte, "matte sphere", 2.0},
                                {SimMaterialId::kPlane, "plane", 2.0},
                                {SimMaterialId::kSphere, "main sphere", 2.0}}) {
    cv::Mat m = (ids == static_cast<uint8_t>(id)) / 255;
    m = m.mul(mask);
    auto e = NormalError(n, s.Normals(), m);
    std::printf("dry-run session normals, %s (%zu px): mean %.2f deg, p95 %.2f deg\n", name,
                e.pixels, e.mean_deg, e.p95_deg);
    EXPECT_GT(e.pixels, 100u);
    EXPECT_LT(e.mean_deg, goal) << name;
  }
  // A second run onto the same file is refused.
  auto again = RunRig("normals " + *session_ + " --out " + out);
  EXPECT_EQ(again.status, 2);
}

TEST_F(CalibrateLights, AMatteSphereGivenAsTheSphereIsRefusedNamingTheImage) {
  auto truth = LoadTruth(*session_ + "/truth");
  ASSERT_TRUE(truth.ok());
  const auto spheres = truth->scene.CalibrationSpheres();
  ASSERT_EQ(spheres.size(), 2u);
  const auto& m = spheres[1];
  auto r = RunRig(fmt::format("calibrate-lights {} --out {}/x.lp --sphere {},{},{}", *session_,
                              *dir_, m.cx_px, m.cy_px, m.r_px));
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("no highlight"));
  EXPECT_THAT(r.output, HasSubstr("h000_v00"));
  EXPECT_FALSE(fs::exists(*dir_ + "/x.lp"));
  auto bad = RunRig("calibrate-lights " + *session_ + " --sphere 10,10");
  EXPECT_EQ(bad.status, 2);
  EXPECT_THAT(bad.output, HasSubstr("CX,CY,R"));
}

TEST_F(CalibrateLights, TheLampsDistanceNeedsTwoSpheres) {
  // This session has one chrome sphere: asking for the lamp's position is bad input.
  auto r = RunRig(fmt::format("calibrate-lights {} --field-height-mm 100 --out {}/one.lp",
                              *session_, *dir_));
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("two or more chrome spheres"));
  auto d = RunRig(fmt::format("calibrate-lights {} --sphere-depth-mm 5 --out {}/one.lp",
                              *session_, *dir_));
  EXPECT_EQ(d.status, 2) << d.output;
  EXPECT_THAT(d.output, HasSubstr("--field-height-mm"));
}

// A session whose lamp is 300 mm from the arm's centre (the simulator's exact near lamp) with
// two chrome spheres; the rig's config knows the field's height, not the lamp's distance.
class CalibrateNearLamp : public testing::DrySessionSuite<CalibrateNearLamp> {
 protected:
  static void SetUpTestSuite() {
    Capture("nearlamp", R"([light_frame]
h_offset_deg = 2.5
v_offset_deg = -1.5
field_height_mm = 100
[sim]
scene = 'matte'
chrome_spheres = 2
lamp_distance_mm = 300
field_height_mm = 100
)");
  }
};

// The median distance and the median 1-sigma of the images with a distance, from lamp.csv.
void ReadLampCsv(const std::string& path, double* median_sigma, int* determined) {
  std::ifstream csv(path);
  ASSERT_TRUE(csv.good()) << path;
  std::string line;
  std::getline(csv, line);
  std::vector<double> sigma;
  *determined = 0;
  while (std::getline(csv, line)) {
    std::stringstream ss(line);
    std::string f;
    std::vector<std::string> v;
    while (std::getline(ss, f, ',')) v.push_back(f);
    ASSERT_EQ(v.size(), 9u);
    if (v[1] != "1") continue;
    ++*determined;
    sigma.push_back(std::stod(v[6]));
  }
  ASSERT_FALSE(sigma.empty());
  std::sort(sigma.begin(), sigma.end());
  *median_sigma = sigma[sigma.size() / 2];
}

TEST_F(CalibrateNearLamp, TwoSpheresGiveTheLampsDistanceAndDirectionsFromTheArmsCentre) {
  auto truth = LoadTruth(*session_ + "/truth");
  ASSERT_TRUE(truth.ok());
  const SimScene& scene = truth->scene;
  std::string args;
  for (const auto& c : scene.CalibrationSpheres())
    args += fmt::format(" --sphere {},{},{} --sphere-depth-mm {}", c.cx_px, c.cy_px, c.r_px,
                        c.center[2] * scene.mm_per_unit());
  auto r = RunRig("calibrate-lights " + *session_ + args);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("lamp: near"));
  EXPECT_THAT(r.output, HasSubstr("suggested: [light_frame] lamp_distance_mm = "));
  // The offsets and directions from the arm's centre meet the far lamp's goals (0.2, 0.5 deg).
  CheckRun(*session_ + "/calib", 0.2, 0.5, "near lamp, two spheres, depths given");
  toml::table t = toml::parse_file(*session_ + "/calib/light_frame.toml");
  const double d = t["light_frame"]["lamp_distance_mm"].value_or(-1.0);
  EXPECT_EQ(t["light_frame"]["field_height_mm"].value_or(-1.0), 100.0);
  double sigma = 0;
  int determined = 0;
  ReadLampCsv(*session_ + "/calib/lamp.csv", &sigma, &determined);
  std::printf("dry-run session, near lamp 300 mm, depths given: lamp_distance_mm %.1f, %d of 40 "
              "images with a distance, their median 1-sigma %.1f mm\n", d, determined, sigma);
  // Within the 1-sigma the spheres' size gives (a tenth of a pixel of highlight on a 26 px
  // sphere over their ~100 mm baseline).
  EXPECT_NEAR(d, 300, sigma);
  EXPECT_GE(determined, 20);
  // The surface under the spheres, were they resting on it: their centres' z minus their radii
  // (the simulator's float in front of its plane, so this is not the plane's depth; printed).
  double under = 0;
  const auto views = scene.CalibrationSpheres();
  for (const auto& c : views)
    under += (c.center[2] * scene.mm_per_unit() - c.r_px * 100.0 / scene.height()) / views.size();
  const auto at = r.output.find("suggested surface_depth_mm = ");
  ASSERT_NE(at, std::string::npos) << r.output;
  const double suggested = std::stod(r.output.substr(at + 29));
  std::printf("dry-run session, depths given: suggested surface_depth_mm %.1f (spheres' bottoms; "
              "the plane lies at %.1f)\n", suggested, scene.plane_depth_mm());
  EXPECT_NEAR(suggested, under, 0.5);  // the circles refined to the edge: a few tenths of a px
  EXPECT_THAT(testing::ReadText(*session_ + "/calib/light_frame.toml"),
              HasSubstr("# surface_depth_mm = "));

  // The depths not given: both spheres assumed resting on the plane through the arm's centre
  // (the simulator's float 15 and 35 mm behind it). Printed; still near, still a distance.
  auto a = RunRig("calibrate-lights " + *session_ + " --force");
  ASSERT_EQ(a.status, 0) << a.output;
  EXPECT_THAT(a.output, HasSubstr("assumed resting on the plane"));
  EXPECT_THAT(a.output, HasSubstr("surface_depth_mm unset"));
  double worst_assumed = 0;
  CheckRun(*session_ + "/calib", 90, 90, "near lamp, two spheres, depths assumed", &worst_assumed);
  toml::table ta = toml::parse_file(*session_ + "/calib/light_frame.toml");
  std::printf("dry-run session, near lamp 300 mm, depths assumed: lamp_distance_mm %.1f\n",
              ta["light_frame"]["lamp_distance_mm"].value_or(-1.0));

  // The depths fitted from the arm's geometry (the lamp's one distance), from that assumption:
  // the largest direction error a third of the assumption's at most, under 1.5 deg (the depths
  // come out ~5 mm off through the camera, inside their ~10 mm 1-sigma; 0.6 deg on exact
  // radiance, process_lights_test), the offsets within 1 deg, the distance within 1-sigma.
  auto f = RunRig("calibrate-lights " + *session_ + " --fit-sphere-depths --force");
  ASSERT_EQ(f.status, 0) << f.output;
  EXPECT_THAT(f.output, HasSubstr("sphere depths fitted"));
  double worst_fitted = 0;
  CheckRun(*session_ + "/calib", 1.0, 1.5, "near lamp, two spheres, depths fitted", &worst_fitted);
  EXPECT_LT(worst_fitted, worst_assumed / 3);
  toml::table tf = toml::parse_file(*session_ + "/calib/light_frame.toml");
  const double df = tf["light_frame"]["lamp_distance_mm"].value_or(-1.0);
  std::printf("dry-run session, near lamp 300 mm, depths fitted: lamp_distance_mm %.1f\n", df);
  EXPECT_NEAR(df, 300, sigma);
}

// 12 JPEGs of the simulator's exact scene (one chrome sphere, far lamp) in `dir`, with EXIF
// `tags` or none; their true directions. `sphere`: the chrome sphere's true circle, as
// --sphere's argument.
std::vector<Vec3> WriteSimJpegs(const std::string& dir, const testing::ExifTags* tags,
                                std::string* sphere = nullptr) {
  SimConfig sim;
  sim.scene = "matte";
  sim.chrome_spheres = 1;
  auto scene = SimScene::Create(sim);
  EXPECT_TRUE(scene.ok());
  fs::create_directories(dir);
  const auto c = scene->CalibrationSpheres()[0];
  if (sphere) *sphere = fmt::format("{},{},{}", c.cx_px, c.cy_px, c.r_px);
  std::vector<Vec3> truth;
  for (int h = 0; h <= 90; h += 30)  // the order of the sorted file names, the .lp's
    for (int v = 0; v <= 20; v += 10) {
      const Vec3 l = LightDirection(h, v);
      cv::Mat rad = scene->Radiance(l, {1, 1, 1});
      // The plane's light cells near 0.5 of white: the chrome highlight clips over a few pixels.
      rad *= 0.5 / 3000.0;
      cv::Mat img(rad.rows, rad.cols, CV_8UC3);
      for (int y = 0; y < rad.rows; ++y)
        for (int x = 0; x < rad.cols * 3; ++x)
          img.ptr<uint8_t>(y)[x] = static_cast<uint8_t>(std::lround(
              255 * SrgbEncode(std::clamp(rad.ptr<float>(y)[x], 0.0f, 1.0f))));
      const std::string path = fmt::format("{}/h{:03d}_v{:02d}.jpg", dir, h, v);
      if (tags)
        EXPECT_TRUE(testing::WriteJpegWithExif(path, img, *tags));
      else
        EXPECT_TRUE(cv::imwrite(path, img, {cv::IMWRITE_JPEG_QUALITY, 95}));
      truth.push_back(l);
    }
  return truth;
}

// The .lp's directions against `truth`: the largest angle.
double WorstLpError(const std::string& lp, const std::vector<Vec3>& truth) {
  std::ifstream in(lp);
  std::string line;
  std::getline(in, line);
  double worst = 0;
  for (size_t k = 0; k < truth.size() && std::getline(in, line); ++k) {
    std::stringstream ss(line);
    std::string name;
    Vec3 d;
    ss >> name >> d[0] >> d[1] >> d[2];
    worst = std::max(worst, AngleDeg(d, truth[k]));
  }
  return worst;
}

TEST(CalibrateLightsExif, TheFocalLengthComesFromTheExifOrTheModelIsOrthographicSaidSo) {
  const std::string dir = testing::FreshTempDir("lights-exif");
  // A machine-vision body: an 800 mm lens on a sensor 6.4 mm wide (the 320 px image at 500 px
  // per cm, no PixelXDimension: the image's own width): 40000 px, near-orthographic.
  testing::ExifTags tags;
  tags.focal_mm = 800;
  tags.focal_plane_x_res = 500;
  tags.focal_plane_unit = 3;
  std::string sphere;
  const auto truth = WriteSimJpegs(dir + "/exif", &tags, &sphere);
  // The sphere given (its true circle): this test is about the camera model, not the finding.
  auto r = RunRig(fmt::format("calibrate-lights --images {}/exif --out {}/exif.lp --sphere {} "
                              "--as-given", dir, dir, sphere));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("perspective, focal length 40000.0 px"));
  EXPECT_THAT(r.output, HasSubstr("from the EXIF of"));
  EXPECT_THAT(r.output, HasSubstr("h000_v00.jpg: EXIF FocalLength 800.00 mm, sensor 6.40 mm wide"));
  // 8-bit JPEGs whose highlight clips over a few pixels: within a degree (the sessions' HDR
  // maps reach 0.5 deg); a 40000 px lens bends the view rays at the sphere by ~0.2 deg only.
  const double with_exif = WorstLpError(dir + "/exif.lp", truth);
  EXPECT_LT(with_exif, 1.0);
  // --focal-mm overrides the EXIF, and says so; a wide lens moves the directions.
  auto g = RunRig(fmt::format("calibrate-lights --images {}/exif --out {}/given.lp --focal-mm 8 "
                              "--sensor-width-mm 6.4 --sphere {} --as-given", dir, dir, sphere));
  ASSERT_EQ(g.status, 0) << g.output;
  EXPECT_THAT(g.output, HasSubstr("focal length 400.0 px"));
  EXPECT_THAT(g.output, HasSubstr("from --focal-mm 8"));
  EXPECT_GT(WorstLpError(dir + "/given.lp", truth), 2.0);
  // --orthographic ignores the EXIF.
  auto o = RunRig(fmt::format("calibrate-lights --images {}/exif --out {}/ortho.lp --orthographic "
                              "--sphere {} --as-given", dir, dir, sphere));
  ASSERT_EQ(o.status, 0) << o.output;
  EXPECT_THAT(o.output,
              HasSubstr("orthographic (view direction +z at every pixel); --orthographic"));
  // No EXIF: orthographic, and the output says why.
  WriteSimJpegs(dir + "/plain", nullptr);
  auto p = RunRig(fmt::format("calibrate-lights --images {}/plain --out {}/plain.lp --sphere {} "
                              "--as-given", dir, dir, sphere));
  ASSERT_EQ(p.status, 0) << p.output;
  EXPECT_THAT(p.output, HasSubstr("orthographic"));
  EXPECT_THAT(p.output, HasSubstr("has no EXIF"));
  const double plain = WorstLpError(dir + "/plain.lp", truth);
  std::printf("JPEGs with EXIF (800 mm on 6.4 mm): worst direction %.3f deg; without EXIF "
              "(orthographic): %.3f deg\n", with_exif, plain);
  EXPECT_LT(plain, 1.0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rig
