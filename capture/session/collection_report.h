// rig collection report's table over a collection folder (docs/collection.md).
#pragma once

#include <filesystem>
#include <string>

#include "config/result.h"

namespace rig {

// Reads every entry of DIR/results (a session or an .lp capture, through its `source` link)
// and writes DIR/report/collection.md, collection.csv, collection.png and index.html;
// *markdown receives the table, *written the report folder. kInvalidInput when DIR has no
// results or no entries.
Status WriteCollectionReport(const std::filesystem::path& dir, std::string* markdown,
                             std::filesystem::path* written);

}  // namespace rig
