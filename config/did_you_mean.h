// "Did you mean": the closest of the known words to one a user typed (a config key, a command,
// an option), for error messages that say what was meant.
#pragma once

#include <string>
#include <vector>

namespace rig {

// Levenshtein distance between two words.
size_t EditDistance(const std::string& a, const std::string& b);

// The known word closest to `word`, or "" when none is close: within an edit distance of
// max(2, a third of the word), a prefix of one another counting as distance 2
// ("exposure_time" for "exposure_times_s").
std::string DidYouMean(const std::string& word, const std::vector<std::string>& known);

}  // namespace rig
