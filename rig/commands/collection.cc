// rig collection init DIR --root ROOT: a Snakemake collection (config.yaml + a Snakefile that
// includes the workflow installed with rig, share/rig/Snakefile); rig collection report DIR:
// one table over every session and .lp capture of the collection, read from what the
// workflow's steps wrote (model reports, evaluation tables, logs, journals, benchmarks).
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "capture/session/collection_report.h"
#include "capture/session/session_store.h"
#include "config/did_you_mean.h"
#include "rig/commands/command.h"

namespace rig {
namespace {

namespace fs = std::filesystem;

// The running executable (/proc/self/exe), for config.yaml and for finding share/rig.
fs::path SelfExe() {
  std::error_code ec;
  fs::path p = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path("rig") : p;
}

// The rig the jobs run, for config.yaml: "rig" when the first rig on $PATH is this executable
// (an installed rig: the collection keeps working when rig is upgraded or moved with PATH),
// else this executable's absolute path (a build tree's rig, which PATH does not find).
std::string RigForJobs() {
  const fs::path self = SelfExe();
  const char* path = std::getenv("PATH");
  std::string dirs = path ? path : "";
  for (size_t start = 0; start <= dirs.size();) {
    const size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::string dir = dirs.substr(start, end - start);
    start = end + 1;
    if (dir.empty()) continue;
    std::error_code ec;
    const fs::path candidate = fs::path(dir) / "rig";
    if (!fs::is_regular_file(candidate, ec) || access(candidate.c_str(), X_OK) != 0) continue;
    return fs::equivalent(candidate, self, ec) ? "rig" : self.string();
  }
  return self.string();
}

// share/rig beside the executable: <prefix>/bin/rig -> <prefix>/share/rig once installed,
// build/rig/rig -> build/share/rig in a build tree; $RIG_SHARE_DIR first when set.
Result<fs::path> ShareDir() {
  std::vector<fs::path> tried;
  if (const char* env = std::getenv("RIG_SHARE_DIR"); env && *env) tried.emplace_back(env);
  tried.push_back(SelfExe().parent_path().parent_path() / "share" / "rig");
  for (const auto& d : tried) {
    std::error_code ec;
    if (fs::is_regular_file(d / "Snakefile", ec)) return fs::weakly_canonical(d, ec);
  }
  return MakeError(ErrorCode::kNotFound, (tried.back() / "Snakefile").string(),
                   "the collection workflow is not installed here (set RIG_SHARE_DIR to the "
                   "folder holding share/rig/Snakefile)");
}

std::string YamlQuote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string YamlList(const std::vector<std::string>& v) {
  std::string out = "[";
  for (size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + YamlQuote(v[i]);
  return out + "]";
}

int RunInit(int argc, char** argv) {
  CLI::App app{"Write a collection folder: DIR/config.yaml (the root to search, the export "
               "formats, per-job threads and memory), DIR/Snakefile, and a copy of the workflow "
               "installed with rig (share/rig/Snakefile -> DIR/workflow/, its local and Slurm "
               "profiles -> DIR/profiles/). Then run Snakemake in DIR. "
               "Nothing else is written; existing files are never replaced.",
               "rig collection init"};
  std::string dir, root, level;
  std::vector<std::string> formats = {"relight"}, lp_fit_args, eval_args;
  bool no_eval_sessions = false, no_eval_lp = false;
  int lp_every = 12;
  app.add_option("DIR", dir, "the collection folder (created)")->required();
  app.add_option("--root", root, "folder searched for sessions (session.toml) and .lp captures")
      ->required();
  app.add_option("--formats", formats, "export formats: relight, ptm, rti (default relight)")
      ->check(CLI::IsMember({"relight", "ptm", "rti"}))
      ->delimiter(',');
  app.add_option("--lp-fit-arg", lp_fit_args,
                 "an argument added to every 'rig fit --lp' (repeat; e.g. --lp-fit-arg=--downsample "
                 "--lp-fit-arg=2)")
      ->allow_extra_args(false);
  app.add_option("--session-evaluate-arg", eval_args,
                 "an argument added to every 'rig evaluate SESSION' (repeat; e.g. "
                 "--session-evaluate-arg=--quick)")
      ->allow_extra_args(false);
  app.add_flag("--no-evaluate-sessions", no_eval_sessions, "no 'rig evaluate' of sessions");
  app.add_flag("--no-evaluate-lp", no_eval_lp, "no 'rig evaluate --lp' of .lp captures");
  app.add_option("--lp-every", lp_every, "rig evaluate --lp: hold out every n-th image (default 12)")
      ->check(CLI::Range(1, 1000));
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;

  auto share = ShareDir();
  if (!share.ok()) return ReportError("collection", share.error());
  std::error_code ec;
  if (!fs::is_directory(root, ec)) {
    return ReportError("collection", MakeError(ErrorCode::kInvalidInput, root, "--root: no such folder"));
  }
  const fs::path d(dir), cfg = d / "config.yaml", snakefile = d / "Snakefile";
  // The workflow and its profiles are copied into the collection (workflow/, profiles/): it
  // keeps working when the build folder that made it moves or is removed, and reruns with the
  // workflow it started with.
  const std::vector<std::pair<fs::path, fs::path>> copies = {
      {*share / "Snakefile", d / "workflow" / "Snakefile"},
      {*share / "local" / "config.yaml", d / "profiles" / "local" / "config.yaml"},
      {*share / "slurm" / "config.yaml", d / "profiles" / "slurm" / "config.yaml"},
      {*share / "slurm" / "status.py", d / "profiles" / "slurm" / "status.py"}};
  for (const auto& p : {cfg, snakefile, copies[0].second, copies[1].second, copies[2].second,
                        copies[3].second}) {
    if (fs::exists(p, ec)) {
      return ReportError("collection", MakeError(ErrorCode::kInvalidInput, p.string(),
                                                 "exists; nothing is overwritten"));
    }
  }
  fs::create_directories(d, ec);
  if (ec) return ReportError("collection", MakeError(ErrorCode::kIo, dir, "cannot create: {}", ec.message()));
  const std::string yaml = fmt::format(
      "# A rig collection (written by `rig collection init`; edit freely: docs/collection.md).\n"
      "root: {}\n"
      "rig: {}\n"
      "formats: {}\n"
      "view: auto               # the page of each entry: rig view if this rig has it, else a render\n"
      "render_light: \"45,20\"    # without rig view: the lamp of results/<name>/render.png\n"
      "lp:\n"
      "  fit_args: {}\n"
      "evaluate:\n"
      "  sessions: {}\n"
      "  session_args: {}\n"
      "  lp: {}\n"
      "  lp_every: {}\n"
      "# Per job: threads, and the least memory (MB) it asks for; larger images ask for more, scaled\n"
      "# from the peaks measured in docs/collection.md. runtime: N (minutes) replaces the scaled time.\n"
      "resources:\n"
      "  merge: {{threads: 2, mem_mb: 300}}\n"
      "  fit: {{threads: 2, mem_mb: 500}}\n"
      "  fit_lp: {{threads: 2, mem_mb: 1000}}\n"
      "  export: {{threads: 1, mem_mb: 300}}\n"
      "  evaluate: {{threads: 1, mem_mb: 500}}\n"
      "  evaluate_lp: {{threads: 2, mem_mb: 2000}}\n"
      "  render: {{mem_mb: 300}}\n"
      "  view: {{mem_mb: 300}}\n",
      YamlQuote(fs::absolute(root).lexically_normal().string()), YamlQuote(RigForJobs()),
      YamlList(formats), YamlList(lp_fit_args), no_eval_sessions ? "false" : "true",
      YamlList(eval_args), no_eval_lp ? "false" : "true", lp_every);
  const std::string sf = fmt::format(
      "# Written by `rig collection init`: the workflow is rig's own ({}), copied here.\n"
      "configfile: \"config.yaml\"\n"
      "include: \"workflow/Snakefile\"\n\n"
      "# The default target (an included file's rules never are): the collection's report.\n"
      "rule collection:\n"
      "    input:\n"
      "        rules.all.input,\n",
      (*share / "Snakefile").string());
  for (const auto& [from, to] : copies) {
    fs::create_directories(to.parent_path(), ec);
    if (ec) return ReportError("collection", MakeError(ErrorCode::kIo, to.parent_path().string(), "cannot create: {}", ec.message()));
    Status st = CopyFileNoFollow(from, to, uint64_t{1} << 20);
    if (!st.ok()) return ReportError("collection", st.error());
  }
  for (const auto& [p, text] : {std::pair{cfg, yaml}, std::pair{snakefile, sf}}) {
    Status st = WriteFileAtomic(p, text, /*overwrite=*/false);
    if (!st.ok()) return ReportError("collection", st.error());
  }
  std::printf("rig collection: wrote %s, %s, %s/workflow/ and %s/profiles/\n", cfg.string().c_str(),
              snakefile.string().c_str(), dir.c_str(), dir.c_str());
  std::printf("  on this machine:  cd %s && snakemake -j2 --keep-going --rerun-incomplete\n", dir.c_str());
  std::printf("  on Slurm:         cd %s && snakemake --profile profiles/slurm\n", dir.c_str());
  std::printf("  the report:       %s/report/index.html (rule 'report', or rig collection report %s)\n",
              dir.c_str(), dir.c_str());
  return 0;
}

// --- the report -------------------------------------------------------------------------

int RunReport(int argc, char** argv) {
  CLI::App app{"One table over a collection: for every session and .lp capture, the model "
               "chosen, bytes per pixel, leave-one-out error, fit time and faults, read from what "
               "the workflow's steps wrote. Writes DIR/report/collection.md, collection.csv, "
               "collection.png (a chart) and index.html (linking each entry's relighting page, "
               "or its render).",
               "rig collection report"};
  std::string dir, level;
  app.add_option("DIR", dir, "the collection folder")->required();
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;
  std::string markdown;
  fs::path written;
  if (Status st = WriteCollectionReport(dir, &markdown, &written); !st.ok())
    return ReportError("collection", st.error());
  std::printf("%s\nrig collection: wrote %s/{collection.md,collection.csv,collection.png,index.html}\n",
              markdown.c_str(), written.string().c_str());
  return 0;
}

}  // namespace

int RunCollection(int argc, char** argv) {
  const std::string sub = argc >= 2 ? argv[1] : "";
  if (sub == "init") return RunInit(argc - 1, argv + 1);
  if (sub == "report") return RunReport(argc - 1, argv + 1);
  const bool help = sub == "--help" || sub == "-h";
  if (!help && !sub.empty()) {
    const std::string hint = DidYouMean(sub, {"init", "report"});
    std::fprintf(stderr, "rig collection: unknown subcommand '%s'%s\n", sub.c_str(),
                 hint.empty() ? "" : (" (did you mean '" + hint + "'?)").c_str());
  }
  std::fprintf(help ? stdout : stderr,
               "Usage: rig collection init DIR --root ROOT [options]   a Snakemake collection folder\n"
               "       rig collection report DIR                        the table over its entries\n"
               "(rig collection <sub> --help for its options; docs/collection.md)\n");
  return help ? 0 : 2;
}

}  // namespace rig
