#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "sdoslam/place/vocabulary.h"

namespace sdoslam {

// Inverted index over keyframes: word -> the keyframes whose bag of words holds it. ORB-SLAM's
// KeyFrameDatabase without the map-specific parts (covisibility, accumulated scores): those
// belong to the caller, through `accept` and what it does with the candidates.
// Not thread-safe: one writer, or a lock around it.
class PlaceIndex {
 public:
  // Adds keyframe `id` with its bag of words; an id already present is replaced.
  void Add(uint64_t id, const BowVector& bow);
  void Erase(uint64_t id);  // no-op for unknown ids
  size_t size() const { return bows_.size(); }
  bool Contains(uint64_t id) const { return bows_.count(id) > 0; }
  // The bag of words of keyframe `id`, or nullptr when it is not in the index.
  const BowVector* Find(uint64_t id) const {
    const auto it = bows_.find(id);
    return it == bows_.end() ? nullptr : &it->second;
  }

  struct Candidate {
    uint64_t id;
    int common_words;
    double score;  // Vocabulary::Score against the query
  };
  // Keyframes sharing words with `bow` and accepted by `accept` (empty = all; called once per
  // keyframe sharing a word, before counting, so the rule below is relative to the accepted
  // ones, as ORB-SLAM leaves out the connected keyframes before it counts), of those the ones
  // with at least 0.8 x the largest number of words in common (ORB-SLAM's rule), scored, best
  // first (equal scores: smaller id first), at most `max_results`.
  std::vector<Candidate> Query(const BowVector& bow, size_t max_results,
                               const std::function<bool(uint64_t)>& accept = {}) const;

 private:
  std::unordered_map<WordId, std::vector<uint64_t>> keyframes_of_word_;
  std::unordered_map<uint64_t, BowVector> bows_;
};

}  // namespace sdoslam
