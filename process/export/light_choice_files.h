// The chosen lights of a dense capture written out: `rig lights`'s SUB.lp and its report.
#pragma once

#include <string>

#include "config/result.h"
#include "process/model/light_choice.h"

namespace rig {

// `rig lights --lp IN --choose N --out SUB.lp [--report R.md]`: the choice, SUB.lp listing the
// chosen images (paths relative to SUB.lp's folder) in the order chosen, and the report.
// Both files written atomically.
Result<LightChoice> ChooseLightsOfLp(const std::string& lp, const LightChoiceOptions& options,
                                     const std::string& out_lp, const std::string& report);

}  // namespace rig
