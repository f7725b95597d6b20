// The daemon's status page in headless Chromium (../shared/docs/browser-testing.md): after the
// page's script ran, its DOM shows the state, the pose and the stored poses of /api/status.
#include <cstdio>
#include <fstream>
#include <regex>

#include <gtest/gtest.h>

#include "capture/devices/signals.h"
#include "capture/service/client.h"
#include "capture/service/http_server.h"
#include "capture/service/service.h"
#include "rig/commands/daemon_client.h"
#include "tests/support/run_rig.h"
#include "tests/support/browser.h"
#include "tests/support/test_daemon.h"

namespace rig {
namespace {

using testing::Chromium;

int CountOf(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

TEST(DaemonPage, HeadlessChromiumShowsTheStatePoseAndStoredPosesOfTheApi) {
  const std::string chromium = Chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup.sh installs it)";
  ClearStopForTesting();
  const std::string dir = testing::FreshTempDir("daemon_page");
  // 4 x 2 poses; the stop comes after the third pose.
  const std::string cfg = testing::WriteSimConfig(dir, R"([sim]
width = 160
height = 120
latency_scale = 0.05
[bracket]
count = 3
[grid]
h_max_deg = 30
v_max_deg = 10
)");
  testing::RunningDaemon daemon(dir);
  const HttpServer& http = daemon.http;
  DaemonAddress a;
  a.port = http.port();
  DaemonClient client(a);
  const std::string session = dir + "/S";
  auto job = client.Post("/api/jobs", {{"kind", "capture"}, {"session", session}, {"config", cfg},
                                       {"dry_run", true}, {"process", false}});
  ASSERT_TRUE(job.ok()) << job.error().ToString();
  nlohmann::json s;
  for (int i = 0; i < 1500; ++i) {
    auto r = client.Get("/api/status");
    ASSERT_TRUE(r.ok());
    s = *r;
    if (s["frames"].is_object() && s["frames"]["stored"].get<int>() >= 9) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(client.Post("/api/stop", nlohmann::json::object()).ok());
  for (int i = 0; i < 500; ++i) {
    s = *client.Get("/api/status");
    if (s["state"] == "idle") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(s["state"], "idle");
  ASSERT_TRUE(s["pose"].is_object());
  const std::string pose = s["pose"]["name"].get<std::string>();
  const int done = static_cast<int>(s["poses_done"].get<size_t>());
  ASSERT_GE(done, 3);
  ASSERT_LT(done, 8);

  const std::string dom_path = dir + "/dom.html";
  const std::string cmd = chromium +
                          " --headless=new --no-sandbox --disable-gpu --use-angle=swiftshader "
                          "--enable-unsafe-swiftshader --window-size=900,700 "
                          "--virtual-time-budget=4000 --dump-dom http://127.0.0.1:" +
                          std::to_string(http.port()) + "/ > " + dom_path + " 2> " + dir +
                          "/chromium.log";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(dom_path);
  const std::string dom((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  daemon.Stop();

  // What the script wrote from /api/status: the state, the pose, the frames, the grid.
  EXPECT_NE(dom.find("data-state=\"idle\""), std::string::npos) << dom.substr(0, 2000);
  EXPECT_NE(dom.find("<span id=\"state\" class=\"idle\">idle (queue held)</span>"), std::string::npos);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(dom, m, std::regex("<dd id=\"pose\">([^<]*)</dd>")));
  EXPECT_EQ(m[1].str(), pose + " (" + std::to_string(done + 1) + " of 8)");
  ASSERT_TRUE(std::regex_search(dom, m, std::regex("<dd id=\"frames\">([^<]*)</dd>")));
  EXPECT_EQ(m[1].str().rfind(std::to_string(s["frames"]["stored"].get<int>()) + " of 24 stored", 0), 0u)
      << m[1].str();
  EXPECT_EQ(CountOf(dom, "class=\"done\""), done);
  EXPECT_EQ(CountOf(dom, "class=\"next\""), 1);
  EXPECT_EQ(CountOf(dom, "class=\"todo\""), 8 - done - 1);
  EXPECT_NE(dom.find("data-pose=\"" + pose + "\""), std::string::npos);
  // The last frame was fetched and shown (an object URL in the image).
  EXPECT_TRUE(std::regex_search(dom, std::regex("<img id=\"frame\"[^>]*src=\"blob:")));
}


// An adaptive grid ([grid] mode = "adaptive") stopped mid-session: the page numbers the poses
// chosen in their order, draws the allowed ones not chosen apart, and says how many of how
// many were chosen and the predicted error; `rig status` draws the same grid as text.
TEST(DaemonPage, AnAdaptiveGridShowsTheChosenPosesInOrderAndThePredictedError) {
  const std::string chromium = Chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup.sh installs it)";
  ClearStopForTesting();
  const std::string dir = testing::FreshTempDir("daemon_page_adaptive");
  // 40 poses allowed, at most 14 taken; the stop comes after 10 poses (8 seeds + 2 chosen).
  const std::string cfg = testing::WriteSimConfig(dir, R"([sim]
width = 96
height = 72
latency_scale = 0.05
[bracket]
count = 3
[grid]
mode = "adaptive"
max_poses = 14
)");
  testing::RunningDaemon daemon(dir);
  const HttpServer& http = daemon.http;
  DaemonAddress a;
  a.port = http.port();
  DaemonClient client(a);
  auto job = client.Post("/api/jobs", {{"kind", "capture"}, {"session", dir + "/S"}, {"config", cfg},
                                       {"dry_run", true}, {"process", false}});
  ASSERT_TRUE(job.ok()) << job.error().ToString();
  nlohmann::json s;
  for (int i = 0; i < 3000; ++i) {
    s = *client.Get("/api/status");
    if (s["poses_done"].is_number() && s["poses_done"].get<int>() >= 10) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_TRUE(client.Post("/api/stop", nlohmann::json::object()).ok());
  for (int i = 0; i < 500; ++i) {
    s = *client.Get("/api/status");
    if (s["state"] == "idle") break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_EQ(s["state"], "idle");
  ASSERT_TRUE(s["choice"].is_object()) << s.dump();
  const int chosen = s["choice"]["chosen"].get<int>();
  ASSERT_GE(chosen, 10);
  ASSERT_LT(chosen, 14);
  EXPECT_EQ(s["choice"]["max_poses"], 14);
  EXPECT_EQ(s["choice"]["allowed"], 40);
  ASSERT_TRUE(s["choice"]["predicted_rms"].is_number()) << s["choice"].dump();
  EXPECT_GE(s["choice"]["predicted_rms"].get<double>(), s["choice"]["floor_rms"].get<double>());
  EXPECT_TRUE(s["choice"]["stopped"].is_null());
  // The pose count is the most the grid takes, not the poses allowed.
  if (s["pose"].is_object()) {
    EXPECT_EQ(s["pose"]["total"], 14);
  }
  EXPECT_EQ(s["frames"]["total"], 14 * 3);
  int numbered = 0, allowed = 0;
  for (const auto& p : s["grid"]) {
    numbered += p.contains("choice");
    allowed += p["state"] == "allowed";
  }
  EXPECT_EQ(numbered, chosen);
  EXPECT_EQ(allowed, 40 - chosen);

  const std::string dom_path = dir + "/dom.html";
  const std::string cmd = chromium +
                          " --headless=new --no-sandbox --disable-gpu --use-angle=swiftshader "
                          "--enable-unsafe-swiftshader --window-size=900,700 "
                          "--virtual-time-budget=4000 --dump-dom http://127.0.0.1:" +
                          std::to_string(http.port()) + "/ > " + dom_path + " 2> " + dir +
                          "/chromium.log";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  std::ifstream in(dom_path);
  const std::string dom((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  auto text = testing::RunRig("status --daemon http://127.0.0.1:" + std::to_string(http.port()));
  daemon.Stop();

  EXPECT_EQ(CountOf(dom, "class=\"choice\""), chosen) << dom.substr(0, 3000);
  EXPECT_EQ(CountOf(dom, "class=\"allowed\""), 40 - chosen);
  // The first pose chosen is numbered 1, the last chosen `chosen`.
  EXPECT_NE(dom.find(">1</text>"), std::string::npos);
  EXPECT_NE(dom.find(">" + std::to_string(chosen) + "</text>"), std::string::npos);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(dom, m, std::regex("<dd id=\"choice\">([^<]*)</dd>"))) << dom.substr(0, 3000);
  EXPECT_EQ(m[1].str().rfind(std::to_string(chosen) + " of at most 14 poses chosen (40 allowed); predicted error ", 0), 0u)
      << m[1].str();

  ASSERT_EQ(text.status, 0) << text.output;
  EXPECT_NE(text.output.find("adaptive grid: " + std::to_string(chosen) + " of at most 14 poses chosen (40 allowed); predicted error"),
            std::string::npos) << text.output;
  // The text grid: 4 rows of 10 marks, the chosen and stored ones '#', the rest 'o'.
  EXPECT_EQ(CountOf(text.output, "  #"), static_cast<int>(s["poses_done"].get<int>())) << text.output;
  EXPECT_EQ(CountOf(text.output, "  o"), 40 - chosen) << text.output;
  EXPECT_NE(text.output.find("   30°"), std::string::npos) << text.output;
}

}  // namespace
}  // namespace rig
