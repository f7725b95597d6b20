// The capture service over real HTTP on loopback (an ephemeral port), against the simulated
// rig through rig's own device factory: start a session, poll the status, stop it mid-way,
// resume it; the result stores what an uninterrupted session stores. The security defaults.
#include <chrono>
#include <map>
#include <set>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "capture/devices/signals.h"
#include "capture/service/client.h"
#include "capture/service/http_server.h"
#include "capture/service/service.h"
#include "capture/session/session_store.h"
#include "rig/commands/daemon_client.h"
#include "tests/support/run_rig.h"
#include "tests/support/session_model.h"

namespace rig {
namespace {

using ::testing::HasSubstr;

// 40 poses x 3 exposures at 160x120, device latencies at 2% of real: a couple of seconds.
const char* kSmall = R"([sim]
width = 160
height = 120
latency_scale = 0.02
[bracket]
center_s = 0.02
ev_step = 1.5
count = 3
)";

ServiceOptions Under(const std::string& root) {
  ServiceOptions o;
  o.sessions_root = root;
  return o;
}

struct Daemon {
  CaptureService service;
  std::unique_ptr<HttpServer> http;
  std::unique_ptr<DaemonClient> client;
  // Sessions (and configuration files) under `root`.
  explicit Daemon(const std::string& root, const std::string& token = "")
      : service(DaemonHooks(), Under(root)) {
    HttpOptions o;
    o.host = "127.0.0.1";
    o.port = 0;
    o.token = token;
    http = std::make_unique<HttpServer>(service, o);
    Status st = http->Start();
    EXPECT_TRUE(st.ok()) << (st.ok() ? "" : st.error().ToString());
    service.Start();
    DaemonAddress a;
    a.port = http->port();
    a.token = token;
    client = std::make_unique<DaemonClient>(a);
  }
  ~Daemon() {
    service.Shutdown();
    http->Stop();
    ClearStopForTesting();
  }
  nlohmann::json Get() {
    auto s = client->Get("/api/status");
    EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().ToString());
    return s.ok() ? *s : nlohmann::json::object();
  }
  // Polls the status until `done` holds (at most `limit_s`); returns the last status.
  template <typename F>
  nlohmann::json WaitFor(F done, double limit_s = 60) {
    auto t0 = std::chrono::steady_clock::now();
    for (;;) {
      nlohmann::json s = Get();
      if (done(s)) return s;
      if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit_s) {
        ADD_FAILURE() << "timed out; last status " << s.dump();
        return s;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  nlohmann::json WaitJob(int id, double limit_s = 60) {
    auto t0 = std::chrono::steady_clock::now();
    for (;;) {
      auto j = client->Get("/api/jobs/" + std::to_string(id));
      EXPECT_TRUE(j.ok());
      if (!j.ok()) return {};
      if ((*j)["state"] != "queued" && (*j)["state"] != "running") return *j;
      if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limit_s) {
        ADD_FAILURE() << "job " << id << " still " << j->dump();
        return *j;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
};

std::vector<nlohmann::json> Records(const fs::path& session) {
  auto c = Journal::Read(session / "journal.jsonl");
  EXPECT_TRUE(c.ok());
  return c.ok() ? c->records : std::vector<nlohmann::json>{};
}

// (pose, index) -> (file, exposure) of the latest frame records; every file checked against
// its size and CRC; no stray file under frames/.
std::map<std::pair<std::string, int>, std::pair<std::string, double>> StoredFrames(
    const fs::path& session) {
  std::map<std::pair<std::string, int>, std::pair<std::string, double>> out;
  std::map<std::pair<std::string, int>, nlohmann::json> latest;
  for (const auto& r : Records(session))
    if (r["event"] == "frame") latest[{r["pose"].get<std::string>(), r["index"].get<int>()}] = r;
  for (const auto& [key, r] : latest) {
    auto bytes = ReadFileBytes(session / r["file"].get<std::string>());
    EXPECT_TRUE(bytes.ok()) << r.dump();
    if (!bytes.ok()) continue;
    EXPECT_EQ(bytes->size(), r["bytes"].get<size_t>());
    EXPECT_EQ(Crc32(*bytes), r["crc32"].get<uint32_t>());
    out[key] = {r["file"].get<std::string>(), r["exposure_s"].get<double>()};
  }
  size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(session / "frames")) {
    if (!e.is_regular_file()) continue;
    if (e.path().parent_path().filename().string()[0] == '.') continue;  // moved aside
    ++files;
  }
  EXPECT_EQ(files, out.size());
  return out;
}

int CountEvents(const fs::path& session, const std::string& event) {
  int n = 0;
  for (const auto& r : Records(session)) n += r["event"] == event ? 1 : 0;
  return n;
}

TEST(DaemonService, StopMidSessionThenResumeStoresWhatAnUninterruptedSessionStores) {
  ClearStopForTesting();
  const std::string dir = testing::FreshTempDir("daemon_service");
  const std::string cfg = testing::WriteSimConfig(dir, kSmall);
  const fs::path a = fs::path(dir) / "A", b = fs::path(dir) / "B";
  Daemon d(dir);
  EXPECT_EQ(d.Get()["state"], "idle");

  auto job = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", a.string()},
                                          {"config", cfg}, {"dry_run", true}, {"process", false}});
  ASSERT_TRUE(job.ok()) << job.error().ToString();
  const int id = (*job)["id"].get<int>();
  // A second job on the same session is refused while the first is queued or running.
  auto twice = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", a.string()}, {"config", cfg}});
  ASSERT_FALSE(twice.ok());
  EXPECT_EQ(twice.error().code, ErrorCode::kBusy);

  nlohmann::json s = d.WaitFor([](const nlohmann::json& s) {
    return s["state"] == "capturing" && s["frames"].is_object() && s["frames"]["stored"].get<int>() >= 15;
  });
  EXPECT_EQ(s["session"], a.string());
  EXPECT_EQ(s["frames"]["total"], 120);
  EXPECT_EQ(s["pose"]["total"], 40);
  EXPECT_GE(s["pose"]["index"].get<int>(), 4);  // 15 frames of 3: at least 5 poses stored
  EXPECT_TRUE(s["eta_s"].is_number());
  EXPECT_EQ(s["grid"].size(), 40u);
  // Running, with its session.toml written: still busy (not "already holds a session").
  auto again = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", a.string()}, {"config", cfg}});
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.error().code, ErrorCode::kBusy) << again.error().ToString();

  auto stop = d.client->Post("/api/stop", nlohmann::json::object());
  ASSERT_TRUE(stop.ok());
  EXPECT_EQ((*stop)["stopping"], true);
  s = d.WaitFor([](const nlohmann::json& s) { return s["state"] == "idle"; });
  EXPECT_TRUE(s["held"].get<bool>());
  EXPECT_EQ(s["last_job"]["id"], id);
  EXPECT_EQ(s["last_job"]["state"], "stopped");
  EXPECT_EQ(s["last_job"]["exit_code"], 128 + 15);
  const int stored_at_stop = s["frames"]["stored"].get<int>();
  EXPECT_LT(stored_at_stop, 120);
  EXPECT_GE(stored_at_stop, 15);
  // Parked as Ctrl-C parks: the journal ends on "interrupted", every frame it names intact.
  auto records = Records(a);
  ASSERT_FALSE(records.empty());
  EXPECT_EQ(records.back()["event"], "interrupted");
  EXPECT_EQ(static_cast<int>(StoredFrames(a).size()), stored_at_stop);
  // The journal as events, from any record on.
  auto journal = d.client->Get("/api/journal?since=2");
  ASSERT_TRUE(journal.ok());
  EXPECT_EQ((*journal)["records"].size() + 2, records.size());
  EXPECT_EQ((*journal)["next"], records.size());
  EXPECT_EQ((*journal)["records"].back()["event"], "interrupted");

  // A job queued while the queue is held waits for the resume.
  auto queued = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", b.string()},
                                             {"config", cfg}, {"dry_run", true}, {"process", false}});
  ASSERT_TRUE(queued.ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(d.Get()["queue"].size(), 1u);
  EXPECT_FALSE(fs::exists(b));

  auto resumed = d.client->Post("/api/resume", {{"process", false}});
  ASSERT_TRUE(resumed.ok()) << resumed.error().ToString();
  ASSERT_TRUE((*resumed)["job"].is_object());
  EXPECT_EQ((*resumed)["job"]["kind"], "resume");
  EXPECT_EQ((*resumed)["job"]["session"], a.string());
  nlohmann::json r = d.WaitJob((*resumed)["job"]["id"].get<int>());
  EXPECT_EQ(r["state"], "done") << r.dump();
  EXPECT_EQ(r["exit_code"], 0);
  nlohmann::json q = d.WaitJob((*queued)["id"].get<int>());
  EXPECT_EQ(q["state"], "done") << q.dump();

  // The stopped-and-resumed session stores what the uninterrupted one does: the same frames
  // (pose, bracket index, exposure, file name), each once, each intact.
  auto fa = StoredFrames(a), fb = StoredFrames(b);
  EXPECT_EQ(fa.size(), 120u);
  EXPECT_EQ(fa, fb);
  EXPECT_EQ(CountEvents(a, "interrupted"), 1);
  EXPECT_EQ(CountEvents(b, "interrupted"), 0);
  EXPECT_EQ(CountEvents(a, "capture_done"), 1);
  EXPECT_EQ(CountEvents(a, "frame"), 120);  // nothing captured twice, nothing lost
  s = d.Get();
  EXPECT_EQ(s["state"], "idle");
  EXPECT_EQ(s["frames"]["stored"], 120);
  EXPECT_TRUE(s["pose"].is_null());
}

TEST(DaemonService, ProcessJobMergesAndFitsAndPreviewsServeJpeg) {
  ClearStopForTesting();
  const std::string dir = testing::FreshTempDir("daemon_process");
  const std::string cfg = testing::WriteSimConfig(
      dir, std::string(kSmall) + "[grid]\nh_max_deg = 30\nv_max_deg = 10\n");
  const fs::path a = fs::path(dir) / "A";
  Daemon d(dir);
  auto none = d.client->Get("/api/preview/frame.jpg");
  EXPECT_FALSE(none.ok());  // no session yet: 404
  auto cap = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", a.string()}, {"config", cfg},
                                          {"dry_run", true}, {"process", false}});
  ASSERT_TRUE(cap.ok());
  EXPECT_EQ(d.WaitJob((*cap)["id"].get<int>())["state"], "done");
  EXPECT_FALSE(testing::SessionHasModel(a));
  auto proc = d.client->Post("/api/jobs", {{"kind", "process"}, {"session", a.string()}});
  ASSERT_TRUE(proc.ok());
  nlohmann::json p = d.WaitJob((*proc)["id"].get<int>());
  EXPECT_EQ(p["state"], "done") << p.dump();
  EXPECT_TRUE(testing::SessionHasModel(a));
  nlohmann::json s = d.Get();
  EXPECT_EQ(s["model"]["radiance_maps"], 8);
  EXPECT_EQ(s["model"]["phase"], "fitted");

  httplib::Client c("127.0.0.1", d.http->port());
  for (const char* path : {"/api/preview/frame.jpg", "/api/preview/radiance.jpg"}) {
    auto res = c.Get(path);
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 200) << path;
    EXPECT_EQ(res->get_header_value("Content-Type"), "image/jpeg");
    ASSERT_GT(res->body.size(), 100u);
    EXPECT_EQ(static_cast<unsigned char>(res->body[0]), 0xFF);  // JPEG SOI
    EXPECT_EQ(static_cast<unsigned char>(res->body[1]), 0xD8);
  }
  // The journal as Server-Sent Events: every record from `since` on, numbered, then status.
  std::string events;
  auto sse = c.Get("/api/events?since=1", [&](const char* data, size_t n) {
    events.append(data, n);
    // Stop reading once the status event came whole (it may arrive in several chunks).
    const size_t at = events.find("event: status");
    return at == std::string::npos || events.find("\n\n", at) == std::string::npos;
  });
  const size_t records = Records(a).size();
  EXPECT_NE(events.find("id: 1\nevent: journal\ndata: {"), std::string::npos) << events.substr(0, 300);
  EXPECT_NE(events.find("id: " + std::to_string(records - 1) + "\nevent: journal"), std::string::npos);
  EXPECT_EQ(events.find("id: 0\n"), std::string::npos);
  EXPECT_NE(events.find("event: status\ndata: {\"eta_s\""), std::string::npos) << events.substr(events.size() - 300);
  // Bad requests name what is wrong.
  auto bad = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", "../elsewhere/S"}, {"config", cfg}});
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(bad.error().message, HasSubstr("is not under the daemon's sessions root"));
  auto again = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", a.string()}, {"config", cfg}});
  ASSERT_FALSE(again.ok());
  EXPECT_THAT(again.error().message, HasSubstr("already holds a session"));
  auto badcfg = d.client->Post("/api/jobs", {{"kind", "capture"}, {"session", (fs::path(dir) / "C").string()},
                                             {"config", "x.toml"}, {"config_toml", "[camera]\nbackend = 3\n"}});
  ASSERT_FALSE(badcfg.ok());
  EXPECT_THAT(badcfg.error().message, HasSubstr("x.toml:2"));
}

TEST(DaemonService, TokenIsRequiredOnEveryApiRequestWhenSet) {
  ClearStopForTesting();
  Daemon d(testing::FreshTempDir("daemon_token"), "s3cret-token");
  httplib::Client c("127.0.0.1", d.http->port());
  auto no = c.Get("/api/status");
  ASSERT_TRUE(no);
  EXPECT_EQ(no->status, 401);
  EXPECT_EQ(no->get_header_value("WWW-Authenticate"), "Bearer realm=\"rig\"");
  httplib::Headers wrong = {{"Authorization", "Bearer s3cret-tokeN"}};
  EXPECT_EQ(c.Get("/api/status", wrong)->status, 401);
  EXPECT_EQ(c.Post("/api/stop", wrong, "", "application/json")->status, 401);
  httplib::Headers right = {{"Authorization", "Bearer s3cret-token"}};
  auto yes = c.Get("/api/status", right);
  ASSERT_TRUE(yes);
  EXPECT_EQ(yes->status, 200);
  EXPECT_THAT(yes->body, HasSubstr("\"state\":\"idle\""));
  // The page holds no data (it sends the token from the address's #fragment itself).
  EXPECT_EQ(c.Get("/")->status, 200);
  EXPECT_TRUE(d.Get().contains("state"));  // the client sends the bearer token
}

TEST(DaemonService, AnAddressBeyondLoopbackNeedsAllowRemoteAndAToken) {
  HttpOptions o;
  o.host = "0.0.0.0";
  Status st = CheckListenOptions(o);
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().message, HasSubstr("--allow-remote"));
  o.allow_remote = true;
  st = CheckListenOptions(o);
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().message, HasSubstr("token"));
  o.token = "t";
  EXPECT_TRUE(CheckListenOptions(o).ok());
  for (const char* h : {"127.0.0.1", "127.1.2.3", "::1", "localhost"}) EXPECT_TRUE(IsLoopbackHost(h)) << h;
  for (const char* h : {"0.0.0.0", "192.168.1.5", "::", "example.org"}) EXPECT_FALSE(IsLoopbackHost(h)) << h;

  // The command refuses them too, with exit code 2, before opening anything.
  testing::CommandResult r = testing::RunRig("daemon --listen 0.0.0.0:0");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("--allow-remote"));
  r = testing::RunRig("daemon --listen 0.0.0.0:0 --allow-remote");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("needs a token"));
}

}  // namespace
}  // namespace rig
