// rig daemon against hostile clients (issue 30), over real HTTP on an ephemeral loopback port:
// cross-site "simple" requests, a rebinding Host, slow and vanished clients, an oversized
// body, configuration paths that are not files of the sessions root, sessions outside it, a
// journal record of the wrong type, a preview through a planted link. Each is refused with a
// 4xx JSON answer naming the problem, and nothing starts.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "capture/devices/signals.h"
#include "capture/service/client.h"
#include "capture/service/http_server.h"
#include "capture/service/request_checks.h"
#include "capture/service/service.h"
#include "rig/commands/daemon_client.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}


// 8 poses x 3 exposures at 160x120, device latencies at 2% of real: well under a second.
const char* kTiny = R"([sim]
width = 160
height = 120
latency_scale = 0.02
[bracket]
count = 3
[grid]
h_max_deg = 30
v_max_deg = 10
)";

struct Daemon {
  std::string root;
  std::string config_text;  // kTiny over the simulated rig's configuration
  CaptureService service;
  std::unique_ptr<HttpServer> http;
  int port = 0;
  static ServiceOptions Under(const std::string& root) {
    ServiceOptions o;
    o.sessions_root = root;
    return o;
  }
  explicit Daemon(const std::string& name, HttpOptions o = {})
      : root(testing::FreshTempDir(name)),
        config_text(testing::ReadText(testing::WriteSimConfig(root, kTiny))),
        service(DaemonHooks(), Under(root)) {
    o.host = "127.0.0.1";
    o.port = 0;
    http = std::make_unique<HttpServer>(service, o);
    Status st = http->Start();
    EXPECT_TRUE(st.ok()) << (st.ok() ? "" : st.error().ToString());
    service.Start();
    port = http->port();
  }
  ~Daemon() {
    service.Shutdown();
    http->Stop();
    ClearStopForTesting();
  }
  httplib::Client Client() const {
    httplib::Client c("127.0.0.1", port);
    c.set_read_timeout(std::chrono::seconds(10));
    return c;
  }
  std::string Origin() const { return "http://127.0.0.1:" + std::to_string(port); }
  // A job the API accepts: {"kind":"capture", "session": ROOT/NAME, "config_toml": kTiny}.
  std::string Job(const std::string& name) const {
    return nlohmann::json{{"kind", "capture"}, {"session", root + "/" + name}, {"config_toml", config_text},
                          {"dry_run", true}, {"process", false}}
        .dump();
  }
};

// {"error": ...} of a refusal, with its status.
void ExpectRefused(const httplib::Result& r, int status, const std::string& says) {
  ASSERT_TRUE(r) << "no answer";
  EXPECT_EQ(r->status, status) << r->body;
  EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
  auto j = nlohmann::json::parse(r->body, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r->body;
  ASSERT_TRUE(j.contains("error")) << r->body;
  EXPECT_THAT(j["error"].get<std::string>(), HasSubstr(says));
}

// A raw TCP connection to 127.0.0.1:port (-1 when refused).
int Connect(int port) {
  int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  timeval tv{0, 200 * 1000};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  return fd;
}

void SendAll(int fd, const std::string& s) { (void)!::send(fd, s.data(), s.size(), MSG_NOSIGNAL); }

// What arrived within `limit_s`, until the peer closed or `until` appeared.
std::string ReadFor(int fd, double limit_s, const std::string& until = "") {
  std::string out;
  const auto t0 = Clock::now();
  char buf[4096];
  while (SecondsSince(t0) < limit_s) {
    ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n == 0) break;
    if (n > 0) out.append(buf, static_cast<size_t>(n));
    if (!until.empty() && out.find(until) != std::string::npos) break;
  }
  return out;
}

TEST(DaemonHostile, CrossSiteSimpleRequestsAreRefusedAndStartNoJob) {
  Daemon d("hostile_csrf");
  httplib::Client c = d.Client();
  const std::string job = d.Job("S");
  // What a page of any site can send without a preflight: text/plain, a form, multipart.
  ExpectRefused(c.Post("/api/jobs", job, "text/plain"), 415, "application/json");
  ExpectRefused(c.Post("/api/jobs", "kind=capture&session=" + d.root + "/S",
                       "application/x-www-form-urlencoded"),
                415, "application/json");
  ExpectRefused(c.Post("/api/jobs", job, "multipart/form-data; boundary=x"), 415, "application/json");
  ExpectRefused(c.Post("/api/stop", "", "text/plain"), 415, "/api/stop");
  ExpectRefused(c.Post("/api/resume", httplib::Headers{}, "", ""), 415, "none");
  // JSON with another site's Origin, or marked cross-site by the browser.
  ExpectRefused(c.Post("/api/jobs", {{"Origin", "http://evil.example"}}, job, "application/json"), 403,
                "Origin 'http://evil.example'");
  ExpectRefused(c.Post("/api/stop", {{"Origin", "http://127.0.0.1:1"}}, "{}", "application/json"), 403,
                "not this daemon's page");
  ExpectRefused(c.Post("/api/stop", {{"Origin", "null"}}, "{}", "application/json"), 403, "Origin 'null'");
  ExpectRefused(c.Post("/api/jobs", {{"Sec-Fetch-Site", "cross-site"}}, job, "application/json"), 403,
                "cross-site");
  // The daemon's own origin from a browser, without the page's token.
  ExpectRefused(c.Post("/api/jobs", {{"Origin", d.Origin()}}, job, "application/json"), 403,
                kPageTokenHeader);
  ExpectRefused(c.Post("/api/jobs", {{"Origin", d.Origin()}, {kPageTokenHeader, "guess"}}, job,
                       "application/json"),
                403, kPageTokenHeader);
  auto jobs = c.Get("/api/jobs");
  ASSERT_TRUE(jobs);
  EXPECT_EQ(nlohmann::json::parse(jobs->body)["jobs"].size(), 0u) << jobs->body;
  EXPECT_FALSE(fs::exists(d.root + "/S"));

  // The page's own request (its origin, its token, JSON) and a command-line client's pass.
  auto page = c.Post("/api/stop", {{"Origin", d.Origin()}, {kPageTokenHeader, d.http->page_token()},
                                   {"Sec-Fetch-Site", "same-origin"}},
                     "{}", "application/json");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200) << page->body;
  auto cli = c.Post("/api/jobs", job, "application/json");
  ASSERT_TRUE(cli);
  EXPECT_EQ(cli->status, 202) << cli->body;
}

TEST(DaemonHostile, AForeignHostIsRefusedAsARebindingPageWouldBe) {
  HttpOptions o;
  o.allowed_hosts = {"rig.lan", "proxy.example:8443"};
  Daemon d("hostile_host", o);
  httplib::Client c = d.Client();
  const std::string port = std::to_string(d.port);
  for (const char* path : {"/", "/api/status", "/api/jobs", "/api/journal", "/api/preview/frame.jpg"}) {
    ExpectRefused(c.Get(path, {{"Host", "evil.example:" + port}}), 421, "Host header 'evil.example:" + port);
  }
  ExpectRefused(c.Get("/api/status", {{"Host", "127.0.0.1:1"}}), 421, "not this daemon's address");
  ExpectRefused(c.Get("/api/status", {{"Host", "localhost"}}), 421, "'localhost'");  // port 80
  ExpectRefused(c.Get("/api/status", {{"Host", "proxy.example:443"}}), 421, "proxy.example");
  ExpectRefused(c.Get("/api/status", {{"Host", "bad host"}}), 400, "malformed Host header");
  for (std::string host : {"127.0.0.1:" + port, "localhost:" + port, "LOCALHOST:" + port,
                           std::string("rig.lan"), std::string("proxy.example:8443")}) {
    auto r = c.Get("/api/status", {{"Host", host}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << host << ": " << r->body;
  }
}

TEST(DaemonHostile, PageHeadersForbidFramingSniffingReferrersAndForeignScripts) {
  Daemon d("hostile_page");
  httplib::Client c = d.Client();
  auto page = c.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  const std::string csp = page->get_header_value("Content-Security-Policy");
  EXPECT_THAT(csp, HasSubstr("default-src 'self'"));
  EXPECT_THAT(csp, HasSubstr("frame-ancestors 'none'"));
  EXPECT_EQ(csp.find("unsafe-inline"), std::string::npos) << csp;
  EXPECT_EQ(page->get_header_value("X-Frame-Options"), "DENY");
  EXPECT_EQ(page->get_header_value("X-Content-Type-Options"), "nosniff");
  EXPECT_EQ(page->get_header_value("Referrer-Policy"), "no-referrer");
  EXPECT_THAT(page->body, HasSubstr("<meta name=\"rig-page-token\" content=\"" + d.http->page_token() + "\">"));
  EXPECT_EQ(d.http->page_token().size(), 64u);
  EXPECT_EQ(page->body.find("<script>"), std::string::npos);  // nothing inline: CSP allows none
  EXPECT_EQ(page->body.find("style=\""), std::string::npos);
  auto js = c.Get("/page.js");
  ASSERT_TRUE(js);
  EXPECT_EQ(js->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_THAT(js->body, HasSubstr("\"X-Rig-Page-Token\": pageToken"));
  EXPECT_THAT(js->body, HasSubstr("\"Content-Type\": \"application/json\""));
  auto css = c.Get("/page.css");
  ASSERT_TRUE(css);
  EXPECT_EQ(css->get_header_value("Content-Type"), "text/css; charset=utf-8");
  // Another daemon, another token.
  Daemon e("hostile_page2");
  EXPECT_NE(e.http->page_token(), d.http->page_token());
}

long RssKiB() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

TEST(DaemonHostile, AnOversizedBodyIsRefusedUnreadAndAChunkedOneToo) {
  Daemon d("hostile_body");
  const long before = RssKiB();
  const auto t0 = Clock::now();
  int fd = Connect(d.port);
  ASSERT_GE(fd, 0);
  const std::string head = "POST /api/jobs HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(d.port) +
                           "\r\nContent-Type: application/json\r\nContent-Length: 536870912\r\n\r\n";
  SendAll(fd, head);
  // Keep sending (as the attack did) while reading the answer.
  const std::string chunk(1 << 16, 'x');
  std::string answer;
  double refuse_s = -1;
  for (int i = 0; i < 200 && refuse_s < 0; ++i) {
    (void)!::send(fd, chunk.data(), chunk.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    answer += ReadFor(fd, 0.02, "}");
    if (answer.find("}") != std::string::npos) refuse_s = SecondsSince(t0);
  }
  ::close(fd);
  const long after = RssKiB();
  EXPECT_THAT(answer, HasSubstr("HTTP/1.1 413"));
  EXPECT_THAT(answer, HasSubstr("a body of 536870912 bytes (Content-Length): at most 1048576 bytes"));
  EXPECT_GE(refuse_s, 0);
  EXPECT_LT(refuse_s, 1.0);
  EXPECT_LT(after - before, 64 * 1024) << "RSS " << before << " KiB -> " << after << " KiB";
  std::printf("oversized body: refused in %.3f s; RSS %ld KiB -> %ld KiB\n", refuse_s, before, after);

  // Announced, never sent: refused on the headers alone.
  fd = Connect(d.port);
  SendAll(fd, "POST /api/jobs HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(d.port) +
                  "\r\nContent-Type: application/json\r\nContent-Length: 2097152\r\n\r\n");
  const std::string announced = ReadFor(fd, 2, "}");
  ::close(fd);
  EXPECT_THAT(announced, HasSubstr("HTTP/1.1 413"));
  EXPECT_THAT(announced, HasSubstr("at most 1048576 bytes"));
  // A request line without an end: cut by its byte budget, not grown for 5 s.
  fd = Connect(d.port);
  const long line_before = RssKiB();
  const auto t1 = Clock::now();
  std::string endless;
  SendAll(fd, "GET /");
  for (int i = 0; i < 400 && endless.find("HTTP/1.1") == std::string::npos; ++i) {
    (void)!::send(fd, chunk.data(), chunk.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    endless += ReadFor(fd, 0.01);
  }
  ::close(fd);
  EXPECT_THAT(endless, HasSubstr("HTTP/1.1 431"));
  EXPECT_THAT(endless, HasSubstr("without the request's headers ending (at most 65536)"));
  EXPECT_LT(SecondsSince(t1), 1.0);
  EXPECT_LT(RssKiB() - line_before, 64 * 1024);
  fd = Connect(d.port);
  SendAll(fd, "POST /api/stop HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(d.port) +
                  "\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n2\r\n{}\r\n0\r\n\r\n");
  const std::string chunked = ReadFor(fd, 2, "}");
  ::close(fd);
  EXPECT_THAT(chunked, HasSubstr("HTTP/1.1 411"));
  EXPECT_THAT(chunked, HasSubstr("Transfer-Encoding 'chunked' is not accepted"));
}

// A stream opened by a raw GET; returns the socket once the answer's headers came.
int OpenStream(int port, std::string* head) {
  int fd = Connect(port);
  if (fd < 0) return fd;
  SendAll(fd, "GET /api/events HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) + "\r\n\r\n");
  *head = ReadFor(fd, 2, "\r\n\r\n");
  return fd;
}

TEST(DaemonHostile, StopAnswersFastWithEightStreamsAndFortySlowClientsAndGoneClientsAreFreed) {
  HttpOptions o;
  o.heartbeat_s = 0.3;
  o.request_timeout_s = 2;
  Daemon d("hostile_flood", o);
  const auto tsetup = Clock::now();
  std::vector<int> streams;
  for (int i = 0; i < 8; ++i) {
    std::string head;
    streams.push_back(OpenStream(d.port, &head));
    ASSERT_THAT(head, HasSubstr("HTTP/1.1 200")) << i;
  }
  // A ninth stream is refused with a message.
  std::string ninth;
  int extra = OpenStream(d.port, &ninth);
  if (ninth.find("}") == std::string::npos) ninth += ReadFor(extra, 1, "}");
  ::close(extra);
  EXPECT_THAT(ninth, HasSubstr("HTTP/1.1 503"));
  EXPECT_THAT(ninth, HasSubstr("8 event streams are open (at most 8)"));
  // 40 clients dribbling their headers a byte at a time.
  std::vector<int> slow;
  for (int i = 0; i < 40; ++i) {
    int fd = Connect(d.port);
    ASSERT_GE(fd, 0);
    SendAll(fd, "G");
    slow.push_back(fd);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  for (int fd : slow) SendAll(fd, "E");
  httplib::Client c = d.Client();
  const auto t0 = Clock::now();
  auto stop = c.Post("/api/stop", "{}", "application/json");
  const double stop_s = SecondsSince(t0);
  ASSERT_TRUE(stop);
  EXPECT_EQ(stop->status, 200) << stop->body;
  EXPECT_LT(stop_s, 1.0);
  std::printf("POST /api/stop with 8 streams and 40 slow clients open: %.3f s\n", stop_s);
  // A dribbler that went on is cut when its request is late (2 s here; 5 s by default).
  const auto t1 = Clock::now();
  std::string cut;
  while (SecondsSince(t1) < 4 && cut.find("HTTP/1.1") == std::string::npos) {
    SendAll(slow.back(), "T");
    cut += ReadFor(slow.back(), 0.2);
  }
  EXPECT_THAT(cut, ::testing::AnyOf(HasSubstr("HTTP/1.1 408"), HasSubstr("HTTP/1.1 503"))) << cut;
  for (int fd : slow) ::close(fd);
  // The stream clients go away without a word: the heartbeat finds them gone, and new
  // streams are taken again.
  for (int fd : streams) ::close(fd);
  const auto t2 = Clock::now();
  std::string head;
  int again = -1;
  while (SecondsSince(t2) < 4) {
    again = OpenStream(d.port, &head);
    if (head.find("HTTP/1.1 200") != std::string::npos) break;
    ::close(again);
    again = -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_THAT(head, HasSubstr("HTTP/1.1 200"));
  const std::string beat = ReadFor(again, 1.5, ": heartbeat");
  EXPECT_THAT(beat, HasSubstr(": heartbeat"));
  ::close(again);
  std::printf("flood test: %.3f s from the first stream\n", SecondsSince(tsetup));
}

TEST(DaemonHostile, ConfigPathsThatAreNotSmallRegularFilesOfTheRootAreRefusedFast) {
  Daemon d("hostile_config");
  httplib::Client c = d.Client();
  auto post = [&](const std::string& config, const std::string& session = "S") {
    return c.Post("/api/jobs",
                  nlohmann::json{{"kind", "capture"}, {"session", d.root + "/" + session}, {"config", config}}.dump(),
                  "application/json");
  };
  ExpectRefused(post("/etc/passwd"), 400, "'/etc/passwd' is not under the daemon's sessions root");
  ExpectRefused(post("/dev/zero"), 400, "is not under the daemon's sessions root");
  const std::string fifo = d.root + "/fifo.toml";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto t0 = Clock::now();
  ExpectRefused(post(fifo), 400, fifo + ": the configuration is not a regular file");
  const double fifo_s = SecondsSince(t0);
  EXPECT_LT(fifo_s, 1.0);
  std::printf("config FIFO refused in %.3f s\n", fifo_s);
  fs::create_symlink("/dev/zero", d.root + "/zero.toml");
  ExpectRefused(post(d.root + "/zero.toml"), 400, "is not under the daemon's sessions root");
  fs::create_symlink("/etc", d.root + "/etc");
  ExpectRefused(post(d.root + "/etc/passwd"), 400, "is not under the daemon's sessions root");
  ExpectRefused(post("fifo.toml/../../../etc/passwd"), 400, "is not under the daemon's sessions root");
  const std::string big = d.root + "/big.toml";
  std::ofstream(big) << std::string((1 << 20) + 1, '#');
  ExpectRefused(post(big), 400, "the configuration is 1048577 bytes: at most 1048576");
  fs::create_directories(d.root + "/dir.toml");
  ExpectRefused(post(d.root + "/dir.toml"), 400, "not a regular file");
  // A file of the root with problems: where they are, never what it holds.
  const std::string secret = d.root + "/secret.toml";
  std::ofstream(secret) << "[camera]\nbackend = \"hunter2-secret\"\n";
  auto r = post(secret);
  ExpectRefused(r, 400, "line 2");
  EXPECT_EQ(r->body.find("hunter2"), std::string::npos) << r->body;
  // A good file of the root (relative to it) is taken.
  std::ofstream(d.root + "/good.toml") << d.config_text;
  auto good = c.Post("/api/jobs",
                     nlohmann::json{{"kind", "capture"}, {"session", "G"}, {"config", "good.toml"},
                                    {"dry_run", true}, {"process", false}}.dump(),
                     "application/json");
  ASSERT_TRUE(good);
  EXPECT_EQ(good->status, 202) << good->body;
  EXPECT_EQ(nlohmann::json::parse(good->body)["session"], fs::weakly_canonical(d.root + "/G").string());
}

TEST(DaemonHostile, SessionsOutsideTheRootAndPathsWithNulOrControlCharactersAreRefused) {
  Daemon d("hostile_session");
  httplib::Client c = d.Client();
  auto post = [&](const std::string& session) {
    return c.Post("/api/jobs",
                  nlohmann::json{{"kind", "capture"}, {"session", session}, {"config_toml", d.config_text},
                                 {"dry_run", true}}.dump(),
                  "application/json");
  };
  ExpectRefused(post("/tmp/rig_hostile_elsewhere"), 400, "is not under the daemon's sessions root");
  ExpectRefused(post(d.root + "/../escape"), 400, "is not under the daemon's sessions root");
  ExpectRefused(post(d.root), 400, "is not under the daemon's sessions root");
  ExpectRefused(post(d.root + std::string("/A\0/../../etc", 14)), 400, "a NUL byte at offset");
  ExpectRefused(post(d.root + "/A\nB"), 400, "a control character (0x0a)");
  fs::create_symlink("/tmp", d.root + "/out");
  ExpectRefused(post(d.root + "/out/S"), 400, "is not under the daemon's sessions root");
  ExpectRefused(c.Post("/api/resume", nlohmann::json{{"session", "/etc"}}.dump(), "application/json"), 400,
                "is not under the daemon's sessions root");
  auto jobs = c.Get("/api/jobs");
  ASSERT_TRUE(jobs);
  EXPECT_EQ(nlohmann::json::parse(jobs->body)["jobs"].size(), 0u);
  EXPECT_FALSE(fs::exists("/tmp/rig_hostile_elsewhere"));
  EXPECT_FALSE(fs::exists("/tmp/S"));
}

// A short dry capture under the daemon's root; returns its session folder.
fs::path CaptureTiny(Daemon& d, httplib::Client& c) {
  auto job = c.Post("/api/jobs", d.Job("S"), "application/json");
  EXPECT_TRUE(job && job->status == 202) << (job ? job->body : "no answer");
  const auto t0 = Clock::now();
  while (SecondsSince(t0) < 30) {
    auto j = c.Get("/api/jobs/1");
    if (j && nlohmann::json::parse(j->body)["state"] != "queued" &&
        nlohmann::json::parse(j->body)["state"] != "running")
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return fs::path(d.root) / "S";
}

TEST(DaemonHostile, AJournalRecordOfTheWrongTypeIsSkippedAndEventsStillAnswer) {
  Daemon d("hostile_journal");
  httplib::Client c = d.Client();
  const fs::path s = CaptureTiny(d, c);
  auto before = c.Get("/api/status");
  ASSERT_TRUE(before);
  const auto records = nlohmann::json::parse(before->body)["journal_records"].get<size_t>();
  ASSERT_GT(records, 8u);
  {
    std::ofstream j(s / "journal.jsonl", std::ios::app);
    j << R"({"event":"frame","pose":5,"index":"x","file":7})" << "\n"
      << R"({"event":17})" << "\n"
      << R"({"event":"plan","poses":"h0_v0","exposures_s":1})" << "\n"
      << R"(["not","an","object"])" << "\n";
  }
  std::string events;
  httplib::Client sc = d.Client();
  auto sse = sc.Get("/api/events", [&](const char* data, size_t n) {
    events.append(data, n);
    return events.find("event: status") == std::string::npos;
  });
  EXPECT_THAT(events, HasSubstr("id: " + std::to_string(records - 1) + "\nevent: journal"));
  EXPECT_THAT(events, HasSubstr("event: status"));
  EXPECT_EQ(events.find("id: " + std::to_string(records) + "\n"), std::string::npos);
  auto after = c.Get("/api/status");
  ASSERT_TRUE(after);
  ASSERT_EQ(after->status, 200);
  const auto st = nlohmann::json::parse(after->body);
  EXPECT_EQ(st["journal_records"], records);
  EXPECT_EQ(st["journal_skipped"], 4);
  EXPECT_EQ(st["state"], "idle");
}

TEST(DaemonHostile, APreviewThroughALinkPlantedInTheSessionIsRefused) {
  Daemon d("hostile_preview");
  httplib::Client c = d.Client();
  const fs::path s = CaptureTiny(d, c);
  auto st = nlohmann::json::parse(c.Get("/api/status")->body);
  ASSERT_TRUE(st["last_frame"].is_object()) << st.dump();
  const fs::path frame = s / st["last_frame"]["file"].get<std::string>();
  auto ok = c.Get("/api/preview/frame.jpg");
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
  // The frame replaced by a link to a file outside the session (a JPEG, so that the preview
  // would show it), then by a link to a file inside it.
  const fs::path outside = fs::path(d.root) / "outside.jpg";
  fs::copy_file(frame, outside);
  fs::remove(frame);
  fs::create_symlink(outside, frame);
  ExpectRefused(c.Get("/api/preview/frame.jpg"), 404, "no frame yet");
  fs::remove(frame);
  fs::copy_file(outside, s / "inside.jpg");
  fs::create_symlink(s / "inside.jpg", frame);
  ExpectRefused(c.Get("/api/preview/frame.jpg"), 404, "no frame yet");
}

}  // namespace
}  // namespace rig
