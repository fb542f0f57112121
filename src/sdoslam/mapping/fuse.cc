#include "sdoslam/mapping/fuse.h"

#include "sdoslam/core/geometry.h"
#include "sdoslam/matching/best_two.h"
#include "sdoslam/matching/matcher.h"

namespace sdoslam {

int Fuse(Map& map, KeyFrame* kf, const std::vector<MapPoint*>& points) {
  const FrameGeometry& g = *kf->frame.geometry;
  const Eigen::Isometry3d& T = kf->pose();
  const Eigen::Vector3d centre = kf->CameraCentre();
  int fused = 0;
  for (MapPoint* point : points) {
    if (point == nullptr || point->bad || point->observations.count(kf->id)) continue;
    PredictedView view;
    if (!PredictInView(g, T, centre, *point, &view)) continue;
    const auto& [p, u, v, distance, view_cos] = view;
    const int level = point->PredictLevel(distance, g);
    const double radius = 3.0 * g.scale[static_cast<size_t>(level)];
    BestTwo nearest;
    for (int j : kf->frame.FeaturesInArea(u, v, radius)) {
      const size_t k = static_cast<size_t>(j);
      const int j_level = kf->frame.keypoints[k].octave;
      if (j_level < level - 1 || j_level > level) continue;
      // Reprojection error gate (χ² on the whitened error, as in ORB-SLAM's Fuse).
      const PointObservation m = kf->frame.Observation(j);
      if (ReprojectionChi2(g.intrinsics, p, m) > ReprojectionChi2Threshold(m.stereo())) continue;
      nearest.Add(DescriptorDistance(point->descriptor.ptr<uint8_t>(),
                                     kf->frame.descriptors.ptr<uint8_t>(j)),
                  j);
    }
    if (!nearest.found() || nearest.best > kMatchStrict) continue;
    const int best_index = nearest.best_index;
    MapPoint* existing = kf->frame.map_points[static_cast<size_t>(best_index)];
    if (existing != nullptr && !existing->bad) {
      if (existing->observations.size() > point->observations.size()) {
        map.Replace(point, existing);
      } else {
        map.Replace(existing, point);
      }
    } else {
      map.AddObservation(point, kf, best_index);
      point->UpdateFromObservations();
    }
    ++fused;
  }
  return fused;
}

}  // namespace sdoslam
