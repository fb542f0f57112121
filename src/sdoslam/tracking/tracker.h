#pragma once

#include <chrono>
#include <deque>
#include <memory>
#include <mutex>
#include <vector>

#include "sdoslam/map/map.h"
#include "sdoslam/place/keyframe_places.h"
#include "sdoslam/tracking/scene_flow.h"

namespace sdoslam {

enum class TrackingState { kNotInitialized, kOk, kLost };
const char* ToString(TrackingState state);

struct TrackerOptions {
  int min_initial_depth_features = 500;  // a first frame needs this many features with depth
  int min_inliers = 30;                  // to call a frame tracked after the local map
  int max_frames_between_keyframes = 30;
  double reference_ratio = 0.75;    // keyframe when tracking less than this of the reference
  int min_close_points = 100;       // keyframe when fewer close points are tracked...
  int close_points_to_create = 70;  // ...and at least this many new ones could be made
  double projection_radius = 15.0;  // px at level 0, motion-model search
  // Lost: the reference keyframe, this many of its best neighbours and this many of the last
  // keyframes are tried, each by descriptor matching and PnP in RANSAC.
  int relocalization_candidates = 5;
  // ... then this many keyframes from anywhere in the map whose bags of words look most like
  // the lost frame (place recognition; needs the Tracker's `places`).
  int relocalization_place_candidates = 5;
  // Lost for fewer than relocalization_prior_frames frames: first the map is searched by
  // projection around where the camera should be (the last pose carried on at the last
  // velocity, then the last pose itself), in windows relocalization_radius_factor times the
  // local-map search's, and the pose is kept when min_inliers remain after optimisation. A
  // person walking past close fills the view for a few frames while the camera hardly moves;
  // when the room comes back, the part in view is often one that only keyframes outside the
  // reference's neighbourhood saw, and descriptor matching against those candidates found 0-2
  // matches (synthetic loop: frames with 40-48 % of the room in view were lost in every mode).
  // 0: off.
  int relocalization_prior_frames = 30;
  double relocalization_radius_factor = 4.0;
  SceneFlowOptions consistency;  // the scene-flow consistency check and map hygiene
  void Check() const;
};

// Label the consistency check gives the features it judges dynamic (the front end's labels are
// 1 and 2).
inline constexpr uint8_t kSceneFlowLabel = 3;

// What the consistency check needs besides the frame's features: this frame's images and the
// front end's segmentation.
struct ConsistencyInput {
  cv::Mat gray;      // CV_8U, image size
  cv::Mat depth;     // CV_32F metres, registered to the colour image (0 = none)
  cv::Mat segments;  // CV_32S segment per pixel (−1: none) at any size of the image's aspect
  std::vector<uint8_t> locked_segments;  // per segment: dynamic whatever its scene flow
};

// Per-frame outcome, for the run log.
struct TrackingResult {
  size_t index = 0;
  double timestamp = 0;
  TrackingState state = TrackingState::kNotInitialized;
  int features = 0;
  int features_with_depth = 0;
  int matches = 0;  // map points matched before the final pose optimisation
  int inliers = 0;  // matched map points after it
  bool keyframe = false;
  bool relocalized = false;                          // tracked again after lost frames
  size_t keyframes_alive = 0, map_points_alive = 0;  // the map's size after this frame
  Eigen::Isometry3d T_camera_world = Eigen::Isometry3d::Identity();
  // Every feature's detected position, its front-end label (0 = static) and whether it ended
  // matched to a map point as an inlier: for overlays and feature-level evaluation.
  std::vector<cv::Point2f> feature_points;
  std::vector<uint8_t> feature_labels;
  std::vector<uint8_t> feature_tracked;
  // Consistency check: classification rounds run (0: not run), whether the static set reached a
  // fixed point, whether its result was dropped (too few inliers left: the rough pose stays),
  // features whose scene flow was measured, features it judged dynamic, and landmarks culled
  // from the map as inconsistent.
  int check_iterations = 0;
  bool check_converged = false;
  bool check_reverted = false;
  int check_measured = 0;
  int check_dynamic = 0;
  int culled_points = 0;
  // Static motion (static_motion.h): grid samples the rough pose explains, samples the chosen
  // pose explains, and whether the widest motion replaced the rough pose.
  int check_rough_samples = 0;
  int check_static_samples = 0;
  bool check_replaced = false;
  // Segments (ids of ConsistencyInput::segments) the check turned dynamic as a whole.
  std::vector<int> check_segments;
};

// Frame-to-map tracking of ORB-SLAM2 (RGB-D): constant-velocity prediction and projection
// search against the last frame (with temporary points from its depth), a descriptor-matching
// fallback against the reference keyframe, then the local map; motion-only pose optimisation
// after each; the keyframe decision. Creates keyframes and their close map points; local
// mapping refines them.
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
  double last_lock_wait_ms() const { return lock_wait_ms_; }

 private:
  // Runs `work` without the map lock when Track was given one (see Track); `work` must touch
  // nothing of the map.
  template <typename Work>
  auto WithoutMapLock(Work&& work) {
    if (map_lock_ == nullptr || !map_lock_->owns_lock()) return work();
    struct Relock {
      std::unique_lock<std::mutex>* lock;
      double* wait_ms;
      ~Relock() {
        const auto start = std::chrono::steady_clock::now();
        lock->lock();
        *wait_ms +=
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count();
      }
    };
    map_lock_->unlock();
    Relock relock{map_lock_, &lock_wait_ms_};
    return work();
  }
  TrackingResult TrackFrame(Frame frame, KeyFrame** new_keyframe, bool mapping_idle,
                            bool mapping_accepts, const ConsistencyInput* consistency);
  bool Initialize(Frame& frame);
  bool TrackWithMotionModel(Frame& frame);
  bool TrackReferenceKeyFrame(Frame& frame);
  // After tracking was lost: the pose from descriptor matches with nearby keyframes.
  bool Relocalize(Frame& frame);
  // A projection search of the whole map around predicted poses, in wide windows: Relocalize's
  // first try, and a tracked camera's last before it is called lost.
  bool RelocalizeNearPrediction(Frame& frame);
  bool TrackLocalMap(Frame& frame, TrackingResult* result);
  int OptimizeAndCount(Frame& frame);
  void MakeTemporaryPoints();
  bool NeedKeyFrame(const Frame& frame, int inliers, bool mapping_idle) const;
  KeyFrame* CreateKeyFrame(Frame& frame);
  // The paper's iterative check (§III-E). Returns the map points of the features it judged
  // dynamic.
  std::vector<MapPoint*> CheckSceneFlow(Frame& frame, const ConsistencyInput& input,
                                        TrackingResult* result);
  // Keeps this frame's images and pose for the scene flow of the frames to come.
  void RememberFrame(size_t index, bool tracked, const Eigen::Isometry3d& T_camera_world,
                     const ConsistencyInput* consistency);
  // Map hygiene: counts the inconsistency of local landmarks and culls the repeat offenders.
  void CheckLandmarks(const Frame& frame, const ConsistencyInput& input,
                      const std::vector<MapPoint*>& judged_dynamic, TrackingResult* result);

  Map* map_;
  KeyFramePlaces* places_;
  std::unique_lock<std::mutex>* map_lock_ = nullptr;  // during Track, when given
  double lock_wait_ms_ = 0;
  TrackerOptions options_;
  TrackingState state_ = TrackingState::kNotInitialized;
  std::unique_ptr<Frame> last_frame_;
  KeyFrame* reference_ = nullptr;
  KeyFrame* last_keyframe_ = nullptr;
  size_t last_keyframe_frame_ = 0;
  bool has_velocity_ = false;
  int frames_lost_ = 0;  // frames since the last tracked one
  Eigen::Isometry3d velocity_ = Eigen::Isometry3d::Identity();
  std::vector<std::unique_ptr<MapPoint>> temporary_points_;
  std::vector<TrajectoryEntry> trajectory_;
  uint64_t frame_stamp_ = 0;
  uint64_t correction_epoch_ = 0;        // of the map's last loop correction carried over
  std::vector<MapPoint*> local_points_;  // of the last TrackLocalMap
  // The last frames' images and poses, for scene flow.
  struct PastFrame {
    size_t index;
    cv::Mat gray, depth;
    Eigen::Isometry3d T_camera_world;
    bool tracked;
  };
  std::deque<PastFrame> history_;
};

}  // namespace sdoslam
