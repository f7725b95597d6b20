// `rig collection` through Snakemake (skipped when snakemake is not installed): three
// simulated sessions and the shared .lp capture run with -j2; a changed [process] table
// reruns only that session's fit and what follows it; a new frame reruns the merge; the Slurm
// profile dry-runs; a workflow killed (SIGKILL, then SIGINT) mid-run and started again ends
// with every job's outputs written exactly once and complete.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/support/run_rig.h"
#include "tests/support/session_model.h"

namespace rig {
namespace {

// Whether the built rig has `rig view` (the workflow then writes a page instead of a render).
bool RigHasView() { return testing::RunRig("--help").output.find("  view ") != std::string::npos; }

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunRig;

std::string ReadText(const fs::path& p) { return testing::ReadText(p.string()); }

// A job Snakemake printed: "rule NAME:" ... "jobid: N" ... "wildcards: ..." (one block).
struct Job {
  std::string rule, wildcards;
  int id = -1;
  std::string Key() const { return rule + "[" + wildcards + "]"; }
};

std::vector<Job> Jobs(const std::string& log) {
  std::vector<Job> jobs;
  std::istringstream in(log);
  static const std::regex kRule("^(local)?rule (\\w+):\\s*$"), kId("^\\s+jobid: (\\d+)"),
      kWild("^\\s+wildcards: (.*)$");
  std::smatch m;
  for (std::string line; std::getline(in, line);) {
    if (std::regex_match(line, m, kRule)) jobs.push_back({m[2].str(), "", -1});
    else if (!jobs.empty() && std::regex_search(line, m, kId)) jobs.back().id = std::stoi(m[1]);
    else if (!jobs.empty() && std::regex_search(line, m, kWild)) jobs.back().wildcards = m[1].str();
  }
  return jobs;
}

std::set<std::string> Keys(const std::vector<Job>& jobs) {
  std::set<std::string> k;
  for (const auto& j : jobs) k.insert(j.Key());
  return k;
}

// The jobs of a run that finished ("Finished job N."), by key.
std::multiset<std::string> Finished(const std::string& log) {
  std::map<int, std::string> by_id;
  for (const auto& j : Jobs(log)) by_id[j.id] = j.Key();
  std::multiset<std::string> done;
  static const std::regex kDone("Finished job (\\d+)\\.");
  for (std::sregex_iterator it(log.begin(), log.end(), kDone), end; it != end; ++it)
    done.insert(by_id[std::stoi((*it)[1])]);
  return done;
}

struct SnakeRun {
  int status;
  std::string log;
};

// Runs snakemake in `dir`; with `timeout_s`, killed after that long (status 124).
SnakeRun Snakemake(const fs::path& dir, const std::string& args, int timeout_s = 0) {
  const fs::path log = dir / "snakemake-run.log";
  const std::string limit = timeout_s > 0 ? "timeout -s KILL " + std::to_string(timeout_s) + " " : "";
  const std::string cmd =
      "cd '" + dir.string() + "' && " + limit + "snakemake " + args + " > '" + log.string() + "' 2>&1";
  const int rc = std::system(cmd.c_str());
  return {WIFEXITED(rc) ? WEXITSTATUS(rc) : 128, ReadText(log)};
}

// Starts snakemake in its own process group (so that a signal reaches it and its jobs).
pid_t StartSnakemake(const fs::path& dir, const std::string& args, const fs::path& log) {
  pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);
    const std::string cmd = "cd '" + dir.string() + "' && exec snakemake " + args + " > '" + log.string() + "' 2>&1";
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ::setpgid(pid, pid);
  return pid;
}

// Waits until `ready` holds (polling), at most `seconds`.
template <class F>
bool WaitFor(F ready, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (ready()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

bool AnyFileIn(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir, ec) && fs::directory_iterator(dir, ec) != fs::directory_iterator();
}

class CollectionCommand : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (std::system("command -v snakemake > /dev/null 2>&1") != 0) return;
    dir_ = new fs::path(testing::FreshTempDir("collection_command"));
    // Small sessions: 64x48, 21 poses, 5 exposures.
    const std::string cfg = testing::WriteSimConfig(
        dir_->string(), "[sim]\nwidth = 64\nheight = 48\n[grid]\nh_step_deg = 15\nv_step_deg = 15\n"
                        "[bracket]\ncount = 5\n");
    auto r = RunRig("capture --config " + cfg + " --out " + (*dir_ / "S").string() +
                    " --dry-run --no-progress --no-process");
    ASSERT_EQ(r.status, 0) << r.output;
    fs::remove(*dir_ / "S" / ".lock");
  }
  static void TearDownTestSuite() {
    if (dir_) fs::remove_all(*dir_);
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    if (!dir_) GTEST_SKIP() << "snakemake is not installed";
  }
  // root/<names...> as copies of the captured session (frames only).
  static fs::path Root(const std::string& name, const std::vector<std::string>& sessions) {
    const fs::path root = *dir_ / name;
    for (const auto& s : sessions) {
      fs::create_directories((root / s).parent_path());
      fs::copy(*dir_ / "S", root / s, fs::copy_options::recursive);
    }
    return root;
  }
  static fs::path Init(const std::string& name, const fs::path& root, const std::string& extra) {
    const fs::path c = *dir_ / name;
    auto r = RunRig("collection init " + c.string() + " --root " + root.string() +
                    " --formats relight,ptm --session-evaluate-arg=--quick " + extra);
    EXPECT_EQ(r.status, 0) << r.output;
    EXPECT_THAT(r.output, HasSubstr("snakemake -j2"));
    // The workflow and its profiles are copied in: nothing points into the build tree.
    EXPECT_EQ(testing::ReadText((c / "workflow/Snakefile").string()),
              testing::ReadText(testing::SourceDir() + "/share/rig/Snakefile"));
    EXPECT_EQ(testing::ReadText((c / "profiles/slurm/config.yaml").string()),
              testing::ReadText(testing::SourceDir() + "/share/rig/slurm/config.yaml"));
    EXPECT_EQ(testing::ReadText((c / "profiles/slurm/status.py").string()),
              testing::ReadText(testing::SourceDir() + "/share/rig/slurm/status.py"));
    EXPECT_THAT(testing::ReadText((c / "Snakefile").string()), HasSubstr("include: \"workflow/Snakefile\""));
    return c;
  }
  static fs::path* dir_;
};
fs::path* CollectionCommand::dir_ = nullptr;

TEST_F(CollectionCommand, RerunsOnlyTheStepsOfTheSessionWhoseProcessTableChanged) {
  const fs::path root = Root("root", {"S1", "S2", "deeper/S3"});
  fs::create_directory_symlink(fs::path(testing::SharedDir()) / "data/rti/neuralrti-example",
                               root / "icon");
  const fs::path c = Init("C", root, "--lp-fit-arg=--downsample --lp-fit-arg=4 --no-evaluate-lp");
  // Nothing is overwritten.
  EXPECT_EQ(RunRig("collection init " + c.string() + " --root " + root.string()).status, 2);

  SnakeRun first = Snakemake(c, "-j2");
  ASSERT_EQ(first.status, 0) << first.log;
  const std::set<std::string> all = Keys(Jobs(first.log));
  for (const char* s : {"S1", "S2", "deeper__S3"}) {
    const std::string w = std::string("name=") + s;
    for (const char* rule : {"merge", "fit_session", "evaluate_session"})
      EXPECT_TRUE(all.count(std::string(rule) + "[" + w + "]")) << rule << " " << s << "\n" << first.log;
    // The page: `rig view` where the binary has it, else a render.
    EXPECT_TRUE(all.count("view[" + w + "]") || all.count("render[" + w + "]")) << s << "\n" << first.log;
    EXPECT_TRUE(all.count("export[" + w + ", format=ptm]"));
    EXPECT_TRUE(all.count("export[" + w + ", format=relight]"));
    EXPECT_TRUE(testing::SessionHasModel(root / (std::string(s) == "deeper__S3" ? "deeper/S3" : s)));
  }
  const std::string lp = "name=icon__dirs";
  EXPECT_TRUE(all.count("fit_lp[" + lp + "]")) << first.log;
  EXPECT_TRUE(fs::exists(c / "results/icon__dirs/model/info.json"));
  EXPECT_TRUE(fs::exists(c / "results/S1/export/ptm/model.ptm"));
  EXPECT_TRUE(fs::exists(c / "results/S1/export/relight/info.json"));
  EXPECT_EQ(first.log.find("Error"), std::string::npos) << first.log;

  // The report: one row per entry, parsed from what the steps wrote.
  const std::string csv = ReadText(c / "report/collection.csv");
  EXPECT_THAT(csv, HasSubstr("S1,session,"));
  EXPECT_THAT(csv, HasSubstr("icon__dirs,lp,"));
  // The sessions' model, whichever family their choice took (the default dry run's: PCA).
  EXPECT_THAT(csv, ::testing::AnyOf(HasSubstr("sh rls order"), HasSubstr("pca power")));
  EXPECT_THAT(csv, HasSubstr("pca-bilinear"));
  EXPECT_GT(fs::file_size(c / "report/collection.png"), 1000u);
  EXPECT_THAT(ReadText(c / "report/index.html"),
              HasSubstr(RigHasView() ? "href=\"../results/S2/view/index.html\""
                                     : "href=\"../results/S2/render.png\""));

  // Unchanged: nothing to do, and the stamps are not rewritten.
  const auto stamp_time = fs::last_write_time(c / "results/S2/params.fit");
  SnakeRun again = Snakemake(c, "-j2");
  ASSERT_EQ(again.status, 0) << again.log;
  EXPECT_THAT(again.log, HasSubstr("Nothing to be done")) << again.log;
  EXPECT_EQ(fs::last_write_time(c / "results/S2/params.fit"), stamp_time);

  // A fit key of S2's [process] table changes: its fit and what follows it run, nothing else.
  {
    std::string toml = ReadText(root / "S2/session.toml");
    const std::string from = "order_tolerance = 0.02";
    ASSERT_NE(toml.find(from), std::string::npos);
    toml.replace(toml.find(from), from.size(), "order_tolerance = 0.05");
    std::ofstream(root / "S2/session.toml") << toml;
  }
  SnakeRun changed = Snakemake(c, "-j2");
  ASSERT_EQ(changed.status, 0) << changed.log;
  const std::set<std::string> expected = {
      "fit_session[name=S2]", "export[name=S2, format=ptm]", "export[name=S2, format=relight]",
      "evaluate_session[name=S2]", RigHasView() ? "view[name=S2]" : "render[name=S2]", "report[]",
      "collection[]"};
  EXPECT_EQ(Keys(Jobs(changed.log)), expected) << changed.log;
  EXPECT_EQ(Finished(changed.log).size(), expected.size()) << changed.log;
  EXPECT_THAT(ReadText(c / "results/S2/params.fit"), HasSubstr("0.05"));

  // A new frame (the journal grows; a touch alone is not enough, Snakemake compares the
  // checksum of small inputs): the merge of that session runs again (dry run).
  std::ofstream(root / "deeper/S3/journal.jsonl", std::ios::app) << "{\"event\":\"note\"}\n";
  SnakeRun frame = Snakemake(c, "-n -j2");
  ASSERT_EQ(frame.status, 0) << frame.log;
  const auto frame_jobs = Keys(Jobs(frame.log));
  EXPECT_TRUE(frame_jobs.count("merge[name=deeper__S3]")) << frame.log;
  EXPECT_TRUE(frame_jobs.count("fit_session[name=deeper__S3]")) << frame.log;
  for (const auto& k : frame_jobs) EXPECT_EQ(k.find("S1"), std::string::npos) << k;

  // The Slurm profile, as far as this machine goes: the dry run plans the same jobs.
  SnakeRun slurm = Snakemake(c, "-n --profile profiles/slurm");
  ASSERT_EQ(slurm.status, 0) << slurm.log;
  EXPECT_EQ(Keys(Jobs(slurm.log)), frame_jobs) << slurm.log;
  EXPECT_THAT(slurm.log, HasSubstr("mem_mb=500"));  // the fit job's declared memory
}

// Files named exactly `name` anywhere below `dir` (links not followed).
std::vector<fs::path> FilesNamed(const fs::path& dir, const std::string& name) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec))
    if (it->path().filename() == name) out.push_back(it->path());
  return out;
}

// Session folders whose names would run code if pasted into a shell line ("$(...)",
// backticks, quotes, ';', a newline), and a .lp with comments in such a folder: the workflow
// passes every path quoted, so nothing runs (no PWNED file anywhere), and every entry is
// processed.
TEST_F(CollectionCommand, HostileFolderNamesRunNoCodeAndTheirEntriesAreProcessed) {
  const std::vector<std::string> names = {"a $(touch PWNED)", "b `touch PWNED`",
                                          "c'; touch PWNED; '", "d\"; touch PWNED; \"",
                                          "e\ntouch PWNED\n"};
  const fs::path root = Root("hroot", names);
  // A .lp capture with '#' comments and blank lines, in a hostile folder too: its images
  // (absolute paths to the shared icon) are the workflow's inputs, read as rig reads them.
  const fs::path icon = fs::path(testing::SharedDir()) / "data/rti/neuralrti-example";
  if (!fs::exists(icon / "dirs.lp")) GTEST_SKIP() << icon << " is not here (RIG_SHARED_DIR)";
  const fs::path lpdir = root / "f $(touch PWNED) `touch PWNED`";
  fs::create_directories(lpdir);
  {
    std::istringstream in(ReadText(icon / "dirs.lp"));
    std::ofstream lp(lpdir / "dirs.lp");
    lp << "# written by a dome's software\n\n   # indented comment\n";
    std::string line;
    std::getline(in, line);
    lp << line << "\n";
    int i = 0;
    while (std::getline(in, line)) {
      if (line.empty()) continue;
      lp << (icon / line).string() << "\n";
      if (++i % 20 == 0) lp << "# a comment between images\n";
    }
  }
  const fs::path c = *dir_ / "H";
  auto init = RunRig("collection init " + c.string() + " --root " + root.string() +
                     " --formats relight,ptm --no-evaluate-sessions --no-evaluate-lp "
                     "--lp-fit-arg=--downsample --lp-fit-arg=4");
  ASSERT_EQ(init.status, 0) << init.output;

  SnakeRun run = Snakemake(c, "-j2");
  EXPECT_TRUE(FilesNamed(*dir_, "PWNED").empty()) << FilesNamed(*dir_, "PWNED").front();
  EXPECT_FALSE(fs::exists(c / "PWNED"));
  ASSERT_EQ(run.status, 0) << run.log;
  const std::set<std::string> jobs = Keys(Jobs(run.log));
  for (const auto& n : names) {
    std::string entry = n;
    for (char& ch : entry)
      if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '_' && ch != '-') ch = '_';
    EXPECT_TRUE(jobs.count("fit_session[name=" + entry + "]")) << entry << "\n" << run.log;
    EXPECT_TRUE(testing::SessionHasModel(root / n)) << n;
    EXPECT_TRUE(fs::exists(c / "results" / entry / "export/ptm/model.ptm")) << entry;
    EXPECT_TRUE(fs::exists(c / "results" / entry / "export/relight/info.json")) << entry;
  }
  // The .lp's 72 images were found past its comments, and its model fitted.
  std::string lp_entry;
  for (const auto& k : jobs)
    if (k.starts_with("fit_lp[")) lp_entry = k;
  EXPECT_FALSE(lp_entry.empty()) << run.log;
  bool lp_model = false;
  for (const auto& e : fs::directory_iterator(c / "results"))
    if (e.path().filename().string().starts_with("f_")) lp_model = fs::exists(e.path() / "model/info.json");
  EXPECT_TRUE(lp_model) << run.log;
  EXPECT_THAT(ReadText(c / "report/collection.csv"), HasSubstr(",lp,"));
}

// A root holding link loops (a link to the root itself, a link to a parent): planning visits
// each folder once, warns naming the link, and finishes; the session in it is still planned.
TEST_F(CollectionCommand, LinkLoopsInTheRootAreSkippedWithAWarningAndPlanningEnds) {
  const fs::path root = Root("lroot", {"deep/L1"});
  fs::create_directory_symlink(root, root / "loop");
  fs::create_directory_symlink("..", root / "deep/up");
  const fs::path c = *dir_ / "L";
  auto init = RunRig("collection init " + c.string() + " --root " + root.string() +
                     " --no-evaluate-sessions");
  ASSERT_EQ(init.status, 0) << init.output;
  // Bounded: a walk that followed the loop would be killed after 120 s (status 137).
  SnakeRun plan = Snakemake(c, "-n -j2", 120);
  ASSERT_EQ(plan.status, 0) << plan.log;
  EXPECT_THAT(plan.log, HasSubstr((root / "loop").string() + ": skipped")) << plan.log;
  EXPECT_THAT(plan.log, HasSubstr((root / "deep/up").string() + ": skipped")) << plan.log;
  EXPECT_THAT(plan.log, HasSubstr("link loop"));
  EXPECT_TRUE(Keys(Jobs(plan.log)).count("merge[name=deep__L1]")) << plan.log;
  EXPECT_EQ(Keys(Jobs(plan.log)).count("merge[name=loop__deep__L1]"), 0u) << plan.log;
}

// Snakemake 7.21 writes the collection folder into each cluster job's shell script quoted only
// as Python quotes a string: on Slurm the workflow refuses a folder a shell would split, before any job; the
// same folder runs locally, and a plain one plans on Slurm.
TEST_F(CollectionCommand, OnSlurmAFolderAShellWouldSplitIsRefusedBeforeAnyJob) {
  const fs::path root = Root("sroot", {"S1"});
  for (const std::string name : {"with space", "plain"}) {
    const fs::path c = *dir_ / name;
    auto init = RunRig("collection init '" + c.string() + "' --root " + root.string() +
                       " --no-evaluate-sessions");
    ASSERT_EQ(init.status, 0) << init.output;
    SnakeRun slurm = Snakemake(c, "-n --profile profiles/slurm", 120);
    SnakeRun local = Snakemake(c, "-n -j2", 120);
    EXPECT_EQ(local.status, 0) << local.log;
    if (name == "plain") {
      EXPECT_EQ(slurm.status, 0) << slurm.log;
    } else {
      EXPECT_NE(slurm.status, 0) << slurm.log;
      EXPECT_THAT(slurm.log, HasSubstr("on Slurm the collection folder's path may hold only")) << slurm.log;
      EXPECT_TRUE(Jobs(slurm.log).empty()) << slurm.log;
    }
  }
}

TEST_F(CollectionCommand, KilledAndStartedAgainWritesEveryOutputExactlyOnce) {
  const fs::path root = Root("kroot", {"K1", "K2"});
  const fs::path c = Init("K", root, "");
  std::vector<std::string> logs;
  // SIGKILL to the whole group (snakemake and its rig jobs) while an evaluation runs ...
  {
    const fs::path log = c / "run-kill.log";
    pid_t pid = StartSnakemake(c, "-j2", log);
    EXPECT_TRUE(WaitFor([&] { return AnyFileIn(c / "logs/evaluate"); }, 60)) << ReadText(log);
    ::kill(-pid, SIGKILL);
    int st = 0;
    ::waitpid(pid, &st, 0);
    EXPECT_TRUE(WIFSIGNALED(st));
    logs.push_back(ReadText(log));
  }
  // ... then, started again, SIGINT (Ctrl-C) while a job it started runs ...
  {
    const fs::path log = c / "run-int.log";
    // A SIGKILL leaves Snakemake's lock behind: --unlock removes it (docs/collection.md).
    ASSERT_EQ(Snakemake(c, "--unlock").status, 0);
    pid_t pid = StartSnakemake(c, "-j2 --rerun-incomplete", log);
    EXPECT_TRUE(WaitFor([&] { return ReadText(log).find("jobid:") != std::string::npos; }, 60))
        << ReadText(log);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    ::kill(-pid, SIGINT);
    int st = 0;
    ::waitpid(pid, &st, 0);
    logs.push_back(ReadText(log));
  }
  // ... and started again to the end.
  SnakeRun last = Snakemake(c, "-j2 --rerun-incomplete");
  ASSERT_EQ(last.status, 0) << last.log;
  logs.push_back(last.log);

  // Every job of the workflow finished exactly once over the three runs: nothing written
  // twice, nothing a killed job left behind taken as done.
  // A job can end in the instant the signal arrives: Snakemake has then marked it complete
  // (handle_job_success runs before "Finished job N." is printed), so no later run plans it
  // again. Such a job finished once in the run that started it, unannounced; one a later run
  // plans again did not.
  std::map<std::string, int> done;
  std::set<std::string> planned;
  for (size_t i = 0; i < logs.size(); ++i) {
    const auto finished = Finished(logs[i]);
    for (const auto& k : finished) ++done[k];
    for (const auto& k : Keys(Jobs(logs[i]))) {
      planned.insert(k);
      bool again = false;
      for (size_t j = i + 1; j < logs.size(); ++j) again = again || Keys(Jobs(logs[j])).count(k) > 0;
      if (!finished.count(k) && !again && i + 1 < logs.size()) ++done[k];
    }
  }
  ASSERT_EQ(planned.size(), 14u);  // 2 x (merge, fit, 2 exports, evaluate, render) + report + target
  for (const auto& k : planned) EXPECT_EQ(done[k], 1) << k << "\n" << logs[0] << logs[1] << logs[2];
  // Jobs were killed mid-run (started, never finished, in the first run): run again later.
  std::set<std::string> killed = Keys(Jobs(logs[0]));
  for (const auto& k : Finished(logs[0])) killed.erase(k);
  std::erase_if(killed, [&](const std::string& k) {
    return !Keys(Jobs(logs[1])).count(k) && !Keys(Jobs(logs[2])).count(k);
  });
  EXPECT_FALSE(killed.empty()) << logs[0];
  SnakeRun check = Snakemake(c, "-n -j2");
  EXPECT_THAT(check.log, HasSubstr("Nothing to be done")) << check.log;
  for (const char* s : {"K1", "K2"}) {
    const fs::path e = c / "results" / s;
    EXPECT_THAT(ReadText(e / "evaluate/report.md"), HasSubstr("automatic choice")) << s;
    EXPECT_TRUE(fs::exists(e / "export/ptm/model.ptm")) << s;
    EXPECT_TRUE(fs::exists(e / "export/relight/info.json")) << s;
    EXPECT_TRUE(testing::SessionHasModel(root / s)) << s;
    std::istringstream maps(ReadText(e / "hdr.txt"));
    int n = 0;
    for (std::string line; std::getline(maps, line);) n += line.ends_with(".exr");
    EXPECT_EQ(n, 21) << s;
  }
  EXPECT_THAT(ReadText(c / "report/collection.csv"), HasSubstr("K2,session,"));
}

}  // namespace
}  // namespace rig
