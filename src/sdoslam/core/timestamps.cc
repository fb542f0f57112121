#include "sdoslam/core/timestamps.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

namespace sdoslam {

std::vector<std::pair<size_t, size_t>> AssociateTimestamps(const std::vector<double>& first,
                                                           const std::vector<double>& second,
                                                           double max_difference, double offset) {
  // Candidates are found through a sorted copy of `second`, so the cost is
  // O(n log n + candidates) instead of the reference tool's O(n·m).
  std::vector<size_t> order(second.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return second[a] < second[b]; });
  std::vector<double> sorted(second.size());
  for (size_t k = 0; k < order.size(); ++k) sorted[k] = second[order[k]] + offset;

  std::vector<std::tuple<double, size_t, size_t>> candidates;
  for (size_t i = 0; i < first.size(); ++i) {
    auto it = std::lower_bound(sorted.begin(), sorted.end(), first[i] - max_difference);
    for (; it != sorted.end() && *it < first[i] + max_difference; ++it) {
      const double difference = std::abs(first[i] - *it);
      if (difference < max_difference) {
        candidates.emplace_back(difference, i, order[static_cast<size_t>(it - sorted.begin())]);
      }
    }
  }
  std::sort(candidates.begin(), candidates.end());

  std::vector<bool> first_used(first.size(), false), second_used(second.size(), false);
  std::vector<std::pair<size_t, size_t>> matches;
  for (const auto& [difference, i, j] : candidates) {
    if (first_used[i] || second_used[j]) continue;
    first_used[i] = second_used[j] = true;
    matches.emplace_back(i, j);
  }
  std::sort(matches.begin(), matches.end());
  return matches;
}

}  // namespace sdoslam
