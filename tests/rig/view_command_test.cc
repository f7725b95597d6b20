// `rig view`: the page in Debian's headless Chromium (SwiftShader WebGL2), served from a
// loopback HTTP server in this process (and once from file://), every other host unresolvable.
// The page's pixels at given lights are compared with `rig render` of the same lights.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "process/export/relight_coefficients.h"
#include "process/export/relight_files.h"
#include "process/io/exr_io.h"
#include "process/io/jpeg_io.h"
#include "process/model/harmonic/fit.h"
#include "process/model/light_direction.h"
#include "process/model/harmonic/model.h"
#include "process/model/pca/pca.h"
#include "tests/support/relight_pca_folder.h"
#include "tests/support/run_rig.h"
#include "tests/support/browser.h"
#include "tests/support/synthetic_model.h"

// Last: it pulls in <resolv.h>, whose _res macro breaks Eigen's headers.
#include <fcntl.h>
#include <httplib.h>

namespace rig {
namespace {

using testing::Chromium;

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

// What the page sent back.
struct PageRun {
  std::map<int, cv::Mat> shots;  // RGB, 8-bit
  nlohmann::json done;
  std::vector<std::string> requests;  // paths the server saw
  bool finished = false;
  double wall_s = 0;
};

// Serves `dir` on 127.0.0.1, opens `page` (a path under it, or a file:// URL when `file_url`)
// in headless Chromium with ?report=<server> (the hook added to the test's copy), waits for /done.
// The test's own copy of the page: `dir`/viewer.js (written by rig view, which publishes no
// test hook) with tests/rig/viewer_report_hook.js put inside its closure.
void AddReportHook(const std::string& dir) {
  const std::string js_path = dir + "/viewer.js";
  std::string js = testing::ReadText(js_path);
  if (js.find("params.get('report')") != std::string::npos) return;  // added already
  const std::string mark = "  // (the test hook goes here";
  const size_t at = js.find(mark);
  ASSERT_NE(at, std::string::npos) << js_path << " has no place marked for the test hook";
  js.insert(at, testing::ReadText(testing::SourceDir() + "/tests/rig/viewer_report_hook.js"));
  std::ofstream(js_path, std::ios::binary) << js;
}

PageRun RunPage(const std::string& dir, const std::string& query, bool file_url = false,
                int width = 400, int height = 320, int timeout_s = 60) {
  PageRun run;
  AddReportHook(dir);
  std::mutex mu;
  std::condition_variable cv;
  httplib::Server server;
  EXPECT_TRUE(server.set_mount_point("/", dir));
  server.set_logger([&](const httplib::Request& req, const httplib::Response&) {
    std::lock_guard<std::mutex> lock(mu);
    run.requests.push_back(req.path);
  });
  server.Post("/report/shot", [&](const httplib::Request& req, httplib::Response& res) {
    const int i = std::stoi(req.get_param_value("i")), w = std::stoi(req.get_param_value("w")),
              h = std::stoi(req.get_param_value("h"));
    cv::Mat rgba(h, w, CV_8UC4);
    if (req.body.size() == rgba.total() * 4) {
      std::memcpy(rgba.data, req.body.data(), req.body.size());
      cv::Mat rgb;
      cv::cvtColor(rgba, rgb, cv::COLOR_RGBA2RGB);
      std::lock_guard<std::mutex> lock(mu);
      run.shots[i] = rgb;
    }
    res.set_header("Access-Control-Allow-Origin", "*");
  });
  server.Post("/report/done", [&](const httplib::Request& req, httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mu);
    run.done = nlohmann::json::parse(req.body, nullptr, false);
    run.finished = true;
    res.set_header("Access-Control-Allow-Origin", "*");
    cv.notify_all();
  });
  const int port = server.bind_to_any_port("127.0.0.1");
  std::thread serving([&] { server.listen_after_bind(); });
  const std::string origin = fmt::format("http://127.0.0.1:{}", port);
  const std::string url = (file_url ? "file://" + fs::absolute(dir).string() + "/index.html" : origin + "/index.html") +
                          "?report=" + origin + "/report&" + query;
  const std::string profile = testing::FreshTempDir("chromium-profile");
  const std::vector<std::string> args = {
      Chromium(), "--headless=new", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader", fmt::format("--window-size={},{}", width, height),
      "--user-data-dir=" + profile, "--no-first-run", "--no-default-browser-check",
      "--disable-background-networking", "--disable-component-update", "--disable-sync",
      "--disable-extensions", "--no-proxy-server", "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
      url};
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    setpgid(0, 0);
    const int null = ::open("/dev/null", O_WRONLY);
    dup2(null, 1);
    dup2(null, 2);
    std::vector<char*> argv;
    for (const auto& s : args) argv.push_back(const_cast<char*>(s.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_for(lock, std::chrono::seconds(timeout_s), [&] { return run.finished; });
  }
  run.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (pid > 0) {
    kill(-pid, SIGKILL);
    waitpid(pid, nullptr, 0);
  }
  server.stop();
  serving.join();
  std::error_code ec;
  fs::remove_all(profile, ec);
  return run;
}

// `rig render MODEL --light H,V` as RGB bytes.
cv::Mat Render(const std::string& model, double h, double v, const std::string& out) {
  const auto r = RunRig(fmt::format("render {} --light {},{} --out {}", model, h, v, out));
  EXPECT_EQ(r.status, 0) << r.output;
  cv::Mat bgr = cv::imread(out, cv::IMREAD_COLOR);
  cv::Mat rgb;
  if (!bgr.empty()) cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  return rgb;
}

struct Diff {
  double mean = 1e9;
  int max = 255;
};
Diff Compare(const cv::Mat& a, const cv::Mat& b) {
  Diff d;
  if (a.empty() || b.empty() || a.size() != b.size()) return d;
  cv::Mat diff;
  cv::absdiff(a, b, diff);
  d.mean = cv::mean(cv::mean(diff))[0] / 1.0;
  const cv::Scalar m = cv::mean(diff);
  d.mean = (m[0] + m[1] + m[2]) / 3;
  double mx;
  cv::minMaxLoc(diff.reshape(1), nullptr, &mx);
  d.max = static_cast<int>(mx);
  return d;
}

std::string Shots(const std::vector<std::pair<double, double>>& angles) {
  std::string s = "fit=native&ui=0&shots=";
  for (size_t i = 0; i < angles.size(); ++i) {
    const Vec3 d = LightDirection(angles[i].first, angles[i].second);
    s += fmt::format("{}{:.9f},{:.9f},{:.9f}", i ? "|" : "", d[0], d[1], d[2]);
  }
  return s;
}

// A smooth sRGB-space SH model (exactly an HSH in relight's basis), 64x48.
std::string WriteShModel(const std::string& dir, FitSpace space) {
  ModelInfo info = testing::DefaultGridInfo();
  info.method = FitMethod::kLs;
  info.transform.space = space;
  Model m(Basis(BasisKind::kSh, 2), info, 64, 48);
  const double b0 = m.basis().Eval(Vec3{0, 0, 1})[0];
  const double level = space == FitSpace::kLinear ? 1.5 : 0.45;
  for (int k = 0; k < m.basis().size(); ++k) {
    cv::Mat c(48, 64, CV_32FC3);
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x)
        for (int ch = 0; ch < 3; ++ch)
          c.at<cv::Vec3f>(y, x)[ch] = static_cast<float>(
              k == 0 ? level * (1 + 0.4 * std::sin(x / 6.0 + ch) * std::cos(y / 5.0)) / b0
                     : level * 0.12 * std::sin(x / (4.0 + k) + ch) * std::cos(y / 7.0));
    m.coefficients().push_back(c);
  }
  const std::string path = dir + (space == FitSpace::kLinear ? "/linear.exr" : "/srgb.exr");
  EXPECT_TRUE(SaveModel(path, m, ExrPixelType::kFloat).ok());
  return path;
}

class ViewTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (Chromium().empty()) GTEST_SKIP() << "chromium is not installed (apt-get install chromium): browser test skipped";
    dir_ = testing::FreshTempDir("view");
  }
  // The page against `rig render` of the page's own folder (and of `original`, when given).
  void ExpectMatches(const std::string& view, const std::vector<std::pair<double, double>>& angles,
                     double mean_bound, int max_bound, const std::string& original = "") {
    const PageRun run = RunPage(view, Shots(angles));
    ASSERT_TRUE(run.finished) << "the page did not report (requests: " << run.requests.size() << ")";
    EXPECT_EQ(run.done.value("message", ""), "");
    for (const auto& r : run.done["resources"]) {
      const std::string url = r.get<std::string>();
      EXPECT_EQ(url.rfind("http://127.0.0.1:", 0), 0u) << "a request off loopback: " << url;
    }
    for (size_t i = 0; i < angles.size(); ++i) {
      ASSERT_TRUE(run.shots.count(static_cast<int>(i))) << "shot " << i;
      const std::string out = fmt::format("{}/render_{}_{}.png", dir_, fs::path(view).filename().string(), renders_++);
      const cv::Mat ref = Render(original.empty() ? view : original, angles[i].first, angles[i].second, out);
      const Diff d = Compare(run.shots.at(static_cast<int>(i)), ref);
      RecordProperty(fmt::format("{}_light{}_mean_dn", fs::path(view).filename().string(), i), fmt::format("{:.4f}", d.mean));
      RecordProperty(fmt::format("{}_light{}_max_dn", fs::path(view).filename().string(), i), d.max);
      std::printf("  %s light %g,%g: mean |page - rig render| %.4f DN, max %d DN\n", view.c_str(),
                  angles[i].first, angles[i].second, d.mean, d.max);
      EXPECT_LE(d.mean, mean_bound) << "light " << angles[i].first << "," << angles[i].second;
      EXPECT_LE(d.max, max_bound) << "light " << angles[i].first << "," << angles[i].second;
    }
  }
  std::string dir_;
  int renders_ = 0;
};

// HSH coefficients of known smooth planes, 9 terms, 64x48.
RelightCoefficients SmoothHsh() {
  RelightCoefficients c;
  c.type = RelightType::kHsh;
  c.terms = 9;
  c.width = 64;
  c.height = 48;
  for (int j = 0; j < 9; ++j) {
    cv::Mat p(48, 64, CV_32FC3);
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x)
        for (int ch = 0; ch < 3; ++ch)
          p.at<cv::Vec3f>(y, x)[ch] = static_cast<float>(
              j == 0 ? 250 * (1 + 0.4 * std::sin(x / 6.0 + ch) * std::cos(y / 5.0))
                     : 30 * std::sin(x / (4.0 + j) + ch) * std::cos(y / 7.0));
    c.planes.push_back(p);
  }
  return c;
}

TEST_F(ViewTest, HshFromAnRtiFileMatchesRigRenderAtThreeLights) {
  const std::string rti = dir_ + "/model.rti";
  ASSERT_TRUE(WriteRti(rti, SmoothHsh()).ok());
  const std::string view = dir_ + "/hsh";
  const auto r = RunRig("view " + rti + " --out " + view);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("copied as it is"));
  for (const char* f : {"index.html", "viewer.js", "viewer.css", "data.js", "info.json", "plane_0.jpg", "plane_8.jpg"})
    EXPECT_TRUE(fs::exists(view + "/" + f)) << f;
  // The page reads the files rig render reads: within 1 DN on average, 3 at most.
  ExpectMatches(view, {{40, 15}, {10, 25}, {75, 5}}, 1.0, 3);
  // Against the .rti itself: plus what the web format's 8-bit JPEG planes lose.
  ExpectMatches(view, {{40, 15}}, 1.5, 12, rti);
}

TEST_F(ViewTest, PtmLrgbAndPcaBilinearMatchRigRender) {
  // PTM lrgb with known coefficients
  RelightCoefficients c;
  c.type = RelightType::kPtm;
  c.terms = 6;
  c.lrgb = true;
  c.width = 60;
  c.height = 40;
  c.albedo.create(40, 60, CV_32FC3);
  for (int j = 0; j < 6; ++j) c.planes.emplace_back(40, 60, CV_32FC1);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 60; ++x) {
      c.albedo.at<cv::Vec3f>(y, x) = cv::Vec3f(float(40 + 3 * x), float(200 - 4 * y), float(120 + (x * y) % 100));
      const float base[6] = {150, 60, 40, -50, 20, -40};
      for (int j = 0; j < 6; ++j) c.planes[j].at<float>(y, x) = base[j] * (1 + 0.3f * std::sin(0.2f * x + j) * std::cos(0.15f * y));
    }
  c.lights = {LightDirection(20, 10), LightDirection(60, 20), LightDirection(40, 30)};
  const std::string web = dir_ + "/lptm-web";
  ASSERT_TRUE(WriteRelightWeb(web, c, WebWriteOptions{}).ok());
  const std::string view = dir_ + "/lptm";
  auto r = RunRig("view " + web + " --out " + view);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("copied as it is"));
  ExpectMatches(view, {{30, 20}}, 1.0, 3);

  // PCA bilinear (mrgb), fitted to a synthetic capture
  LightSamples s;
  s.width = 48;
  s.height = 32;
  for (double v = 10; v <= 70; v += 20)
    for (double h = 0; h < 180; h += 30) s.directions.push_back(LightDirection(h, v));
  s.values.resize(s.pixels() * s.directions.size() * 3);
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      const Vec3 n = {0.3 * std::sin(x / 7.0), 0.3 * std::cos(y / 6.0), 1};
      const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + 1);
      for (size_t l = 0; l < s.directions.size(); ++l) {
        const Vec3& d = s.directions[l];
        const double shade = std::max(0.0, (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / nn);
        for (int ch = 0; ch < 3; ++ch) {
          const double albedo = 0.3 + 0.25 * (ch + 1) / 3.0 + 0.2 * std::sin(x / 5.0 + ch);
          s.values[((size_t(y) * s.width + x) * s.directions.size() + l) * 3 + ch] =
              static_cast<uint8_t>(std::lround(255 * SrgbEncode(static_cast<float>(albedo * shade))));
        }
      }
    }
  PcaOptions o;
  o.components = 6;
  o.grid_resolution = 8;
  auto pca = FitPca(s, o);
  ASSERT_TRUE(pca.ok()) << pca.error().ToString();
  const std::string pca_dir = dir_ + "/pca-model";
  ASSERT_TRUE(pca->Save(pca_dir).ok());
  const std::string pca_view = dir_ + "/pca";
  r = RunRig("view " + pca_dir + " --out " + pca_view);
  ASSERT_EQ(r.status, 0) << r.output;
  ExpectMatches(pca_view, {{45, 40}}, 1.0, 3);
  // Lit by default at the mean of the model's lights (not head-on), as docs/viewer.md says.
  std::string js = testing::ReadText(pca_view + "/data.js");
  js = js.substr(js.find('{'));
  js = js.substr(0, js.rfind('}') + 1);
  const auto data = nlohmann::json::parse(js);
  Vec3 mean{0, 0, 0};
  for (const Vec3& d : s.directions)
    for (int k = 0; k < 3; ++k) mean[k] += d[k];
  const double norm = std::sqrt(mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]);
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(data.at("default_light")[k].get<double>(), mean[k] / norm, 1e-3) << k;  // info.json rounds
  EXPECT_LT(data.at("default_light")[2].get<double>(), 0.95);  // far from head-on here
}

// relight's own PCA types (hand-made folders: rbf, its default; ybilinear and yrbf in mycc):
// copied as they are, and the page draws what `rig render` draws (which is relight's renderer
// within 1 DN: tests/process/relight_pca_types_test.cc).
TEST_F(ViewTest, RelightRbfAndMyccFoldersMatchRigRender) {
  uint32_t seed = 90;
  for (auto [rbf, ycc] : {std::pair{true, false}, std::pair{false, true}, std::pair{true, true}}) {
    const std::string type = std::string(ycc ? "y" : "") + (rbf ? "rbf" : "bilinear");
    const auto f = testing::MakeRelightPcaFolder(dir_ + "/" + type + "-model", rbf, ycc, seed++);
    const std::string view = dir_ + "/" + type;
    const auto r = RunRig("view " + f.dir + " --out " + view);
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_THAT(r.output, HasSubstr("copied as it is"));
    ExpectMatches(view, {{30, 20}, {70, 45}}, 1.0, 3);
  }
}

TEST_F(ViewTest, HdrModelUsesWardsCurveOfTheDefaultLight) {
  const std::string model = WriteShModel(dir_, FitSpace::kLinear);
  const Vec3 d = LightDirection(40, 15);
  const std::string view = dir_ + "/hdr";
  // The conversion reports its stages off a terminal as every long job does (here at every step).
  setenv("RIG_PROGRESS_EVERY_S", "0.000001", 1);
  const auto r = RunRig(fmt::format("view {} --light {:.9f},{:.9f},{:.9f} --out {}", model, d[0], d[1], d[2], view));
  setenv("RIG_PROGRESS_EVERY_S", "100000", 1);  // as tests/test_env.cc sets it
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("Ward"));
  EXPECT_THAT(r.output, HasSubstr("progress: refitting ")) << r.output;
  EXPECT_THAT(r.output, HasSubstr("progress: measuring the error ")) << r.output;
  // against rig render of the original (Ward, recomputed): the refit onto HSH in sRGB
  // values and the 8-bit planes are in the difference
  ExpectMatches(view, {{40, 15}}, 2.0, 40, model);
}

TEST_F(ViewTest, OpensFromFileUrlWithEmbeddedPlanes) {
  const std::string rti = dir_ + "/model.rti";
  ASSERT_TRUE(WriteRti(rti, SmoothHsh()).ok());
  const std::string view = dir_ + "/file";
  ASSERT_EQ(RunRig("view " + rti + " --out " + view).status, 0);
  const PageRun run = RunPage(view, Shots({{40, 15}}), /*file_url=*/true);
  ASSERT_TRUE(run.finished);
  EXPECT_EQ(run.done.value("message", ""), "");
  EXPECT_EQ(run.done.value("location", "").rfind("file://", 0), 0u);
  for (const auto& path : run.requests) EXPECT_EQ(path.rfind("/report/", 0), 0u) << path;  // nothing fetched
  const cv::Mat ref = Render(view, 40, 15, dir_ + "/file.png");
  ASSERT_TRUE(run.shots.count(0));
  const Diff diff = Compare(run.shots.at(0), ref);
  EXPECT_LE(diff.mean, 1.0);
  EXPECT_LE(diff.max, 3);
}

// A tiled model: the page loads only the tiles of the level its zoom needs, and the full-size
// level relights as the plane files do (the tiles are JPEG again: a second generation).
TEST_F(ViewTest, DeepZoomLoadsOnlyVisibleTilesAndMatches) {
  const int W = 1100, H = 700;
  RelightCoefficients c;
  c.type = RelightType::kPtm;
  c.terms = 6;
  c.width = W;
  c.height = H;
  for (int j = 0; j < 6; ++j) {
    cv::Mat p(H, W, CV_32FC3);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        for (int ch = 0; ch < 3; ++ch)
          p.at<cv::Vec3f>(y, x)[ch] = static_cast<float>((j == 0 ? 120 : 40.0 / j) *
                                                         (1 + 0.5 * std::sin(x / 40.0 + ch + j) * std::cos(y / 30.0)));
    c.planes.push_back(p);
  }
  const std::string web = dir_ + "/big-web";
  ASSERT_TRUE(WriteRelightWeb(web, c, WebWriteOptions{}).ok());
  const std::string view = dir_ + "/big";
  const auto r = RunRig("view " + web + " --tiles on --out " + view);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("deep zoom: 6 plane files x 12 levels"));
  ASSERT_TRUE(fs::exists(view + "/plane_5.dzi"));
  ASSERT_TRUE(fs::exists(view + "/plane_5_files/11/4_2.jpg"));
  ASSERT_TRUE(fs::exists(view + "/plane_5_files/0/0_0.jpg"));
  // The first view, the whole image in 400x320 (zoom 0.364): level 10 (550x350, 3x2 tiles of
  // the 5x3 at full size) and, for a whole picture sooner, level 9 (275x175, 2x1 tiles).
  const Vec3 d = LightDirection(30, 20);
  PageRun run = RunPage(view, fmt::format("ui=0&shots={},{},{}", d[0], d[1], d[2]));
  ASSERT_TRUE(run.finished);
  int tile_requests = 0;
  for (const auto& p : run.requests) {
    EXPECT_EQ(p.find("/plane_0.jpg"), std::string::npos) << "the full plane was fetched";
    if (p.find("_files/") != std::string::npos) {
      ++tile_requests;
      EXPECT_THAT(p, ::testing::AnyOf(HasSubstr("_files/10/"), HasSubstr("_files/9/")));
    }
  }
  EXPECT_EQ(tile_requests, 6 * (6 + 2));
  // Native size: every full-size tile, against rig render of the plane files.
  run = RunPage(view, Shots({{30, 20}}), false, W, H);
  ASSERT_TRUE(run.finished);
  ASSERT_TRUE(run.shots.count(0));
  const Diff diff = Compare(run.shots.at(0), Render(view, 30, 20, dir_ + "/big.png"));
  std::printf("  tiled %dx%d at native size: mean |page - rig render| %.4f DN, max %d DN\n", W, H, diff.mean, diff.max);
  EXPECT_LE(diff.mean, 1.0);
  EXPECT_LE(diff.max, 8);
}

// normals.png / albedo.png beside the model are copied and shown as they are.
TEST_F(ViewTest, NormalsBesideTheModelAreShown) {
  const std::string web = dir_ + "/with-normals";
  ASSERT_TRUE(WriteRelightWeb(web, SmoothHsh(), WebWriteOptions{}).ok());
  cv::Mat normals(48, 64, CV_8UC3);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) normals.at<cv::Vec3b>(y, x) = cv::Vec3b(255, uint8_t(4 * x), uint8_t(5 * y));  // B, G, R
  ASSERT_TRUE(cv::imwrite(web + "/normals.png", normals));
  const std::string view = dir_ + "/normals-view";
  ASSERT_EQ(RunRig("view " + web + " --out " + view).status, 0);
  ASSERT_TRUE(fs::exists(view + "/normals.png"));
  const PageRun run = RunPage(view, "fit=native&ui=0&view=normals&shots=0,0,1");
  ASSERT_TRUE(run.finished);
  ASSERT_TRUE(run.shots.count(0));
  cv::Mat rgb;
  cv::cvtColor(normals, rgb, cv::COLOR_BGR2RGB);
  const Diff d = Compare(run.shots.at(0), rgb);
  EXPECT_EQ(d.max, 0) << "mean " << d.mean;
}

// data.js of a page folder: `window.RIG_VIEW = {...};` after a comment line, edited.
void EditPageData(const std::string& view, const std::function<void(nlohmann::json&)>& edit) {
  const std::string path = view + "/data.js", text = testing::ReadText(path);
  const size_t at = text.find("window.RIG_VIEW = ");
  ASSERT_NE(at, std::string::npos) << path;
  const size_t begin = at + std::string("window.RIG_VIEW = ").size(), end = text.rfind(';');
  ASSERT_GT(end, begin) << path;
  nlohmann::json d = nlohmann::json::parse(text.substr(begin, end - begin));
  edit(d);
  std::ofstream(path, std::ios::binary) << text.substr(0, begin) << d.dump() << ";\n";
}

// The first view rejects, naming what failed, when the page cannot show the model: a plane
// the server does not have, a plane that is not an image, a type the page does not draw. (It
// used to resolve over a picture with a plane missing, or never be defined.)
TEST_F(ViewTest, FirstViewRejectsNamingWhatFailed) {
  const std::string model = WriteShModel(dir_, FitSpace::kSrgb);
  struct Case {
    std::string name, expect;
    std::function<void(const std::string&, nlohmann::json&)> edit;
  };
  const std::vector<Case> cases = {
      {"missing", "plane_1.jpg: HTTP 404",
       [](const std::string& view, nlohmann::json& d) {
         d["embedded"].erase("plane_1.jpg");
         fs::remove(view + "/plane_1.jpg");
       }},
      {"corrupt", "plane_0.jpg: not an image the browser decodes",
       [](const std::string&, nlohmann::json& d) { d["embedded"]["plane_0.jpg"] = "bm90IGEgSlBFRw=="; }},
      {"type", "Type \"dmd\" is not shown here",
       [](const std::string&, nlohmann::json& d) { d["info"]["type"] = "dmd"; }},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string view = dir_ + "/page-" + c.name;
    const auto r = RunRig("view " + model + " --out " + view);
    ASSERT_EQ(r.status, 0) << r.output;
    EditPageData(view, [&](nlohmann::json& d) { c.edit(view, d); });
    const PageRun run = RunPage(view, "fit=native&ui=0&shots=0,0,1", false, 400, 320, 30);
    ASSERT_TRUE(run.finished) << "the page did not report (requests: " << run.requests.size() << ")";
    EXPECT_THAT(run.done.value("failed", ""), HasSubstr(c.expect));
    EXPECT_THAT(run.done.value("message", ""), HasSubstr(c.expect));  // shown in the panel too
    EXPECT_TRUE(run.shots.empty());
  }
  // The page unedited reports its views (the hook's success path in the same set-up).
  const std::string view = dir_ + "/page-good";
  ASSERT_EQ(RunRig("view " + model + " --out " + view).status, 0);
  const PageRun run = RunPage(view, "fit=native&ui=0&shots=0,0,1");
  ASSERT_TRUE(run.finished);
  EXPECT_EQ(run.done.value("failed", ""), "");
  EXPECT_GT(run.done.value("first_view_ms", -1.0), 0);
  EXPECT_EQ(run.shots.size(), 1u);
}

TEST_F(ViewTest, RefusesAnExistingFolderAndABadLight) {
  const std::string model = WriteShModel(dir_, FitSpace::kSrgb);
  fs::create_directories(dir_ + "/there");
  auto r = RunRig("view " + model + " --out " + dir_ + "/there");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("exists"));
  r = RunRig("view " + model + " --light 1,x,2 --out " + dir_ + "/bad");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.output, HasSubstr("--light"));
}

}  // namespace
}  // namespace rig

namespace rig {
namespace {

// A 24 MP PTM (6000x4000, 6 plane files) written as JPEG planes directly; rig view tiles it
// and the page's first view is timed. Slow (about a minute on 2 cores): run with
// RIG_VIEW_24MP=1 (scripts/view-24mp.sh); skipped otherwise.
TEST_F(ViewTest, Bench24MpFirstView) {
  if (!std::getenv("RIG_VIEW_24MP")) GTEST_SKIP() << "set RIG_VIEW_24MP=1 to time a 24 MP model";
  const int W = 6000, H = 4000;
  const std::string src = dir_ + "/24mp-web";
  fs::create_directories(src);
  for (int j = 0; j < 6; ++j) {
    cv::Mat rgb(H, W, CV_8UC3);
    for (int y = 0; y < H; ++y) {
      uint8_t* p = rgb.ptr<uint8_t>(y);
      for (int x = 0; x < W; ++x)
        for (int ch = 0; ch < 3; ++ch)
          p[3 * x + ch] = static_cast<uint8_t>(128 + 100 * std::sin(x / (90.0 + 13 * j) + ch) * std::cos(y / 70.0));
    }
    ASSERT_TRUE(WriteJpeg(fmt::format("{}/plane_{}.jpg", src, j), rgb, JpegColor::kYcbcr, 95).ok());
  }
  nlohmann::ordered_json info = {{"width", W}, {"height", H}, {"format", "jpg"}, {"type", "ptm"},
                                 {"colorspace", "rgb"}, {"nplanes", 18}, {"quality", 95}};
  std::vector<double> scale(18), bias(18);
  for (int p = 0; p < 18; ++p) {
    scale[p] = p < 3 ? 1.0 : 0.5;
    bias[p] = p < 3 ? 0.0 : 0.5;
  }
  info["materials"] = nlohmann::ordered_json::array({{{"scale", scale}, {"bias", bias}}});
  std::ofstream(src + "/info.json") << info.dump();
  const std::string view = dir_ + "/24mp";
  const auto start = std::chrono::steady_clock::now();
  const auto r = RunRig("view " + src + " --out " + view);
  const double view_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_EQ(r.status, 0) << r.output;
  std::printf("%s  rig view of a 24 MP ptm (6 plane files): %.2f s in all\n", r.output.c_str(), view_s);
  const Vec3 d = LightDirection(30, 20);
  const PageRun run = RunPage(view, fmt::format("ui=0&shots={},{},{}", d[0], d[1], d[2]), false, 1280, 800);
  ASSERT_TRUE(run.finished);
  int tiles = 0;
  for (const auto& p : run.requests) tiles += p.find("_files/") != std::string::npos;
  const double first_ms = run.done.value("first_view_ms", -1.0);
  const double full_ms = run.done.value("full_view_ms", -1.0);
  std::printf("  first view in headless Chromium (SwiftShader, 1280x800): %.0f ms after navigation "
              "start; every tile of its level: %.0f ms (%d tile requests); browser launch to "
              "report: %.2f s\n",
              first_ms, full_ms, tiles, run.wall_s);
  RecordProperty("full_view_ms", fmt::format("{:.0f}", full_ms));
  RecordProperty("first_view_ms", fmt::format("{:.0f}", first_ms));
  EXPECT_LT(first_ms, 2000);
}

}  // namespace
}  // namespace rig
