#include "sdoslam/place/keyframe_places.h"

namespace sdoslam {

BowVector KeyFramePlaces::Describe(const Frame& frame, FeatureVector* features) const {
  std::vector<int> feature_of_row;
  for (size_t i = 0; i < frame.size(); ++i) {
    if (frame.IsStatic(static_cast<int>(i))) feature_of_row.push_back(static_cast<int>(i));
  }
  cv::Mat rows(static_cast<int>(feature_of_row.size()), frame.descriptors.cols, CV_8U);
  for (size_t r = 0; r < feature_of_row.size(); ++r)
    frame.descriptors.row(feature_of_row[r]).copyTo(rows.row(static_cast<int>(r)));
  BowVector bow;
  if (rows.empty()) return bow;
  FeatureVector by_row;
  vocabulary_->Transform(rows, &bow, features != nullptr ? &by_row : nullptr);
  if (features != nullptr) {
    features->clear();
    for (auto& [node, row_indices] : by_row) {
      std::vector<int>& out = (*features)[node];
      for (int r : row_indices) out.push_back(feature_of_row[static_cast<size_t>(r)]);
    }
  }
  return bow;
}

void KeyFramePlaces::Add(const KeyFrame* keyframe, const BowVector& bow, FeatureVector features) {
  index_.Add(keyframe->id, bow);
  if (features.empty()) {
    features_.erase(keyframe->id);
  } else {
    features_[keyframe->id] = std::move(features);
  }
}

const FeatureVector* KeyFramePlaces::Features(uint64_t keyframe_id) const {
  const auto it = features_.find(keyframe_id);
  return it == features_.end() ? nullptr : &it->second;
}

std::vector<PlaceIndex::Candidate> KeyFramePlaces::Query(
    const Map& map, const BowVector& bow, size_t max_results,
    const std::function<bool(uint64_t)>& accept) {
  // Culled keyframes leave the index when a query meets them: culling happens in local mapping,
  // which does not know of places.
  std::vector<uint64_t> culled;
  auto candidates = index_.Query(bow, max_results, [&](uint64_t id) {
    const auto it = map.keyframes().find(id);
    if (it == map.keyframes().end() || it->second->bad) {
      culled.push_back(id);
      return false;
    }
    return !accept || accept(id);
  });
  for (uint64_t id : culled) {
    index_.Erase(id);
    features_.erase(id);
  }
  return candidates;
}

}  // namespace sdoslam
