// `rig daemon` as a process: rig capture --daemon submits the job to it, rig status reads it,
// SIGTERM parks the rig exactly as Ctrl-C does (journal ends on "interrupted", resumable),
// and rig resume --daemon --wait finishes the session through a new daemon.
#include <signal.h>

#include <chrono>
#include <fstream>
#include <map>
#include <regex>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "capture/service/client.h"
#include "capture/session/session_store.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;

const char* kSmall = R"([sim]
width = 160
height = 120
latency_scale = 0.02
[bracket]
center_s = 0.02
ev_step = 1.5
count = 3
)";

std::string ReadAll(const std::string& path) {
  std::ifstream in(path);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Starts `rig daemon` on an ephemeral loopback port; returns its pid and port.
std::pair<pid_t, int> StartDaemon(const std::string& log, const std::string& sessions_root) {
  pid_t pid = testing::SpawnRig({"daemon", "--listen", "127.0.0.1:0", "--sessions-root", sessions_root}, log);
  const std::regex re("listening on http://127\\.0\\.0\\.1:([0-9]+)/");
  for (int i = 0; i < 200; ++i) {
    std::smatch m;
    std::string text = ReadAll(log);
    if (std::regex_search(text, m, re)) return {pid, std::stoi(m[1].str())};
    std::this_thread::sleep_for(std::chrono::milliseconds(25));
  }
  ADD_FAILURE() << "the daemon did not say where it listens: " << ReadAll(log);
  return {pid, 0};
}

TEST(DaemonCommand, SubmitStatusSigtermParksAsCtrlCThenResumeThroughTheDaemon) {
  const std::string dir = testing::FreshTempDir("daemon_command");
  const std::string cfg = testing::WriteSimConfig(dir, kSmall);
  const fs::path session = fs::path(dir) / "S";
  auto [pid, port] = StartDaemon(dir + "/daemon1.log", dir);
  ASSERT_GT(port, 0);
  const std::string url = "http://127.0.0.1:" + std::to_string(port);

  testing::CommandResult sub = testing::RunRig("capture --config " + cfg + " --out " +
                                               session.string() + " --dry-run --no-process --daemon " + url);
  ASSERT_EQ(sub.status, 0) << sub.output;
  EXPECT_THAT(sub.output, HasSubstr("job 1 (capture " + session.string() + ") queued"));

  DaemonAddress a;
  a.port = port;
  DaemonClient client(a);
  int stored = 0;
  for (int i = 0; i < 1500 && stored < 12; ++i) {
    auto s = client.Get("/api/status");
    ASSERT_TRUE(s.ok()) << s.error().ToString();
    if ((*s)["frames"].is_object()) stored = (*s)["frames"]["stored"].get<int>();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_GE(stored, 12);
  testing::CommandResult st = testing::RunRig("status --daemon " + url);
  EXPECT_EQ(st.status, 0) << st.output;
  EXPECT_THAT(st.output, HasSubstr(": capturing; job 1 capture running"));
  EXPECT_THAT(st.output, HasSubstr("session " + session.string()));
  EXPECT_THAT(st.output, ::testing::ContainsRegex("pose h[0-9]+_v[0-9]+ \\([0-9]+ of 40\\)"));

  kill(pid, SIGTERM);
  EXPECT_EQ(testing::WaitRig(pid), 128 + SIGTERM) << ReadAll(dir + "/daemon1.log");
  auto journal = Journal::Read(session / "journal.jsonl");
  ASSERT_TRUE(journal.ok());
  const auto& recs = journal->records;
  ASSERT_FALSE(recs.empty());
  EXPECT_EQ(recs.back()["event"], "interrupted");  // as after Ctrl-C: parked, journal synced
  EXPECT_EQ(recs.back()["signal"], SIGTERM);
  int frames_before = 0;
  for (const auto& r : recs) frames_before += r["event"] == "frame" ? 1 : 0;
  EXPECT_GE(frames_before, 12);
  EXPECT_LT(frames_before, 120);
  EXPECT_THAT(ReadAll(dir + "/daemon1.log"), HasSubstr("rig resume"));

  // No daemon now: rig status says so, exit 1.
  testing::CommandResult none = testing::RunRig("status --daemon " + url);
  EXPECT_EQ(none.status, 1) << none.output;
  EXPECT_THAT(none.output, HasSubstr("no daemon answers"));

  auto [pid2, port2] = StartDaemon(dir + "/daemon2.log", dir);
  ASSERT_GT(port2, 0);
  testing::CommandResult res = testing::RunRig("resume " + session.string() +
                                               " --no-process --wait --daemon 127.0.0.1:" +
                                               std::to_string(port2));
  EXPECT_EQ(res.status, 0) << res.output;
  EXPECT_THAT(res.output, HasSubstr("job 1: done"));
  kill(pid2, SIGTERM);  // idle: closes at once
  EXPECT_EQ(testing::WaitRig(pid2), 128 + SIGTERM);

  journal = Journal::Read(session / "journal.jsonl");
  ASSERT_TRUE(journal.ok());
  std::map<std::pair<std::string, int>, int> count;
  for (const auto& r : journal->records)
    if (r["event"] == "frame") ++count[{r["pose"].get<std::string>(), r["index"].get<int>()}];
  EXPECT_EQ(count.size(), 120u);
  for (const auto& [key, n] : count) EXPECT_EQ(n, 1) << key.first << " " << key.second;
  EXPECT_EQ(journal->records.back()["event"], "capture_done");
}

}  // namespace
}  // namespace rig
