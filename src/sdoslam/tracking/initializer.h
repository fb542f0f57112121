#pragma once

#include "sdoslam/map/map.h"
#include "sdoslam/tracking/tracking_types.h"

namespace sdoslam {

// Whether `frame` has the min_initial_depth_features features with depth a map starts from.
bool CanStartMap(const TrackerOptions& options, const Frame& frame);

// RGB-D initialisation: a frame that CanStartMap becomes a keyframe at `T_camera_world` (the
// identity for the run's first: it defines the world), with a map point from depth for each of
// its static features with depth. Returns that keyframe, or nullptr (and the map unchanged) when
// the frame has too few features with depth.
KeyFrame* InitializeMap(Map* map, const TrackerOptions& options, Frame& frame,
                        const Eigen::Isometry3d& T_camera_world = Eigen::Isometry3d::Identity());

}  // namespace sdoslam
