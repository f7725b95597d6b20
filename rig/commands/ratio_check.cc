// rig ratio-check --list LIST --out DIR: the paper's Fig. 6 (intensity vs radiance pixel ratios).
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <opencv2/imgcodecs.hpp>

#include "process/hdr/hdr.h"
#include "config/atomic_file.h"
#include "process/io/image_io.h"
#include "process/io/image_io.h"
#include "process/hdr/ratio_check.h"
#include "rig/commands/command.h"

namespace rig {

int RunRatioCheck(int argc, char** argv) {
  CLI::App app{"The paper's Fig. 6 check on one bracket: two pixels' ratio from plain "
               "intensities varies with the exposure time, from radiance it is constant. "
               "Writes DIR/ratio_table.csv and DIR/ratio_plot.png.",
               "rig ratio-check"};
  std::string list, out, response_in, log_level;
  std::vector<std::string> pixels;
  bool linear = false;
  int threads = 2;
  app.add_option("--list", list, "bracket list ('<image> <exposure_s>' per line)")->required();
  app.add_option("--out", out, "output folder")->required();
  app.add_option("--pixel", pixels, "a pixel X,Y (give it twice; default: chosen from the data)")
      ->expected(0, 2);
  app.add_option("--response", response_in, "stored response curve (default: recovered)");
  app.add_flag("--linear", linear, "the frames are linear");
  app.add_option("--threads", threads, "threads")->check(CLI::Range(1, 64));
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;
  RatioCheckOptions o;
  if (!pixels.empty()) {
    if (pixels.size() != 2) {
      std::fprintf(stderr, "rig ratio-check: give --pixel twice (or not at all)\n");
      return 2;
    }
    cv::Point p[2];
    for (int i = 0; i < 2; ++i) {
      if (std::sscanf(pixels[i].c_str(), "%d,%d", &p[i].x, &p[i].y) != 2) {
        std::fprintf(stderr, "rig ratio-check: --pixel '%s' is not X,Y\n", pixels[i].c_str());
        return 2;
      }
    }
    o.a = p[0];
    o.b = p[1];
  }
  auto frames = LoadBracketList(list, threads);
  if (!frames.ok()) return ReportError("ratio-check", frames.error());
  ResponseCurve response;
  if (linear) {
    response = LinearResponse(frames->front().image.depth() == CV_16U ? 65536 : 256);
  } else if (!response_in.empty()) {
    auto r = LoadResponse(response_in);
    if (!r.ok()) return ReportError("ratio-check", r.error());
    response = std::move(r).value();
  } else {
    const Bracket brackets[1] = {*frames};
    ResponseOptions ro;
    ro.threads = threads;
    auto r = RecoverResponse(brackets, ro);
    if (!r.ok()) return ReportError("ratio-check", r.error().Within(list));
    response = std::move(r).value();
  }
  auto result = CheckPixelRatios(*frames, response, o);
  if (!result.ok()) return ReportError("ratio-check", result.error());
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  const std::string csv = out + "/ratio_table.csv", png = out + "/ratio_plot.png";
  if (ec) return ReportError("ratio-check", MakeError(ErrorCode::kIo, out, "cannot create: {}", ec.message()));
  if (Status st = WriteFileAtomic(csv, result->Csv()); !st.ok()) return ReportError("ratio-check", st.error());
  if (Status st = WriteImageFile(png, PlotPixelRatios(*result)); !st.ok())
    return ReportError("ratio-check", st.error());
  std::printf("pixels %d,%d / %d,%d; merged radiance ratio %.4f\n%s", result->a.x, result->a.y,
              result->b.x, result->b.y, result->merged_ratio, result->Csv().c_str());
  std::printf("intensity ratio spread %.3fx, radiance ratio spread %.4fx; wrote %s, %s\n",
              result->intensity_spread, result->radiance_spread, csv.c_str(), png.c_str());
  return 0;
}

}  // namespace rig
