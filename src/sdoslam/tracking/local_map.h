#pragma once

#include <vector>

#include "sdoslam/map/map.h"

namespace sdoslam {

// A frame's local map: what tracking searches after the frame's first matches.
struct LocalMap {
  // The good keyframes that see the frame's matched points (by id), then their best covisible
  // neighbours (10 each) and parents, while fewer than 80.
  std::vector<KeyFrame*> keyframes;
  // Of the keyframes that see the matched points, the one that sees most of them (the first by
  // id on a tie); nullptr when no good keyframe sees any.
  KeyFrame* reference = nullptr;
  // The good map points of `keyframes`, each once, in their order.
  std::vector<MapPoint*> points;
};

// The local map of `frame` from its matched map points (frame.map_points).
LocalMap FindLocalMap(const Map& map, const Frame& frame);

}  // namespace sdoslam
