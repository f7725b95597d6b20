// `rig lights`: the next-best-light choice of an .lp capture, written as an .lp and a report.
#include "process/export/light_choice_files.h"

#include <filesystem>
#include <vector>

#include "config/atomic_file.h"
#include "process/export/relight_files.h"

namespace rig {

Result<LightChoice> ChooseLightsOfLp(const std::string& lp, const LightChoiceOptions& options,
                                     const std::string& out_lp, const std::string& report) {
  RIG_ASSIGN_OR_RETURN(std::vector<LpEntry> entries, ReadLp(lp));
  RIG_ASSIGN_OR_RETURN(LightChoice choice, ChooseLpLights(entries, options));
  namespace fs = std::filesystem;
  const fs::path folder = fs::absolute(fs::path(out_lp)).parent_path();
  std::vector<std::string> images;
  std::vector<Vec3> dirs;
  for (int l : choice.Chosen()) {
    images.push_back(fs::absolute(entries[l].image).lexically_relative(folder).string());
    dirs.push_back(entries[l].direction);
  }
  RIG_TRY(WriteLp(out_lp, images, dirs));
  if (!report.empty()) RIG_TRY(WriteFileAtomic(report, LightChoiceMarkdown(entries, choice, options)));
  return choice;
}

}  // namespace rig
