#include "config/did_you_mean.h"

#include <algorithm>

namespace rig {

size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] != b[j - 1])});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string DidYouMean(const std::string& word, const std::vector<std::string>& known) {
  std::string best;
  size_t best_d = 1000;
  for (const auto& k : known) {
    size_t d = EditDistance(word, k);
    if (!word.empty() && (k.rfind(word, 0) == 0 || word.rfind(k, 0) == 0)) d = std::min(d, size_t{2});
    if (d < best_d) best_d = d, best = k;
  }
  if (best_d <= std::max<size_t>(2, word.size() / 3)) return best;
  return "";
}

}  // namespace rig
