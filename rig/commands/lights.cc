// rig lights --lp FILE.lp --choose N --out SUB.lp: next-best-light choice replayed on a dense
// capture (docs/lights.md "Choosing the lights").
#include <cstdio>

#include "process/export/light_choice_files.h"
#include "process/model/light_choice.h"
#include "rig/commands/command.h"

namespace rig {

int RunLights(int argc, char** argv) {
  CLI::App app{"Choose N lights of a dense .lp capture one after another, each from the images "
               "of the lights already chosen (never an image not yet chosen): a spread seed, "
               "then the light whose taking removes the most error that a per-pixel "
               "model of the chosen lights predicts over the lights not chosen. Writes SUB.lp (the chosen images, in the order chosen) and, with "
               "--report, why each was chosen (docs/lights.md).",
               "rig lights"};
  std::string lp, out, report, log_level, criterion = "reduction";
  LightChoiceOptions o;
  app.add_option("--lp", lp, "the dense capture's .lp file")->required();
  app.add_option("--choose", o.count, "N: how many lights to choose (the seed included)")
      ->required()
      ->check(CLI::PositiveNumber);
  app.add_option("--out", out, "the .lp of the chosen lights (image paths relative to it)")
      ->required();
  app.add_option("--report", report, "a Markdown report: every light chosen, in order, and why");
  app.add_option("--seed", o.seed, "lights of the spread seed (default 8; at least 6)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--working-pixels", o.max_working_pixels,
                 "images shrunk (area) to at most this many pixels for the choice (default 65536)")
      ->check(CLI::Range(64, 1 << 30));
  app.add_option("--pixels", o.pixels, "pixels of the working copy in the model (default 16384)")
      ->check(CLI::Range(16, 1 << 30));
  app.add_option("--criterion", criterion,
                 "reduction (default): the light that removes the most predicted error over every "
                 "light not chosen; largest: the light of largest predicted error")
      ->check(CLI::IsMember({"reduction", "largest"}));
  AddLogLevelOption(app, &log_level);
  if (auto rc = ParseCommandLine(app, argc, argv)) return *rc;
  if (auto rc = ApplyLogLevel(log_level)) return *rc;
  o.criterion = criterion == "largest" ? LightCriterion::kLargestError
                                       : LightCriterion::kErrorReduction;
  auto choice = ChooseLightsOfLp(lp, o, out, report);
  if (!choice.ok()) return ReportError("lights", choice.error());
  std::printf("rig lights: wrote %s: %zu lights (seed %d, then by predicted error) from %s, "
              "read %zu images at %dx%d\n",
              out.c_str(), choice->steps.size(), LightChoiceSeedCount(o),
              lp.c_str(), choice->images_read.size(), choice->working_width,
              choice->working_height);
  if (!report.empty()) std::printf("rig lights: wrote %s\n", report.c_str());
  return 0;
}

}  // namespace rig
