#include "sdoslam/tracking/initializer.h"

namespace sdoslam {

bool CanStartMap(const TrackerOptions& options, const Frame& frame) {
  int with_depth = 0;
  for (size_t i = 0; i < frame.size(); ++i) with_depth += frame.HasDepth(static_cast<int>(i));
  return with_depth >= options.min_initial_depth_features;
}

KeyFrame* InitializeMap(Map* map, const TrackerOptions& options, Frame& frame,
                        const Eigen::Isometry3d& T_camera_world) {
  if (!CanStartMap(options, frame)) return nullptr;
  frame.T_camera_world = T_camera_world;
  KeyFrame* kf = map->AddKeyFrame(frame);
  for (size_t i = 0; i < kf->frame.size(); ++i) {
    if (!kf->frame.IsStaticWithDepth(static_cast<int>(i))) continue;
    MapPoint* p = map->AddMapPoint(kf->frame.UnprojectWorld(static_cast<int>(i)), kf);
    map->AddObservation(p, kf, static_cast<int>(i));
    p->UpdateFromObservations();
  }
  return kf;
}

}  // namespace sdoslam
