#pragma once

#include <functional>
#include <map>

#include "sdoslam/map/map.h"
#include "sdoslam/place/place_index.h"
#include "sdoslam/place/vocabulary.h"

namespace sdoslam {

// Keyframes described as bags of words (static features only), for place recognition: loop
// closing adds to it, relocalization queries it. Not thread-safe: callers hold the map lock.
class KeyFramePlaces {
 public:
  explicit KeyFramePlaces(const Vocabulary* vocabulary) : vocabulary_(vocabulary) {}
  const Vocabulary& vocabulary() const { return *vocabulary_; }
  // The bag of words of a frame's static features (those with label 0): a dynamic feature
  // never votes for a place.
  BowVector Describe(const Frame& frame, FeatureVector* features = nullptr) const;
  // `features`: the keyframe's direct index (Describe's), kept for vocabulary-guided matching.
  void Add(const KeyFrame* keyframe, const BowVector& bow, FeatureVector features = {});
  const BowVector* Find(uint64_t keyframe_id) const { return index_.Find(keyframe_id); }
  // The direct index given to Add, or nullptr (unknown keyframe, or none given).
  const FeatureVector* Features(uint64_t keyframe_id) const;
  // Keyframes that look like `bow` (PlaceIndex::Query), culled ones dropped from the index.
  std::vector<PlaceIndex::Candidate> Query(const Map& map, const BowVector& bow, size_t max_results,
                                           const std::function<bool(uint64_t)>& accept = {});
  size_t size() const { return index_.size(); }

 private:
  const Vocabulary* vocabulary_;
  PlaceIndex index_;  // the bags of words
  std::map<uint64_t, FeatureVector> features_;
};

}  // namespace sdoslam
