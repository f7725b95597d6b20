// The project's one writer (config/atomic_file.h): a link at the target is replaced, never
// followed; a link or file planted at a temporary-like name is never opened; overwrite off
// replaces nothing; a failed or abandoned write leaves nothing behind; a folder written whole
// is exchanged with the old one, refused when it is a link or holds someone else's files.
#include "config/atomic_file.h"

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/support/run_rig.h"

namespace rig {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string Slurp(const fs::path& p) { return testing::ReadText(p.string()); }

void Put(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

// Every entry of a folder, names only.
std::vector<std::string> Names(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

TEST(AtomicFile, ALinkAtTheTargetIsReplacedNotFollowed) {
  const fs::path dir = testing::FreshTempDir("atomic-link");
  Put(dir / "outside.txt", "someone else's");
  fs::create_symlink(dir / "outside.txt", dir / "out.txt");
  ASSERT_TRUE(WriteFileAtomic(dir / "out.txt", std::string_view("ours")).ok());
  EXPECT_EQ(Slurp(dir / "outside.txt"), "someone else's");
  EXPECT_FALSE(fs::is_symlink(fs::symlink_status(dir / "out.txt")));
  EXPECT_EQ(Slurp(dir / "out.txt"), "ours");
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"out.txt", "outside.txt"}));
}

TEST(AtomicFile, LinksAtTheOldFixedTemporaryNamesAreNeverOpened) {
  const fs::path dir = testing::FreshTempDir("atomic-planted");
  Put(dir / "outside.txt", "someone else's");
  for (const char* name : {"out.ptm.tmp", ".out.ptm.tmp", ".info.json.tmp"})
    fs::create_symlink(dir / "outside.txt", dir / name);
  ASSERT_TRUE(WriteFileAtomic(dir / "out.ptm", std::string_view("ours")).ok());
  auto file = AtomicFile::Create(dir / "info.json");
  ASSERT_TRUE(file.ok());
  ASSERT_TRUE(file->Write("{}").ok());
  ASSERT_TRUE(file->Commit().ok());
  EXPECT_EQ(Slurp(dir / "outside.txt"), "someone else's");
  EXPECT_EQ(Slurp(dir / "info.json"), "{}");
}

TEST(AtomicFile, OverwriteOffReplacesNeitherAFileNorALink) {
  const fs::path dir = testing::FreshTempDir("atomic-noreplace");
  Put(dir / "f.jpg", "first");
  Status st = WriteFileAtomic(dir / "f.jpg", std::string_view("second"), false);
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("refusing to overwrite"));
  EXPECT_EQ(Slurp(dir / "f.jpg"), "first");
  fs::create_symlink("nowhere", dir / "g.jpg");
  EXPECT_FALSE(WriteFileAtomic(dir / "g.jpg", std::string_view("x"), false).ok());
  EXPECT_TRUE(fs::is_symlink(fs::symlink_status(dir / "g.jpg")));
  EXPECT_TRUE(WriteFileAtomic(dir / "h.jpg", std::string_view("new"), false).ok());
  EXPECT_EQ(Slurp(dir / "h.jpg"), "new");
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"f.jpg", "g.jpg", "h.jpg"}));
}

TEST(AtomicFile, ConcurrentNoOverwriteWritersLeaveExactlyOneWinner) {
  const fs::path dir = testing::FreshTempDir("atomic-race");
  std::vector<std::thread> threads;
  std::atomic<int> won{0};
  for (int t = 0; t < 8; ++t)
    threads.emplace_back([&, t] {
      if (WriteFileAtomic(dir / "frame.jpg", std::to_string(t), false).ok()) ++won;
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(won.load(), 1);
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"frame.jpg"}));  // no temporary left
}

TEST(AtomicFile, AFailedOrAbandonedWriteLeavesNothing) {
  const fs::path dir = testing::FreshTempDir("atomic-fail");
  fs::create_directory(dir / "sub");
  Status st = WriteFileAtomic(dir / "sub", std::string_view("x"));  // a folder is not replaced
  EXPECT_FALSE(st.ok());
  EXPECT_THAT(st.error().ToString(), HasSubstr("sub"));
  {
    auto f = AtomicFile::Create(dir / "big.exr");
    ASSERT_TRUE(f.ok());
    ASSERT_TRUE(f->Write(std::string(3 << 20, 'x')).ok());
    EXPECT_TRUE(fs::exists(f->temp_path()));
  }  // destroyed uncommitted
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"sub"}));
  if (::geteuid() != 0) {  // a folder without write permission: the temporary cannot be made
    fs::create_directory(dir / "ro");
    fs::permissions(dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_FALSE(WriteFileAtomic(dir / "ro" / "x", std::string_view("x")).ok());
    fs::permissions(dir / "ro", fs::perms::owner_all);
    EXPECT_TRUE(fs::is_empty(dir / "ro"));
  }
}

TEST(AtomicFile, SeekRewritesInPlaceAndTheModeHonoursTheUmask) {
  const fs::path dir = testing::FreshTempDir("atomic-seek");
  const mode_t old = ::umask(027);
  auto f = AtomicFile::Create(dir / "t.bin");
  ::umask(old);
  ASSERT_TRUE(f.ok());
  ASSERT_TRUE(f->Write("0000abcd").ok());
  EXPECT_EQ(f->Tell(), 8u);
  ASSERT_TRUE(f->Seek(0).ok());
  ASSERT_TRUE(f->Write("1234").ok());
  ASSERT_TRUE(f->Commit().ok());
  EXPECT_EQ(Slurp(dir / "t.bin"), "1234abcd");
  struct stat st {};
  ASSERT_EQ(::stat((dir / "t.bin").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
}

TEST(AtomicFolder, ReplacesTheOldFolderWholeAndCleansStaleTemporaries) {
  const fs::path dir = testing::FreshTempDir("atomic-folder");
  fs::create_directory(dir / "model");
  Put(dir / "model" / "info.json", "old");
  Put(dir / "model" / "plane_5.jpg", "old plane");
  fs::create_directory(dir / ".model.AbC123");  // a killed writer's
  Put(dir / ".model.AbC123" / "plane_0.jpg", "stale");
  auto model_file = [](const std::string& n) { return n == "info.json" || n.rfind("plane_", 0) == 0; };
  auto f = AtomicFolder::Begin(dir / "model", model_file);
  ASSERT_TRUE(f.ok()) << f.error().ToString();
  EXPECT_FALSE(fs::exists(dir / ".model.AbC123"));
  Put(f->dir() / "info.json", "new");
  Put(f->dir() / "plane_0.jpg", "new plane");
  EXPECT_EQ(Slurp(dir / "model" / "info.json"), "old");  // nothing seen before the commit
  ASSERT_TRUE(f->Commit().ok());
  EXPECT_EQ(Names(dir / "model"), (std::vector<std::string>{"info.json", "plane_0.jpg"}));
  EXPECT_EQ(Slurp(dir / "model" / "info.json"), "new");
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"model"}));
}

TEST(AtomicFolder, ALiveWritersTemporaryIsNotStaleToAnother) {
  const fs::path dir = testing::FreshTempDir("atomic-folder-two");
  auto first = AtomicFolder::Begin(dir / "model");
  ASSERT_TRUE(first.ok());
  auto second = AtomicFolder::Begin(dir / "model");  // would remove a killed writer's
  ASSERT_TRUE(second.ok());
  EXPECT_TRUE(fs::is_directory(first->dir()));
  Put(first->dir() / "info.json", "first");
  Put(second->dir() / "info.json", "second");
  ASSERT_TRUE(first->Commit().ok());
  ASSERT_TRUE(second->Commit().ok());
  EXPECT_EQ(Slurp(dir / "model" / "info.json"), "second");
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"model"}));
}

TEST(AtomicFolder, RefusesALinkAndAFolderHoldingOtherFiles) {
  const fs::path dir = testing::FreshTempDir("atomic-folder-refuse");
  fs::create_directory(dir / "elsewhere");
  Put(dir / "elsewhere" / "thesis.tex", "years of work");
  fs::create_directory_symlink(dir / "elsewhere", dir / "link");
  auto model_file = [](const std::string& n) { return n == "info.json"; };
  auto a = AtomicFolder::Begin(dir / "link", model_file);
  ASSERT_FALSE(a.ok());
  EXPECT_EQ(a.error().ExitCode(), 2);
  EXPECT_THAT(a.error().ToString(), HasSubstr("link"));
  auto b = AtomicFolder::Begin(dir / "elsewhere", model_file);
  ASSERT_FALSE(b.ok());
  EXPECT_THAT(b.error().ToString(), HasSubstr("thesis.tex"));
  EXPECT_EQ(Slurp(dir / "elsewhere" / "thesis.tex"), "years of work");
  {
    auto c = AtomicFolder::Begin(dir / "fresh", model_file);  // abandoned: nothing left
    ASSERT_TRUE(c.ok());
    Put(c->dir() / "info.json", "x");
  }
  EXPECT_EQ(Names(dir), (std::vector<std::string>{"elsewhere", "link"}));
}

}  // namespace
}  // namespace rig
