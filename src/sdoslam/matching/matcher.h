#pragma once

#include <Eigen/Geometry>
#include <map>
#include <vector>

#include "sdoslam/map/map.h"

namespace sdoslam {

// Descriptor thresholds of ORB-SLAM (Hamming distance of 256-bit descriptors).
inline constexpr int kMatchStrict = 50;
inline constexpr int kMatchLoose = 100;

// Projects the map points matched in `last` (at their world positions) into `current` at its
// predicted pose and matches them within `radius` px × the keypoint's scale, keeping the
// matches whose orientation change agrees with the dominant ones. Returns the number matched.
int SearchByProjection(Frame& current, const Frame& last, double radius);

// Matches `points` (the local map) not yet matched in `current`, predicted in view at
// `current`'s pose. `radius_factor` scales the search window (1 normally). Returns the number
// matched; counts each predicted-visible point's `visible` when `count_visible` (not for a
// trial search at a guessed pose, which would skew the points' found/visible ratio).
int SearchLocalPoints(Frame& current, const std::vector<MapPoint*>& points, uint64_t frame_stamp,
                      double radius_factor, bool count_visible = true);

// A direct index of a vocabulary (place/vocabulary.h's FeatureVector, the same type): node id
// -> indices of the features whose words lie below that node, ascending.
using FeatureVector = std::map<uint32_t, std::vector<int>>;

// Descriptor matching of `current` against the map points of `keyframe` with Lowe's ratio test
// and a rotation-consistency check: for when no pose prediction is good enough (tracking
// against the reference keyframe, relocalization, loop verification). With both direct
// indexes, vocabulary-guided as ORB-SLAM's SearchByBoW: a keyframe feature is compared only
// with the frame's features under the same vocabulary node, about a hundredth of them;
// without, with every static feature of the frame.
int SearchByDescriptor(Frame& current, const KeyFrame& keyframe,
                       const FeatureVector* keyframe_words = nullptr,
                       const FeatureVector* current_words = nullptr);

// Where a map point should appear in a camera at T_camera_world (centre: its centre): in the
// image, within the point's scale-invariance range and seen from less than 60° off its mean
// viewing direction. False when it should not be seen there. The local-map search looks for
// points where they should appear; fusion (mapping/fuse.h) does too.
struct PredictedView {
  Eigen::Vector3d p;  // camera frame
  double u, v, distance, view_cos;
};
bool PredictInView(const FrameGeometry& g, const Eigen::Isometry3d& T_camera_world,
                   const Eigen::Vector3d& centre, const MapPoint& point, PredictedView* view);

}  // namespace sdoslam
