// A page of another origin (a second server on another port) in headless Chromium
// (../shared/docs/browser-testing.md) tries what any web site could against a daemon on
// loopback: a job posted as text/plain with no-cors, a stop with no body, a JSON job (which
// needs a preflight), and a text/plain form posted into a hidden frame. The daemon refuses
// each (its refusal count grows), starts no job and writes no session; the page's script ran
// to its end (its DOM says so).
#include <fstream>
#include <regex>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "capture/devices/signals.h"
#include "capture/service/http_server.h"
#include "capture/service/service.h"
#include "rig/commands/daemon_client.h"
#include "tests/support/run_rig.h"
#include "tests/support/browser.h"
#include "tests/support/test_daemon.h"

namespace rig {
namespace {

using testing::Chromium;

// The attacker's page: every request a site can make without the daemon's consent.
std::string AttackPage(const std::string& daemon, const std::string& session) {
  const std::string job = nlohmann::json{{"kind", "capture"}, {"session", session}, {"dry_run", true},
                                         {"config_toml", "[sim]\n"}}.dump();
  return R"(<!doctype html><html><body data-done="no"><iframe name="sink"></iframe>
<form id="f" method="post" enctype="text/plain" target="sink" action=")" + daemon + R"(/api/jobs">
<input name='{"kind":"capture","session":")" + session + R"(","dry_run":true,"x":"' value='"}'></form>
<script>
const D = ")" + daemon + R"(", job = )" + nlohmann::json(job).dump() + R"(;
const results = [];
async function attempt(name, f) {
  try { const r = await f(); results.push(name + ":" + (r.type === "opaque" ? "opaque" : r.status)); }
  catch (e) { results.push(name + ":blocked"); }
}
(async () => {
  await attempt("text", () => fetch(D + "/api/jobs", {method: "POST", mode: "no-cors",
      headers: {"Content-Type": "text/plain"}, body: job}));
  await attempt("stop", () => fetch(D + "/api/stop", {method: "POST", mode: "no-cors"}));
  await attempt("resume", () => fetch(D + "/api/resume", {method: "POST", mode: "no-cors",
      headers: {"Content-Type": "application/x-www-form-urlencoded"}, body: "a=b"}));
  await attempt("json", () => fetch(D + "/api/jobs", {method: "POST",
      headers: {"Content-Type": "application/json"}, body: job}));
  document.getElementById("f").submit();
  await new Promise(r => setTimeout(r, 500));
  document.body.dataset.results = results.join(" ");
  document.body.dataset.done = "yes";
})();
</script></body></html>)";
}

TEST(DaemonCrossOrigin, APageOfAnotherOriginInChromiumStartsNoJobAndStopsNothing) {
  const std::string chromium = Chromium();
  if (chromium.empty()) GTEST_SKIP() << "chromium is not installed (scripts/setup.sh installs it)";
  ClearStopForTesting();
  const std::string dir = testing::FreshTempDir("daemon_cross_origin");
  testing::RunningDaemon running(dir);
  CaptureService& service = running.service;
  const HttpServer& http = running.http;
  const std::string daemon = "http://127.0.0.1:" + std::to_string(http.port());
  const std::string session = dir + "/Attacked";

  httplib::Server attacker;
  const std::string page = AttackPage(daemon, session);
  attacker.Get("/", [&](const httplib::Request&, httplib::Response& res) {
    res.set_content(page, "text/html");
  });
  const int attacker_port = attacker.bind_to_any_port("127.0.0.1");
  ASSERT_GT(attacker_port, 0);
  ASSERT_NE(attacker_port, http.port());
  std::thread serving([&] { attacker.listen_after_bind(); });

  const std::string dom_path = dir + "/dom.html";
  const std::string cmd = chromium +
                          " --headless=new --no-sandbox --disable-gpu --no-first-run "
                          "--user-data-dir=" + dir + "/profile --virtual-time-budget=5000 "
                          "--dump-dom http://127.0.0.1:" + std::to_string(attacker_port) + "/ > " +
                          dom_path + " 2> " + dir + "/chromium.log";
  const int rc = std::system(cmd.c_str());
  attacker.stop();
  serving.join();
  const std::vector<JobInfo> jobs = service.Jobs();
  const size_t refused = http.refused();
  running.Stop();
  ASSERT_EQ(rc, 0) << cmd;
  const std::string dom = testing::ReadText(dom_path);

  // The page's script ran to its end: every attempt made (the no-cors ones "succeed" as
  // opaque answers, the JSON one is blocked at its preflight).
  EXPECT_NE(dom.find("data-done=\"yes\""), std::string::npos) << dom.substr(0, 3000);
  EXPECT_NE(dom.find("text:opaque stop:opaque resume:opaque json:blocked"), std::string::npos)
      << dom.substr(0, 3000);
  // The daemon saw and refused the text/plain job, the stop, the resume and the form.
  EXPECT_GE(refused, 4u);
  EXPECT_TRUE(jobs.empty()) << jobs.front().ToJson().dump();
  EXPECT_FALSE(fs::exists(session));
}

}  // namespace
}  // namespace rig
