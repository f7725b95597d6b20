// rig evaluate: speed against accuracy, on the same data, for every processing choice — the
// reflectance models (basis, fit method, order), the HDR methods (ours, OpenCV's Debevec and
// Robertson) — with charts, the Pareto front, the automatic choice, scenes of growing
// complexity and the stability of each method where methods fail. The work is
// sim/evaluation.h; this file parses the options and prints.
#include <cstdio>

#include <filesystem>

#include "config/console.h"
#include "process/evaluate/rti_loo.h"
#include "process/model/any/rti_fit.h"
#include "rig/commands/command.h"
#include "sim/evaluation.h"

namespace rig {

int RunEvaluate(int argc, char** argv) {
  CLI::App app{"Speed against accuracy for every processing choice, on the same data: every "
               "reflectance model (basis, fit method, order) and HDR method (ours, OpenCV's "
               "Debevec and Robertson); tables (CSV, Markdown), charts (PNG) with the Pareto "
               "front and the automatic choice, scenes of growing complexity, and stability "
               "where methods fail. A report in DIR/report.md.",
               "rig evaluate"};
  EvaluationRequest request;
  std::string session_dir, out_dir, hdr_dir = request.hdr_images.string(), level;
  app.add_option("SESSION", session_dir, "a session with radiance maps (truth used when simulated)");
  app.add_flag("--dry-run", request.dry_run, "evaluate freshly simulated sessions (config's [sim], every scene)");
  app.add_option("--config", request.config_path, "configuration of the simulated sessions (with --dry-run; default: the "
                 "built-in config/sim.toml)");
  app.add_option("--width", request.width, "simulated image width (default 160)")->check(CLI::Range(16, 4096));
  app.add_option("--height", request.height, "simulated image height (default 120)")->check(CLI::Range(16, 4096));
  app.add_option("--hdr-images", hdr_dir, "folder of real HDR images (.exr, .hdr) used as HDR truth (default: none, the synthetic "
                 "radiance image only; docs/data.md names public ones)");
  app.add_flag("--quick", request.quick, "fewer scenes and HDR trials (for tests)");
  app.add_option("--timing-runs", request.timing_runs,
                 "time every fit, render and HDR merge this many times and chart the median "
                 "(default 3; 1 is faster, its chart moves with the machine's load)")
      ->check(CLI::Range(1, 50));
  std::string lp;
  int lp_every = 1;
  app.add_option("--lp", lp, "a multi-light capture (.lp): every model family by leave-one-out "
                             "(refitting without each image), PSNR against bytes and fit time");
  app.add_option("--lp-every", lp_every, "with --lp: hold out every n-th image only")
      ->check(CLI::Range(1, 1000));
  app.add_option("--out", out_dir, "report folder (created; refused if it holds a report)")->required();
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;
  if (!lp.empty()) {
    if (request.dry_run || !session_dir.empty()) {
      return ReportError("evaluate", MakeError(ErrorCode::kInvalidInput, "--lp",
                                               "give --lp alone (not with SESSION or --dry-run)"));
    }
    const std::string md = (std::filesystem::path(out_dir) / "rti-loo.md").string();
    if (std::filesystem::exists(md)) {
      return ReportError("evaluate", MakeError(ErrorCode::kInvalidInput, md,
                                               "exists; choose another --out (nothing is overwritten)"));
    }
    std::filesystem::create_directories(out_dir);
    auto capture = LoadRtiCapture(lp);
    if (!capture.ok()) return ReportError("evaluate", capture.error());
    RtiLooOptions lo;
    lo.every = lp_every;
    auto rows = WriteRtiLooReport(*capture, lo, md, [](const RtiLooRow& r) {
      ConsoleLine(stdout, RtiLooRowLine(r));
    });
    if (!rows.ok()) return ReportError("evaluate", rows.error());
    std::printf("report: %s\n", md.c_str());
    return 0;
  }
  if (request.dry_run == !session_dir.empty()) {
    return ReportError("evaluate", MakeError(ErrorCode::kInvalidInput, "SESSION",
                                             "give a SESSION or --dry-run (not both)"));
  }
  request.session = session_dir;
  request.hdr_images = hdr_dir;
  request.out = out_dir;
  request.progress = [](const std::string& line) { ConsoleLine(stdout, line); };

  auto report = RunEvaluation(request);
  if (!report.ok()) return ReportError("evaluate", report.error());
  std::printf("%s\nreport: %s\n", report->findings.c_str(), report->report.string().c_str());
  return 0;
}

}  // namespace rig
