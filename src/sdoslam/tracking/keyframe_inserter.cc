#include "sdoslam/tracking/keyframe_inserter.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace sdoslam {

int ReferenceMatches(const Map& map, const KeyFrame& reference) {
  const size_t keyframes = map.GoodKeyFrames();
  const int min_observations = keyframes == 1 ? 1 : keyframes == 2 ? 2 : 3;
  return reference.TrackedPoints(min_observations);
}

ClosePoints CountClosePoints(const Frame& frame) {
  ClosePoints close;
  for (size_t i = 0; i < frame.size(); ++i) {
    if (!frame.IsStaticWithDepth(static_cast<int>(i)) ||
        frame.depth[i] > frame.geometry->close_depth)
      continue;
    if (frame.map_points[i] != nullptr && !frame.outlier[i]) {
      ++close.tracked;
    } else {
      ++close.untracked;
    }
  }
  return close;
}

bool NeedKeyFrame(const TrackerOptions& options, const Frame& frame,
                  const KeyFrameDecisionInput& input) {
  const int inliers = input.inliers;
  const int reference_matches = input.reference_matches;
  const ClosePoints close = CountClosePoints(frame);
  const bool need_close =
      close.tracked < options.min_close_points && close.untracked > options.close_points_to_create;
  const bool long_since =
      frame.index >=
      input.last_keyframe_frame + static_cast<size_t>(options.max_frames_between_keyframes);
  const bool few_inliers = inliers < 0.25 * reference_matches;
  const bool weak = few_inliers || need_close;
  const bool c2 =
      (inliers < options.reference_ratio * reference_matches || need_close) && inliers > 15;
  const bool too_soon = frame.index < input.last_keyframe_frame +
                                          static_cast<size_t>(options.min_frames_between_keyframes);
  // The map's second keyframe is not held back: ORB-SLAM2 makes it the frame after the first,
  // and the real clip's frames (conventional, --sequential) keep 3.3 mm with it there against
  // 3.9 a frame later.
  if (too_soon && !few_inliers && input.good_keyframes >= 2) return false;
  return (long_since || input.mapping_idle || weak) && c2;
}

KeyFrame* CreateKeyFrame(Map* map, const TrackerOptions& options, Frame& frame) {
  KeyFrame* kf = map->AddKeyFrame(frame);
  // New close points from depth, nearest first; at least min_close_points of them.
  std::vector<std::pair<float, int>> by_depth;
  for (size_t i = 0; i < kf->frame.size(); ++i) {
    const int feature = static_cast<int>(i);
    if (kf->frame.MakesPoints(feature) && kf->frame.HasDepth(feature))
      by_depth.emplace_back(kf->frame.depth[i], feature);
  }
  std::sort(by_depth.begin(), by_depth.end());
  int count = 0;
  for (const auto& [depth, i] : by_depth) {
    MapPoint* existing = kf->frame.map_points[static_cast<size_t>(i)];
    if (existing == nullptr || existing->bad) {
      MapPoint* p = map->AddMapPoint(kf->frame.UnprojectWorld(i), kf);
      map->AddObservation(p, kf, i);
      p->UpdateFromObservations();
    }
    if (++count > options.min_close_points && depth > kf->frame.geometry->close_depth) break;
  }
  return kf;
}

}  // namespace sdoslam
