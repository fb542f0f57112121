#pragma once

#include <memory>
#include <mutex>
#include <vector>

#include "sdoslam/map/map.h"
#include "sdoslam/place/keyframe_places.h"
#include "sdoslam/tracking/map_lock.h"
#include "sdoslam/tracking/relocalizer.h"
#include "sdoslam/tracking/scene_flow_checker.h"
#include "sdoslam/tracking/tracking_types.h"

namespace sdoslam {

// Frame-to-map tracking of ORB-SLAM2 (RGB-D): constant-velocity prediction and projection
// search against the last frame (with temporary points from its depth), a descriptor-matching
// fallback against the reference keyframe, then the local map; motion-only pose optimisation
// after each; the keyframe decision. Creates keyframes and their close map points; local
// mapping refines them.
//
// Split into parts as stella_vslam splits its tracking module. tracker.cc keeps frame tracking
// (the motion model with the last frame's temporary points, the reference-keyframe fallback,
// the search of the local map, the motion-only pose optimisation OptimizeAndCount) and all the
// state that carries from frame to frame: the last frame, the velocity, the reference keyframe,
// the frame stamp, the trajectory. The parts:
//   initializer.h          InitializeMap: the first keyframe and its points
//   local_map.h            FindLocalMap: the local keyframes, their points, the new reference
//   keyframe_inserter.h    NeedKeyFrame, CreateKeyFrame: the keyframe decision and insertion
//   relocalizer.h          Relocalizer: the pose of a frame that frame tracking lost
//   scene_flow_checker.h   SceneFlowChecker: the paper's consistency check, the last frames'
//                          images and poses it needs, and the landmark cleanup after it
//   map_lock.h             MapLockReleaser: work without the map lock (see Track)
//   tracking_types.h       the options, ConsistencyInput, TrackingResult, RefinePose
// The checker is a class because it keeps its image history from frame to frame; the
// relocalizer because it searches with the same map, places and options every time. The others
// are free functions: they take what they read and return what they make, and the Tracker
// applies that to its own state (the first keyframe, each new one and the local map's best
// become the reference), so that each can be tested alone. Parts that end with a pose
// optimisation get the Tracker's as a callable (RefinePose), those that work on images its
// MapLockReleaser. The relocalizer is the one part that changes the Tracker's state itself: it
// is handed the reference keyframe it may replace and the frame stamp it advances.
class Tracker {
 public:
  // `places` (optional): keyframes by their bags of words; relocalization then also tries the
  // keyframes anywhere in the map that look like the lost frame.
  Tracker(Map* map, const TrackerOptions& options, KeyFramePlaces* places = nullptr);

  // Tracks `frame`. When a keyframe is created it is returned through `new_keyframe`.
  // `mapping_idle`: local mapping has nothing queued (always true when it runs inline);
  // `mapping_accepts`: a keyframe may be queued now.
  // `consistency`: when given (and enabled in the options), the scene-flow consistency check
  // refines the static set and the pose, and inconsistent landmarks are culled.
  // `map_lock`: threaded runs pass the lock on the map they hold; Track releases it while it
  // works on copies and images only (Lucas–Kanade of the check, the static world's motion, the
  // pose solves), so that local mapping is not held up by them. Memory stays valid meanwhile:
  // culled points are freed only after the frame finishes (Map::CollectGarbage).
  TrackingResult Track(Frame frame, KeyFrame** new_keyframe, bool mapping_idle = true,
                       bool mapping_accepts = true, const ConsistencyInput* consistency = nullptr,
                       std::unique_lock<std::mutex>* map_lock = nullptr);

  // Each frame's pose relative to its reference keyframe, so that the trajectory follows the
  // keyframes as mapping refines them.
  struct TrajectoryEntry {
    double timestamp;
    KeyFrame* reference;  // nullptr when the frame was not tracked
    Eigen::Isometry3d T_camera_reference;
  };
  const std::vector<TrajectoryEntry>& trajectory() const { return trajectory_; }
  TrackingState state() const { return state_; }
  // Of the last Track: milliseconds spent taking the map lock back (see Track's map_lock).
  double last_lock_wait_ms() const { return map_lock_.wait_ms(); }

 private:
  TrackingResult TrackFrame(Frame frame, KeyFrame** new_keyframe, bool mapping_idle,
                            bool mapping_accepts, const ConsistencyInput* consistency);
  // The steps of TrackFrame. Follows what local mapping and loop closing did to the map since
  // the last frame: a culled reference keyframe, a corrected map.
  void FollowMapChanges();
  // The first frame: the map from its depth, when it has enough (`result` filled as far as the
  // frame goes).
  TrackingResult Initialize(Frame& frame, KeyFrame** new_keyframe,
                            const ConsistencyInput* consistency, TrackingResult result);
  // A keyframe of `frame` at `T_camera_world` with its points (InitializeMap), made the
  // reference and the last frame; null when the frame has too few features with depth.
  KeyFrame* StartMap(Frame& frame, const Eigen::Isometry3d& T_camera_world, KeyFrame** new_keyframe,
                     TrackingResult* result);
  // A lost frame with a young map (restart_below_keyframes): the map starts again from it when
  // it follows the frame before, lost straight from tracking and kept at the motion model's
  // prediction (restart_candidate_); otherwise it may become that candidate. Returns whether
  // the map started again.
  bool Restart(Frame& frame, KeyFrame** new_keyframe, const ConsistencyInput* consistency,
               TrackingResult* result);
  // Whether `frame` tracks against `candidate` by the motion model (at least min_inliers);
  // leaves the frame at the pose found, unmatched.
  bool FollowsCandidate(Frame& frame, const Frame& candidate);
  // The frame's pose: by the motion model or the reference keyframe (or relocalization when
  // lost), then against the local map. False when the frame could not be tracked.
  bool TrackPose(Frame& frame, TrackingResult* result);
  // Unmatches the temporary points and outliers, frees the temporaries, and records which
  // features are tracked.
  void DropTemporaryPoints(Frame& frame, TrackingResult* result);
  // What the keyframe decision knows besides the frame.
  struct KeyFrameChoice {
    bool mapping_idle = true, mapping_accepts = true;
    bool judged = true;  // the check judged the frame (or there is no check)
    const ConsistencyInput* consistency = nullptr;
  };
  // Makes the tracked frame a keyframe when the map needs one (keyframe_inserter.h) and the
  // static view vouches for its pose (TrackerOptions).
  void DecideKeyFrame(Frame& frame, const KeyFrameChoice& choice, KeyFrame** new_keyframe,
                      TrackingResult* result);
  bool TrackWithMotionModel(Frame& frame);
  bool TrackReferenceKeyFrame(Frame& frame);
  bool TrackLocalMap(Frame& frame, TrackingResult* result);
  // The motion-only pose optimisation every step ends with (see RefinePose): the pose from the
  // frame's matches, outliers unmatched; returns the inliers.
  int OptimizeAndCount(Frame& frame);
  // OptimizeAndCount, for the parts.
  RefinePose Refiner();
  // What the relocalizer needs of the last tracked frame.
  Relocalizer::Prior RelocalizationPrior() const;
  void MakeTemporaryPoints();
  // The first frames of a map (or after a loss) are made before the motion model knows how the
  // camera moves, so a rolling shutter's rows stay as seen. Once frame `index` gives the
  // velocity, the keyframes made in the last two frames without compensation take it
  // (Frame::CompensateRollingShutter), and the points made from their depth move with their
  // features. (TrackFrame hands the same motion to the frames the check remembers.)
  void CompensateRecentKeyFrames(size_t index, const RowMotion& motion);

  Map* map_;
  MapLockReleaser map_lock_;  // during Track, the lock it was given
  TrackerOptions options_;
  SceneFlowChecker checker_;  // the consistency check; keeps the last frames' images and poses
  Relocalizer relocalizer_;
  TrackingState state_ = TrackingState::kNotInitialized;
  std::unique_ptr<Frame> last_frame_;
  std::unique_ptr<Frame> restart_candidate_;  // see Restart
  KeyFrame* reference_ = nullptr;
  size_t last_keyframe_frame_ = 0;  // frame index of the last keyframe
  bool has_velocity_ = false;
  int frames_lost_ = 0;  // frames since the last tracked one
  // Whether the last frame, tracked, had a narrow view of the static world (TrackerOptions).
  bool last_narrow_static_view_ = false;
  Eigen::Isometry3d velocity_ = Eigen::Isometry3d::Identity();
  double velocity_seconds_ = 0;  // the time velocity_ spans (its two frames' timestamps)
  std::vector<std::unique_ptr<MapPoint>> temporary_points_;
  std::vector<TrajectoryEntry> trajectory_;
  uint64_t frame_stamp_ = 0;
  uint64_t correction_epoch_ = 0;        // of the map's last loop correction carried over
  std::vector<MapPoint*> local_points_;  // of the last TrackLocalMap
};

}  // namespace sdoslam
