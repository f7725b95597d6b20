// rig process SESSION: (re)process stored brackets into radiance maps and the model.
#include <cstdio>
#include <optional>

#include "config/console.h"
#include "config/log.h"
#include "rig/commands/command.h"
#include "capture/daemon/session_model.h"
#include "capture/daemon/processor.h"

namespace rig {

int RunProcess(int argc, char** argv) {
  CLI::App app{"Process a stored session again: merge every complete bracket into hdr/<pose>.exr "
               "(through the session's response curve, recovered once into calib/), then fit the "
               "reflectance model into model/model.exr. Radiance maps newer than their frames "
               "and the response are kept unless --force.",
               "rig process"};
  std::string dir, level;
  bool force = false, hdr_only = false, new_response = false;
  app.add_option("SESSION", dir, "session folder")->required();
  app.add_flag("--force", force, "merge every pose again, even up-to-date ones");
  app.add_flag("--new-response", new_response, "recover the response curve again (implies --force)");
  app.add_flag("--hdr-only", hdr_only, "radiance maps only, no model");
  AddLogLevelOption(app, &level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(level)) return *rc;

  auto session = Session::OpenExisting(dir);
  if (!session.ok()) return ReportError("process", session.error());
  auto jobs = CompleteBrackets(*session);
  if (!jobs.ok()) return ReportError("process", jobs.error());
  if (jobs->empty()) return ReportError("process", MakeError(ErrorCode::kInvalidInput, dir, "no complete bracket to process"));
  if (new_response) {
    std::error_code ec;
    fs::path r = session->layout().calib() / "response.csv";
    if (fs::exists(r)) {
      // Never lose a result: the old curve is kept beside the new one, under a free name.
      fs::path keep = session->layout().calib() / "response.previous.csv";
      for (int i = 2; fs::exists(keep); ++i)
        keep = session->layout().calib() / fmt::format("response.previous-{}.csv", i);
      fs::rename(r, keep, ec);
      if (ec) return ReportError("process", MakeError(ErrorCode::kIo, r.string(), "cannot keep the old response as {}: {}", keep.string(), ec.message()));
    }
    force = true;
  }
  Config config = session->config();
  HdrStage stage(session->layout(), config);
  // Every map (merged now or up to date) kept in memory for the model: no map read back.
  MapStore maps(config.process.hdr_pixel_type == "half" ? ExrPixelType::kHalf : ExrPixelType::kFloat,
                jobs->size(), MapStore::DefaultMaxBytes());
  if (!hdr_only) {
    PlanSessionGram(maps, config);
    stage.set_map_store(&maps);
  }
  stage.set_skip_up_to_date(!force);
  std::optional<ProgressTask> task(std::in_place, "radiance maps", static_cast<int64_t>(jobs->size()));
  stage.set_on_pose([&](const std::string& pose) { task->Advance(1, "pose " + pose); });
  for (auto& job : *jobs) stage.Add(std::move(job));
  stage.Flush();
  stage.set_on_pose(nullptr);
  task.reset();
  const ProcessingSummary& s = stage.summary();
  std::printf("radiance maps: %d merged, %d up to date, %zu failed (response %s; decode %.2f s, "
              "response %.2f s, merge %.2f s, write %.2f s)\n",
              s.merged, s.skipped_up_to_date, s.failed.size(), s.response_id.c_str(), s.decode_s,
              s.recover_s, s.merge_s, s.write_s);
  for (const auto& [pose, err] : s.failed) std::fprintf(stderr, "rig process: pose %s: %s\n", pose.c_str(), err.c_str());
  int rc = s.failed.empty() ? 0 : 1;
  if (!hdr_only) {
    Status fit = FitSessionModel(*session, &maps);
    if (!fit.ok()) rc = ReportError("process", fit.error()) == 2 ? 2 : 1;
  }
  return rc;
}

}  // namespace rig
