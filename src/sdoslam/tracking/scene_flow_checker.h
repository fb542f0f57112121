#pragma once

#include <cstddef>
#include <deque>
#include <vector>

#include "sdoslam/map/map.h"
#include "sdoslam/tracking/map_lock.h"
#include "sdoslam/tracking/scene_flow.h"
#include "sdoslam/tracking/tracking_types.h"

namespace sdoslam {

// The scene-flow consistency check of the paper (§III-E) on tracked frames, and the map hygiene
// that follows it. Remembers the last frames' images and poses (the Tracker calls RememberFrame
// after each frame); a frame's features are followed back into the earliest of them by
// Lucas–Kanade, both ends become 3-D points from depth, and features whose scene flow exceeds
// what noise explains (scene_flow.h), or that the static world's motion does not explain
// (static_motion.h), are dynamic, and so are the segments mostly made of them. The pose is
// re-estimated without them until the dynamic set stops growing.
class SceneFlowChecker {
 public:
  // `map`: for culling the landmarks judged inconsistent too often (CheckLandmarks).
  SceneFlowChecker(Map* map, const SceneFlowOptions& options);

  // Keeps frame `index`'s images (cloned: the caller may reuse its buffers) and pose, and
  // whether it was tracked, for the scene flow of the frames to come; the last frame_gap frames
  // are kept. A frame tracked against `reference` keeps its pose relative to that keyframe, and
  // FollowMap moves it where the keyframe has moved since; without one the pose stays as given.
  // `row_motion`: how its rows moved (Frame::row_motion), for the points followed into it.
  void RememberFrame(size_t index, bool tracked, const Eigen::Isometry3d& T_camera_world,
                     const ConsistencyInput& input, const KeyFrame* reference = nullptr,
                     const RowMotion& row_motion = {});
  // Local BA and loop closing have moved keyframes: the remembered poses follow their reference
  // keyframes (culled ones through their parents), or the check would see the whole room move
  // by as much.
  void FollowMap();
  // The remembered frames from `index` − 2 on whose rows were taken as seen (no RowMotion):
  // their rows moved by `motion` (Tracker::CompensateRecentKeyFrames).
  void CompensateRecentFrames(size_t index, const RowMotion& motion);
  size_t remembered() const { return history_.size(); }
  // Forgets the remembered frames: the map started again, and their poses are in the old one.
  void Forget() { history_.clear(); }

  // Whether CheckSceneFlow can judge frame `index`: a tracked frame before it is remembered
  // (none after a loss of frame_gap frames or more).
  bool CanJudge(size_t index) const { return TrackedPastFrame(index) != nullptr; }

  // The paper's iterative check (§III-E) on `frame`, tracked at a rough pose with its matches
  // (frame.map_points, frame.outlier), against the earliest remembered tracked frame before it
  // (nothing is done without one). Features judged dynamic are labelled kSceneFlowLabel and
  // unmatched, and the pose is re-estimated by `refine_pose` without them. When too few inliers
  // would be left, or the check would overturn the map's established landmarks, the frame keeps
  // its matches and tracking's pose (result->check_reverted). Features the front end selected by
  // motion (kMotionSelectedLabel, where input.motion_selected_recheckable) are judged too, and
  // those found static are relabelled static (result->check_readmitted). Fills the check's fields
  // and `inliers` of `result`. Returns the map points of the features it judged dynamic.
  // `map_lock`: Lucas–Kanade, the grid corners and the static world's motion run without it.
  std::vector<MapPoint*> CheckSceneFlow(Frame& frame, const ConsistencyInput& input,
                                        const RefinePose& refine_pose, MapLockReleaser& map_lock,
                                        TrackingResult* result);

  // Map hygiene after CheckSceneFlow: counts the inconsistency of landmarks (MapPoint::
  // inconsistent) and culls those judged inconsistent cull_after times in a row
  // (result->culled_points). Landmarks `judged_dynamic` are inconsistent; those matched as
  // inliers are consistent; of the other `local_points` in view, those the depth image sees
  // through (a surface behind them, nothing in front) are inconsistent, unless more than
  // seen_through_max_share of them are.
  void CheckLandmarks(const Frame& frame, const ConsistencyInput& input,
                      const std::vector<MapPoint*>& judged_dynamic,
                      const std::vector<MapPoint*>& local_points, TrackingResult* result);

 private:
  // A remembered frame.
  struct PastFrame {
    size_t index;
    LkPyramid pyramid;  // of its grey image, for Lucas–Kanade
    cv::Mat depth;
    Eigen::Isometry3d T_camera_world;
    bool tracked;
    const KeyFrame* reference;  // null: the pose stays as remembered
    Eigen::Isometry3d T_camera_reference;
    RowMotion row_motion;  // how its rows moved (rolling shutter)
  };

  // A correspondence of the check: each end as a ray in the world frame and the depths it may
  // have along it (the depths within depth_window_radius of its pixel).
  struct Ends {
    Eigen::Vector3d past_origin, past_direction, current_direction;
    std::vector<float> past_depths, current_depths;
  };
  // The features still taken as static and the motion-selected ones judged again (the
  // candidates), followed back into a past frame.
  struct Correspondences {
    std::vector<int> candidates;         // feature indices
    std::vector<uint8_t> rechecked;      // per candidate: motion-selected, judged again
    std::vector<uint8_t> measured;       // per candidate: followed back, with depth at both ends
    std::vector<Ends> ends;              // per candidate, where measured
    std::vector<int> segment;            // per candidate: its segment (SegmentsAt)
    const LkPyramid* current = nullptr;  // the current frame's pyramid
  };
  // The static world's motion (static_motion.h): the grid samples that vote in the segment rule
  // beside the features, and the candidates that motion does not explain.
  struct StaticWorld {
    std::vector<Ends> sample_ends;
    std::vector<int> sample_segment;
    std::vector<uint8_t> off_static_motion;  // per candidate
  };

  // The earliest remembered tracked frame before frame `index` (frame index − frame_gap when
  // all were tracked); null when there is none.
  const PastFrame* TrackedPastFrame(size_t index) const;
  // The steps of CheckSceneFlow. Follows the candidates back into `past` by Lucas–Kanade (those
  // lost over frame_gap frames are tried again over retry_gap) and makes their ends.
  Correspondences FollowFeaturesBack(const Frame& frame, const ConsistencyInput& input,
                                     const PastFrame& past, MapLockReleaser& map_lock);
  // FollowFeaturesBack's second try: the candidates in `tracked_points` (slots `tracked_slot`)
  // that were not `found` in `past`, followed back retry_gap frames instead.
  void RetryOverNearPast(const Frame& frame, const ConsistencyInput& input, const PastFrame& past,
                         const std::vector<cv::Point2f>& tracked_points,
                         const std::vector<size_t>& tracked_slot, const std::vector<uint8_t>& found,
                         MapLockReleaser& map_lock, Correspondences* features);
  // The measured candidates whose past end, at any of its depths, the frame's pose does not
  // project within `limit_px` of the feature.
  std::vector<uint8_t> UnexplainedByPose(const Frame& frame, const Correspondences& features,
                                         double limit_px) const;
  // Finds the static world's motion from the grid samples; where it explains more of the image
  // than tracking's pose it replaces it (result->check_replaced), and the candidates it does not
  // explain are moving.
  StaticWorld FindStaticWorld(Frame& frame, const ConsistencyInput& input, const PastFrame& past,
                              const Correspondences& features, MapLockReleaser& map_lock,
                              TrackingResult* result) const;
  // Classifies the candidates at the frame's pose, re-estimates the pose without the dynamic
  // ones (their matches, from `matched`, dropped) and repeats until the dynamic set stops
  // growing. Returns it, per candidate; `segment_dynamic`: the segments turned dynamic.
  std::vector<uint8_t> ClassifyUntilSettled(Frame& frame, const ConsistencyInput& input,
                                            const Correspondences& features,
                                            const StaticWorld& world,
                                            const std::vector<MapPoint*>& matched,
                                            const RefinePose& refine_pose, TrackingResult* result,
                                            std::vector<uint8_t>* segment_dynamic) const;
  // The ends of a correspondence from `past_pixel` (undistorted: `past_undistorted`) in
  // `earlier` to `pixel` (`undistorted`) in the current frame, whose depth is `current_depth`.
  // False when either depth window has no depth.
  bool MakeEnds(const Camera& camera, const PastFrame& earlier, const cv::Mat& current_depth,
                const cv::Point2f& past_pixel, const cv::Point2f& past_undistorted,
                const cv::Point2f& pixel, const cv::Point2f& undistorted, Ends* ends) const;
  // The current frame's pyramid, built once by CheckSceneFlow and handed to RememberFrame.
  const LkPyramid& CurrentPyramid(size_t index, const cv::Mat& gray);

  Map* map_;
  SceneFlowOptions options_;
  std::deque<PastFrame> history_;  // oldest first
  size_t current_index_ = 0;
  LkPyramid current_pyramid_;  // frame current_index_'s, or empty
};

}  // namespace sdoslam
