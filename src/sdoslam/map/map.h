#pragma once

#include <deque>
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
  uint64_t last_seen_frame = static_cast<uint64_t>(-1);  // bookkeeping for local-map search

  double FoundRatio() const { return static_cast<double>(found) / visible; }
  // Pyramid level at which a point this far away should appear.
  int PredictLevel(double distance, const FrameGeometry& g) const;
  // Recomputes descriptor, normal and distance range from the observations.
  void UpdateFromObservations();
  // The observation's descriptor with the least median distance to the others: quadratic in
  // the candidates, so only when the observations change. Past kMaxDescriptorCandidates
  // observations, that many evenly spread ones are the candidates.
  void UpdateDescriptor();
  static constexpr size_t kMaxDescriptorCandidates = 64;
  // Mean viewing direction and scale-invariance range: after the position or the observations
  // change.
  void UpdateNormalAndDepth();
};

class KeyFrame {
 public:
  KeyFrame(uint64_t id, Frame frame);

  uint64_t id;
  Frame frame;  // features, depth, matched map points, pose (T_camera_world)
  std::map<uint64_t, int> covisibility;   // keyframe id -> shared map points
  std::vector<KeyFrame*> best_covisible;  // by weight, then id
  // Spanning tree. Invariant: a keyframe's parent is never culled (bad); a culled keyframe
  // keeps a parent so that frames tracked against it can still be placed.
  KeyFrame* parent = nullptr;
  std::map<uint64_t, KeyFrame*> children;  // by id, culled ones included
  bool bad = false;
  // Set when culled: this keyframe's pose relative to its parent, re-composed whenever the
  // parent is culled in turn, so pose = T_camera_parent * parent->pose() holds across culling.
  Eigen::Isometry3d T_camera_parent = Eigen::Isometry3d::Identity();

  const Eigen::Isometry3d& pose() const { return frame.T_camera_world; }
  Eigen::Vector3d CameraCentre() const { return frame.CameraCentre(); }
  std::vector<KeyFrame*> Covisible(size_t count) const;
  int TrackedPoints(int min_observations) const;
};

// `kf`, then at most `count` of its most covisible keyframes that are not culled, strongest
// first: the neighbourhood that local mapping adjusts and a loop closure fuses over.
std::vector<KeyFrame*> WithStrongestNeighbours(KeyFrame* kf, int count);

// The world pose of a camera tracked relative to `reference`, following culled references to
// their parents: T_camera_reference * T_reference_parent * ... * first good ancestor's pose.
Eigen::Isometry3d ComposeWithReference(const KeyFrame* reference,
                                       const Eigen::Isometry3d& T_camera_reference);

// Whether `ancestor` is `keyframe` or one of its ancestors in the spanning tree.
bool DescendsFrom(const KeyFrame* keyframe, const KeyFrame* ancestor);

// Owns keyframes and map points; ids increase from 0 and are never reused.
// Culled keyframes are flagged bad and kept, with their features released (frames tracked
// against them still need their place in the spanning tree): a few hundred bytes each.
// Culled map points are flagged bad and freed by CollectGarbage() once nobody can still hold a
// pointer to them (see there).
class Map {
 public:
  Map() = default;
  Map(const Map&) = delete;
  Map& operator=(const Map&) = delete;

  KeyFrame* AddKeyFrame(Frame frame);
  MapPoint* AddMapPoint(const Eigen::Vector3d& position, KeyFrame* reference);
  void AddObservation(MapPoint* point, KeyFrame* keyframe, int feature);
  void EraseObservation(MapPoint* point, KeyFrame* keyframe);
  // Replaces `point` by `by` everywhere it is observed (fusing duplicates).
  void Replace(MapPoint* point, MapPoint* by);
  void SetBad(MapPoint* point);
  // Recomputes the keyframe's covisibility edges (both sides) and, for a keyframe without a
  // parent, chooses the most covisible one that does not descend from it as its parent.
  void UpdateConnections(KeyFrame* keyframe);
  // Culls a keyframe: its observations go, its children (culled ones included) hang from its
  // parent, and its features are released. The first keyframe and a keyframe without a parent
  // are never culled. Returns whether it was culled.
  bool SetBad(KeyFrame* keyframe);

  // Lifetime of culled map points. A point culled while tracking holds pointers to it (the
  // last frame, a keyframe queued for mapping) must outlive them: tracking reports each
  // finished frame, mapping each inserted keyframe (in creation order), and a culled point is
  // freed once a frame has been finished after its culling and every keyframe made before its
  // culling has been inserted. Call CollectGarbage() where no pointer to a culled point is held
  // across the call (local mapping calls it before each keyframe). Returns the points freed.
  void FrameFinished() { ++finished_frames_; }
  void KeyFrameInserted(const KeyFrame* keyframe) { inserted_keyframes_ = keyframe->id + 1; }
  size_t CollectGarbage();

  const std::map<uint64_t, std::unique_ptr<KeyFrame>>& keyframes() const { return keyframes_; }
  const std::map<uint64_t, std::unique_ptr<MapPoint>>& points() const { return points_; }
  size_t GoodKeyFrames() const { return good_keyframes_; }
  size_t GoodPoints() const { return good_points_; }
  // Culled points not yet freed.
  size_t PendingGarbage() const { return graveyard_.size(); }

  // Loop closing moves keyframes (and their points) to new poses. It records, per keyframe
  // id, the change D = T_old⁻¹ · T_new of T_camera_world, so that whoever holds poses tied to
  // the old map (tracking's last frame, its scene-flow history, a local BA solved on a copy)
  // can carry them over, T_new = T_old · D, or drop them. The epoch counts corrections.
  void NoteCorrection(std::map<uint64_t, Eigen::Isometry3d> change_by_keyframe);
  uint64_t correction_epoch() const { return correction_epoch_; }
  // The change of `keyframe` (identity where a correction did not move it) over the
  // corrections after epoch `since`, composed in order: a loop's pose graph and its global BA
  // are two, and tracking may see both at once. A culled keyframe moved with its first good
  // ancestor. The last kMaxCorrections are kept; older ones count as identity.
  Eigen::Isometry3d CorrectionSince(const KeyFrame* keyframe, uint64_t since) const;
  static constexpr size_t kMaxCorrections = 8;

 private:
  void SetParent(KeyFrame* keyframe, KeyFrame* parent);
  void Bury(MapPoint* point);

  std::map<uint64_t, std::unique_ptr<KeyFrame>> keyframes_;
  std::map<uint64_t, std::unique_ptr<MapPoint>> points_;
  uint64_t next_keyframe_id_ = 0, next_point_id_ = 0;
  size_t good_keyframes_ = 0, good_points_ = 0;
  uint64_t finished_frames_ = 0, inserted_keyframes_ = 0;
  struct Grave {
    MapPoint* point;
    uint64_t finished_frames;  // when it was culled
    uint64_t keyframes_made;
  };
  std::vector<Grave> graveyard_;  // in culling order
  uint64_t correction_epoch_ = 0;
  std::deque<std::map<uint64_t, Eigen::Isometry3d>> corrections_;  // the last, oldest first
};

}  // namespace sdoslam
