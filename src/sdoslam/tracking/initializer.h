#pragma once

#include "sdoslam/map/map.h"
#include "sdoslam/tracking/tracking_types.h"

namespace sdoslam {

// RGB-D initialisation: the first frame with at least min_initial_depth_features features with
// depth defines the world (its pose becomes the identity) and becomes the first keyframe, with a
// map point from depth for each of its static features with depth. Returns that keyframe, or
// nullptr (and the map unchanged) when the frame has too few features with depth.
KeyFrame* InitializeMap(Map* map, const TrackerOptions& options, Frame& frame);

}  // namespace sdoslam
