#include "sdoslam/place/place_index.h"

#include <algorithm>

namespace sdoslam {

void PlaceIndex::Add(uint64_t id, const BowVector& bow) {
  Erase(id);
  for (const auto& [word, weight] : bow) keyframes_of_word_[word].push_back(id);
  bows_.emplace(id, bow);
}

void PlaceIndex::Erase(uint64_t id) {
  const auto it = bows_.find(id);
  if (it == bows_.end()) return;
  for (const auto& [word, weight] : it->second) {
    auto list = keyframes_of_word_.find(word);
    if (list == keyframes_of_word_.end()) continue;
    auto& ids = list->second;
    ids.erase(std::remove(ids.begin(), ids.end(), id), ids.end());
    if (ids.empty()) keyframes_of_word_.erase(list);
  }
  bows_.erase(it);
}

std::vector<PlaceIndex::Candidate> PlaceIndex::Query(
    const BowVector& bow, size_t max_results, const std::function<bool(uint64_t)>& accept) const {
  // Words in common per keyframe; -1 marks a keyframe `accept` turned down.
  std::unordered_map<uint64_t, int> common;
  for (const auto& [word, weight] : bow) {
    const auto list = keyframes_of_word_.find(word);
    if (list == keyframes_of_word_.end()) continue;
    for (uint64_t id : list->second) {
      auto [it, inserted] = common.try_emplace(id, 0);
      if (inserted && accept && !accept(id)) it->second = -1;
      if (it->second >= 0) ++it->second;
    }
  }
  int most = 0;
  for (const auto& [id, count] : common) most = std::max(most, count);
  std::vector<Candidate> candidates;
  if (most == 0) return candidates;
  for (const auto& [id, count] : common) {
    // count >= 0.8 most, in integers.
    if (count > 0 && 5 * count >= 4 * most)
      candidates.push_back({id, count, Vocabulary::Score(bow, bows_.at(id))});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    if (a.score != b.score) return a.score > b.score;
    return a.id < b.id;
  });
  if (candidates.size() > max_results) candidates.resize(max_results);
  return candidates;
}

}  // namespace sdoslam
