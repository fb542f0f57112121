#pragma once

#include <vector>

#include "sdoslam/map/map.h"

namespace sdoslam {

// Projects `points` into `keyframe`; where one lands on a feature with a similar descriptor,
// the point is added to it, or fused with the point the feature already has (the one with
// more observations stays). Returns the number of fusions and additions. Unlike the searches of
// matching/matcher.h, which only match a frame's features, this edits the map: local mapping
// fuses a new keyframe's points with its neighbours', loop closing the two sides of a loop.
int Fuse(Map& map, KeyFrame* keyframe, const std::vector<MapPoint*>& points);

}  // namespace sdoslam
