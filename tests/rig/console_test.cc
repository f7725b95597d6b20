// The console: progress bars with an ETA on a terminal that log lines never tear, none when
// piped; commands that find their defaults wherever they run; a folder given as a config.
#include <pty.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "config/console.h"
#include "tests/support/run_rig.h"

namespace rig {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using testing::RunRig;

struct Ran {
  int status = -1;
  std::string output;
};

// Runs the rig binary in `cwd` with stdout and stderr on a pseudo-terminal.
Ran RunRigOnTerminal(const std::vector<std::string>& args, const std::string& cwd = ".") {
  const char* bin = std::getenv("RIG_BINARY");
  EXPECT_NE(bin, nullptr);
  Ran r;
  if (!bin) return r;
  int master = -1;
  winsize ws{};
  ws.ws_col = 160;
  ws.ws_row = 40;
  pid_t pid = forkpty(&master, nullptr, nullptr, &ws);
  if (pid == 0) {
    if (chdir(cwd.c_str()) != 0) _exit(126);
    std::vector<std::string> all = {bin};
    all.insert(all.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : all) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(bin, argv.data());
    _exit(127);
  }
  char buf[4096];
  for (;;) {
    ssize_t n = read(master, buf, sizeof buf);
    if (n <= 0) break;  // EIO once the child has exited and closed the terminal
    r.output.append(buf, static_cast<size_t>(n));
  }
  close(master);
  int st = 0;
  waitpid(pid, &st, 0);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

std::string SmallSession(const std::string& dir) {
  const std::string cfg = testing::WriteSimConfig(
      dir, "[sim]\nwidth = 96\nheight = 72\n[bracket]\ncount = 3\n");
  auto r = RunRig("capture --config " + cfg + " --out " + dir + "/S --no-process --no-progress");
  EXPECT_EQ(r.status, 0) << r.output;
  return dir + "/S";
}

TEST(Console, PipedOutputOfLongStepsHasNoProgressEscapeCodes) {
  const std::string dir = testing::FreshTempDir("console_piped");
  const std::string s = SmallSession(dir);
  auto r = RunRig("process " + s + " --force --log-level debug");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("radiance maps: 40 merged"));
  EXPECT_THAT(r.output, Not(HasSubstr("\r")));
  EXPECT_THAT(r.output, Not(HasSubstr("\033[")));
  EXPECT_THAT(r.output, Not(HasSubstr("ETA")));
  // Off a terminal, progress is a plain line every few seconds ($RIG_PROGRESS_EVERY_S; here
  // every 0.05 s, so the 40 maps and the fit take long enough to print some).
  setenv("RIG_PROGRESS_EVERY_S", "0.05", 1);
  auto lines = RunRig("process " + s + " --force");
  setenv("RIG_PROGRESS_EVERY_S", "100000", 1);  // as tests/test_env.cc sets it
  ASSERT_EQ(lines.status, 0) << lines.output;
  EXPECT_THAT(lines.output, HasSubstr("progress: radiance maps "));
  EXPECT_THAT(lines.output, HasSubstr(" elapsed, "));
  EXPECT_THAT(lines.output, Not(HasSubstr("\r")));
  EXPECT_THAT(lines.output, Not(HasSubstr("\033[")));
  std::filesystem::remove_all(dir);
}

// On a terminal: bars with an ETA are drawn, and every line that ends in a newline (a log
// line, a printed result) starts on an erased line, never after a bar's text.
TEST(Console, OnATerminalBarsHaveAnEtaAndLogLinesNeverLandOnThem) {
  const std::string dir = testing::FreshTempDir("console_tty");
  const std::string s = SmallSession(dir);
  Ran r = RunRigOnTerminal({"process", s, "--force", "--log-level", "debug"});
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("radiance maps ["));
  EXPECT_THAT(r.output, HasSubstr("fitting the model ["));
  EXPECT_THAT(r.output, HasSubstr("ETA "));
  std::istringstream lines(r.output);
  std::string line;
  int logged = 0;
  while (std::getline(lines, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();  // the terminal's CR LF
    // What the terminal shows of this line: the text after the last carriage return.
    const size_t cr = line.rfind('\r');
    const std::string visible = cr == std::string::npos ? line : line.substr(cr + 1);
    EXPECT_THAT(visible, Not(HasSubstr("ETA"))) << "a bar torn by a line: '" << line << "'";
    if (visible.find("process") != std::string::npos) ++logged;
  }
  EXPECT_GT(logged, 2);
  std::filesystem::remove_all(dir);
}

TEST(Console, ATaskComputesItsEtaFromTheWorkDoneInThisRun) {
  ProgressTask t("work", 10, 4);  // 4 done before: not counted for the rate
  EXPECT_THAT(t.Line(), HasSubstr("4/10"));
  EXPECT_THAT(t.Line(), HasSubstr("ETA --:--"));
  t.Advance(2, "step");
  EXPECT_THAT(t.Line(), HasSubstr("60%"));
  EXPECT_THAT(t.Line(), HasSubstr("step"));
  EXPECT_THAT(t.Line(), Not(HasSubstr("ETA --:--")));
}

TEST(CheckConfig, AFolderIsReportedAsAFolderNotAsMissingTables) {
  const std::string dir = testing::FreshTempDir("check_config_dir");
  auto r = RunRig("check-config " + dir);
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("is a directory"));
  EXPECT_THAT(r.output, Not(HasSubstr("missing")));
  EXPECT_THAT(r.output, HasSubstr("1 error"));
  // A file that is not there is named as missing, for check-config and for capture alike.
  auto missing = RunRig("check-config " + dir + "/nothere.toml");
  EXPECT_EQ(missing.status, 2);
  EXPECT_THAT(missing.output, HasSubstr("nothere.toml: (file): no such file"));
  auto capture = RunRig("capture --config " + dir + "/nothere.toml --out " + dir + "/s --dry-run");
  EXPECT_EQ(capture.status, 2);
  EXPECT_THAT(capture.output, HasSubstr("no such file"));
  EXPECT_FALSE(std::filesystem::exists(dir + "/s"));
  std::filesystem::remove_all(dir);
}

// A mistyped command or option is answered with the one meant, and a non-zero exit; a word
// close to nothing gets the list (commands) or the plain refusal (options).
TEST(CommandLine, MistypedCommandsAndOptionsAreAnsweredWithTheOneMeant) {
  auto cmd = RunRig("captur");
  EXPECT_EQ(cmd.status, 2);
  EXPECT_THAT(cmd.output, HasSubstr("unknown command 'captur' (did you mean 'capture'?)"));
  auto far = RunRig("zzzzzzzzzz");
  EXPECT_EQ(far.status, 2);
  EXPECT_THAT(far.output, Not(HasSubstr("did you mean")));
  EXPECT_THAT(far.output, HasSubstr("Acquisition:"));
  auto opt = RunRig("render some-session --ligth 45,20 --out x.png");
  EXPECT_EQ(opt.status, 2);
  EXPECT_THAT(opt.output, HasSubstr("unknown option '--ligth' (did you mean '--light'?)"));
  auto eq = RunRig("render some-session --light 45,20 --tonemapp=ward --out x.png");
  EXPECT_EQ(eq.status, 2);
  EXPECT_THAT(eq.output, HasSubstr("unknown option '--tonemapp' (did you mean '--tonemap'?)"));
  // A subcommand's options count as known (collection init's).
  auto sub = RunRig("collection init --help");
  EXPECT_EQ(sub.status, 0) << sub.output;
  // A mistyped subcommand, and a mistyped option of a subcommand named with its command.
  auto inti = RunRig("collection inti some-dir");
  EXPECT_EQ(inti.status, 2);
  EXPECT_THAT(inti.output, HasSubstr("unknown subcommand 'inti' (did you mean 'init'?)"));
  auto subopt = RunRig("collection init some-dir --rot /tmp");
  EXPECT_EQ(subopt.status, 2);
  EXPECT_THAT(subopt.output, HasSubstr("rig collection init: unknown option '--rot' (did you mean '--root'?)"));
}

// rig --help lists every command once, under its group, names aligned in one column.
TEST(CommandLine, HelpGroupsEveryCommandOnceWithAlignedSummaries) {
  auto help = RunRig("--help");
  ASSERT_EQ(help.status, 0);
  for (const char* group : {"Acquisition:", "Processing:", "Viewing and export:", "Bring-up", "Service:"})
    EXPECT_THAT(help.output, HasSubstr(group));
  std::istringstream lines(help.output);
  std::string line;
  size_t column = 0;
  int commands = 0;
  while (std::getline(lines, line)) {
    if (line.rfind("  ", 0) != 0 || line.rfind("  --", 0) == 0) continue;
    const size_t name_end = line.find(' ', 2);
    const size_t summary = line.find_first_not_of(' ', name_end);
    ASSERT_NE(summary, std::string::npos) << line;
    if (column == 0) column = summary;
    EXPECT_EQ(summary, column) << line;
    ++commands;
  }
  EXPECT_GE(commands, 20);
}

}  // namespace
}  // namespace rig
