#pragma once

#include "sdoslam/map/map.h"
#include "sdoslam/tracking/tracking_types.h"

namespace sdoslam {

// RGB-D initialisation: the first frame with at least min_initial_depth_features features with
// depth defines the world (its pose becomes `T_camera_world`, the identity for the first) and
// becomes a keyframe, with a map point from depth for each of its static features with depth.
// Returns that keyframe, or nullptr (and the map unchanged) when the frame has too few features
// with depth.
// Whether `frame` has the min_initial_depth_features features with depth a map starts from.
bool CanStartMap(const TrackerOptions& options, const Frame& frame);

KeyFrame* InitializeMap(Map* map, const TrackerOptions& options, Frame& frame,
                        const Eigen::Isometry3d& T_camera_world = Eigen::Isometry3d::Identity());

}  // namespace sdoslam
