#pragma once

#include <cstddef>

#include "sdoslam/map/map.h"
#include "sdoslam/tracking/tracking_types.h"

namespace sdoslam {

// What the keyframe decision knows besides the frame.
struct KeyFrameDecisionInput {
  int inliers = 0;                 // the frame's inliers after the local map
  int reference_matches = 0;       // ReferenceMatches of the reference keyframe
  size_t last_keyframe_frame = 0;  // frame index of the last keyframe made
  bool mapping_idle = true;        // local mapping has nothing queued
  size_t good_keyframes = 2;       // keyframes in the map (Map::GoodKeyFrames)
};

// The reference keyframe's map points that enough keyframes see to count in the keyframe
// decision: 1, 2 or 3 keyframes when the map has 1, 2 or more good keyframes.
int ReferenceMatches(const Map& map, const KeyFrame& reference);

// The frame's static features with depth within close_depth: those tracked (an inlier map
// point) and the rest, which a keyframe could make points of.
struct ClosePoints {
  int tracked = 0, untracked = 0;
};
ClosePoints CountClosePoints(const Frame& frame);

// ORB-SLAM2's keyframe decision (RGB-D), for a tracked `frame`: a keyframe when the frame tracks
// more than 15 inliers but fewer than reference_ratio of the reference's matches, or too few
// close points while many untracked close ones could be made (min_close_points,
// close_points_to_create); and, besides, either max_frames_between_keyframes have passed since
// the last keyframe, local mapping is idle, or tracking is weak (below a quarter of the
// reference's matches, or too few close points). Within min_frames_between_keyframes of the last
// keyframe, only the first kind of weak tracking (few inliers) makes one, once the map has two
// keyframes.
bool NeedKeyFrame(const TrackerOptions& options, const Frame& frame,
                  const KeyFrameDecisionInput& input);

// Adds `frame` to the map as a keyframe, with new map points from depth for its static features
// with depth that have no good map point. The features are gone through nearest first: every
// one within close_depth, then farther ones until more than min_close_points have been gone
// through (at least one farther). Returns the keyframe.
KeyFrame* CreateKeyFrame(Map* map, const TrackerOptions& options, Frame& frame);

}  // namespace sdoslam
