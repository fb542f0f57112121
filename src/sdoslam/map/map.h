#pragma once

#include <map>
#include <memory>
#include <vector>

#include "sdoslam/map/frame.h"

namespace sdoslam {

class KeyFrame;

// A 3-D landmark. Observations are keyed by keyframe id, so every iteration over them is in
// creation order, never in pointer order.
class MapPoint {
 public:
  MapPoint(uint64_t id, const Eigen::Vector3d& position, KeyFrame* reference);

  uint64_t id;
  Eigen::Vector3d position;
  KeyFrame* reference;  // the keyframe that created it
  uint64_t first_keyframe_id;
  cv::Mat descriptor;  // 1 x 32: the observation's descriptor closest to all others
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();            // mean viewing direction
  double min_distance = 0, max_distance = 0;                   // scale-invariance range
  std::map<uint64_t, std::pair<KeyFrame*, int>> observations;  // keyframe id -> (kf, feature)
  int visible = 1, found = 1;  // times predicted in view / matched by tracking
  int inconsistent = 0;  // times judged moved since its last consistent match (consistency check)
  bool bad = false;
  MapPoint* replaced_by = nullptr;
  uint64_t last_seen_frame = static_cast<uint64_t>(-1);  // bookkeeping for local-map search
  uint64_t fuse_target = static_cast<uint64_t>(-1);

  double FoundRatio() const { return static_cast<double>(found) / visible; }
  // Pyramid level at which a point this far away should appear.
  int PredictLevel(double distance, const FrameGeometry& g) const;
  // Recomputes descriptor, normal and distance range from the observations.
  void UpdateFromObservations();
};

class KeyFrame {
 public:
  KeyFrame(uint64_t id, Frame frame);

  uint64_t id;
  Frame frame;  // features, depth, matched map points, pose (T_camera_world)
  std::map<uint64_t, int> covisibility;   // keyframe id -> shared map points
  std::vector<KeyFrame*> best_covisible;  // by weight, then id
  KeyFrame* parent = nullptr;             // spanning tree
  bool bad = false;
  Eigen::Isometry3d T_camera_parent = Eigen::Isometry3d::Identity();  // kept when culled
  uint64_t local_ba_for = static_cast<uint64_t>(-1), fixed_ba_for = static_cast<uint64_t>(-1);

  const Eigen::Isometry3d& pose() const { return frame.T_camera_world; }
  Eigen::Vector3d CameraCentre() const { return frame.CameraCentre(); }
  std::vector<KeyFrame*> Covisible(size_t count) const;
  int TrackedPoints(int min_observations) const;
};

// Owns keyframes and map points; ids increase from 0 and are never reused. Culled elements are
// flagged bad and kept (frames may still point at them) until the map is destroyed.
class Map {
 public:
  KeyFrame* AddKeyFrame(Frame frame);
  MapPoint* AddMapPoint(const Eigen::Vector3d& position, KeyFrame* reference);
  void AddObservation(MapPoint* point, KeyFrame* keyframe, int feature);
  void EraseObservation(MapPoint* point, KeyFrame* keyframe);
  // Replaces `point` by `by` everywhere it is observed (fusing duplicates).
  void Replace(MapPoint* point, MapPoint* by);
  void SetBad(MapPoint* point);
  void UpdateConnections(KeyFrame* keyframe);
  void SetBad(KeyFrame* keyframe);

  const std::map<uint64_t, std::unique_ptr<KeyFrame>>& keyframes() const { return keyframes_; }
  const std::map<uint64_t, std::unique_ptr<MapPoint>>& points() const { return points_; }
  size_t GoodKeyFrames() const;
  size_t GoodPoints() const;

 private:
  std::map<uint64_t, std::unique_ptr<KeyFrame>> keyframes_;
  std::map<uint64_t, std::unique_ptr<MapPoint>> points_;
  uint64_t next_keyframe_id_ = 0, next_point_id_ = 0;
};

}  // namespace sdoslam
