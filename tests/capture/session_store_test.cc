// Session store: the journal survives a torn last line, atomic writes never show a partial
// file, and the session lock refuses a second process and is freed when its holder dies.
#include "capture/session/session_store.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <random>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace rig {
namespace {

fs::path TempDir(const std::string& name) {
  fs::path p = fs::temp_directory_path() / fmt::format("rig_{}_{}", name, ::getpid());
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(Journal, AppendsAndReadsBackRecords) {
  fs::path dir = TempDir("journal");
  {
    auto j = Journal::Open(dir / "journal.jsonl");
    ASSERT_TRUE(j.ok()) << j.error().ToString();
    for (int i = 0; i < 5; ++i) ASSERT_TRUE(j->Append({{"event", "note"}, {"index", i}}).ok());
  }
  auto c = Journal::Read(dir / "journal.jsonl");
  ASSERT_TRUE(c.ok());
  ASSERT_EQ(c->records.size(), 5u);
  EXPECT_FALSE(c->torn_tail);
  EXPECT_EQ(c->records[3]["index"], 3);
  EXPECT_TRUE(c->records[3].contains("t"));
}

TEST(Journal, TornLastLineIsIgnoredReportedAndCutOnReopen) {
  fs::path dir = TempDir("torn");
  fs::path path = dir / "journal.jsonl";
  {
    auto j = Journal::Open(path);
    ASSERT_TRUE(j.ok());
    ASSERT_TRUE(j->Append({{"event", "a"}}).ok());
    ASSERT_TRUE(j->Append({{"event", "b"}}).ok());
  }
  std::string intact = Slurp(path);
  std::ofstream(path, std::ios::app) << R"({"event":"frame","pose":"h0)";  // a crash mid-line
  auto c = Journal::Read(path);
  ASSERT_TRUE(c.ok());
  EXPECT_TRUE(c->torn_tail);
  EXPECT_EQ(c->records.size(), 2u);
  ASSERT_EQ(c->warnings.size(), 1u);
  EXPECT_THAT(c->warnings[0], ::testing::HasSubstr("journal.jsonl:3: last record is incomplete"));
  {
    auto j = Journal::Open(path);  // cuts the torn tail, then appends cleanly
    ASSERT_TRUE(j.ok());
    ASSERT_TRUE(j->Append({{"event", "c"}}).ok());
  }
  auto c2 = Journal::Read(path);
  ASSERT_TRUE(c2.ok());
  EXPECT_FALSE(c2->torn_tail);
  ASSERT_EQ(c2->records.size(), 3u);
  EXPECT_EQ(c2->records[2]["event"], "c");
  EXPECT_EQ(Slurp(path).substr(0, intact.size()), intact);
}

TEST(Journal, DamagedMiddleLineIsAnErrorWithItsLineNumber) {
  fs::path dir = TempDir("damaged");
  fs::path path = dir / "journal.jsonl";
  std::ofstream(path) << "{\"event\":\"a\"}\n{garbage\n{\"event\":\"b\"}\n";
  auto c = Journal::Read(path);
  ASSERT_FALSE(c.ok());
  EXPECT_THAT(c.error().ToString(), ::testing::HasSubstr("journal.jsonl:2"));
}

TEST(AtomicWrite, NeverOverwritesWhenAskedNotTo) {
  fs::path dir = TempDir("nooverwrite");
  ASSERT_TRUE(WriteFileAtomic(dir / "f.jpg", std::string("first"), false).ok());
  Status st = WriteFileAtomic(dir / "f.jpg", std::string("second"), false);
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), ::testing::HasSubstr("refusing to overwrite"));
  EXPECT_EQ(Slurp(dir / "f.jpg"), "first");
}

// A child process rewrites a large file again and again; it is killed at a random moment,
// many times over. The final name must always hold one complete version, never a mix.
TEST(AtomicWrite, KilledWriterNeverLeavesAPartialFileUnderTheFinalName) {
  fs::path dir = TempDir("atomic");
  fs::path target = dir / "big.bin";
  const size_t kSize = 8 << 20;
  // Version 0 is all 'A'; every later version one of 'B'..'Z', never 'A' again.
  auto content = [&](int version) {
    return std::string(kSize, static_cast<char>(version == 0 ? 'A' : 'B' + version % 25));
  };
  ASSERT_TRUE(WriteFileAtomic(target, content(0)).ok());
  // Kills are placed by the writer's progress, not by the clock (a write takes milliseconds on
  // an idle disk and most of a second on a loaded one): the child reports each finished write
  // on a pipe; each round waits for 0..2 of them, then kills at a random moment within about
  // one write's time — inside a write, between two, or during the rename.
  std::mt19937 rng(42);
  int observed_versions = 0;
  for (int round = 0; round < 12; ++round) {
    int done[2];
    ASSERT_EQ(pipe(done), 0);
    pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      close(done[0]);
      for (int v = 1 + round * 3;; ++v) {
        if (!WriteFileAtomic(target, content(v)).ok()) _exit(3);
        if (write(done[1], "w", 1) != 1) _exit(4);
      }
    }
    close(done[1]);
    const int wait_for = static_cast<int>(rng() % 3);
    auto last = std::chrono::steady_clock::now();
    auto one_write = std::chrono::microseconds(20000);
    for (int k = 0; k < wait_for; ++k) {
      char c;
      if (read(done[0], &c, 1) != 1) {
        int st = 0;
        waitpid(pid, &st, 0);
        FAIL() << "round " << round << ": the writer stopped (exit " << WEXITSTATUS(st) << ")";
      }
      const auto now = std::chrono::steady_clock::now();
      one_write = std::chrono::duration_cast<std::chrono::microseconds>(now - last);
      last = now;
    }
    std::this_thread::sleep_for(one_write * static_cast<int>(rng() % 100) / 100);
    kill(pid, SIGKILL);
    int status = 0;
    waitpid(pid, &status, 0);
    close(done[0]);
    std::string now = Slurp(target);
    ASSERT_EQ(now.size(), kSize) << "round " << round;
    EXPECT_EQ(now.find_first_not_of(now[0]), std::string::npos) << "mixed content, round " << round;
    if (wait_for > 0) {
      ++observed_versions;
      EXPECT_NE(now[0], 'A') << "round " << round << ": a finished write is not under the final name";
    }
  }
  EXPECT_GT(observed_versions, 0);  // the writer did replace the file in some rounds
}

TEST(SessionLock, SecondHolderIsRefusedAndLockIsFreedWhenHolderIsKilled) {
  fs::path dir = TempDir("lock");
  int ready[2];
  ASSERT_EQ(pipe(ready), 0);
  pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    auto lock = SessionLock::Acquire(dir);
    char c = lock.ok() ? 'y' : 'n';
    if (write(ready[1], &c, 1) != 1) _exit(2);
    pause();
    _exit(0);
  }
  char c = 0;
  ASSERT_EQ(read(ready[0], &c, 1), 1);
  ASSERT_EQ(c, 'y');
  auto second = SessionLock::Acquire(dir);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.error().code, ErrorCode::kBusy);
  EXPECT_THAT(second.error().ToString(), ::testing::HasSubstr(fmt::format("pid {}", pid)));
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  auto third = SessionLock::Acquire(dir);
  EXPECT_TRUE(third.ok()) << third.error().ToString();
  close(ready[0]);
  close(ready[1]);
}

TEST(Session, CreateRefusesAnExistingSessionAndStoresFramesWithChecksums) {
  fs::path dir = TempDir("session");
  Config config;
  config.camera.backend = config.motor.backend = config.lamp.backend = "sim";
  config.bracket.center_s = 0.01;
  config.bracket.count = 3;
  {
    auto s = Session::Create(dir, config);
    ASSERT_TRUE(s.ok()) << s.error().ToString();
    std::vector<uint8_t> bytes = {1, 2, 3, 4, 5};
    auto rec = s->StoreFrame("h030_v10", 0, 0.01, "jpg", bytes);
    ASSERT_TRUE(rec.ok()) << rec.error().ToString();
    EXPECT_EQ((*rec)["file"], "frames/h030_v10/0_0.01000.jpg");
    EXPECT_EQ((*rec)["crc32"], Crc32(bytes));
    auto again = s->StoreFrame("h030_v10", 0, 0.01, "jpg", bytes);
    EXPECT_FALSE(again.ok());  // never overwrites a stored frame
  }
  auto dup = Session::Create(dir, config);
  ASSERT_FALSE(dup.ok());
  EXPECT_THAT(dup.error().ToString(), ::testing::HasSubstr("already holds a session"));
  auto opened = Session::OpenExisting(dir);
  ASSERT_TRUE(opened.ok()) << opened.error().ToString();
  ASSERT_EQ(opened->history().records.size(), 2u);  // the configuration's digest, the frame
  EXPECT_EQ(opened->history().records[0]["event"], "config");
  EXPECT_EQ(opened->config().bracket.count, 3);
}

}  // namespace
}  // namespace rig
