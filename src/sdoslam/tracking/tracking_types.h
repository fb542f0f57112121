#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sdoslam/tracking/scene_flow.h"

namespace sdoslam {

class Frame;

// The Tracker's options, inputs and per-frame outcome, shared by the parts of tracking
// (tracker.h lists the parts).

enum class TrackingState { kNotInitialized, kOk, kLost };
const char* ToString(TrackingState state);

struct TrackerOptions {
  int min_initial_depth_features = 500;  // a first frame needs this many features with depth
  int min_inliers = 30;                  // to call a frame tracked after the local map
  int max_frames_between_keyframes = 30;
  // No keyframe within this many frames of the last one unless tracking is weak (inliers below
  // a quarter of the reference's matches) or the map has a single keyframe. ORB-SLAM2's RGB-D
  // tracking has no such spacing (0), and where movers hide much of the room its close-point
  // rule fires on every second frame, each keyframe costing a local BA. 2 makes fewer keyframes
  // and less mapping work at the same or better accuracy; 3 costs accuracy (scripts/plays.sh,
  // docs/results.md: Robustness to small perturbations).
  int min_frames_between_keyframes = 2;
  double reference_ratio = 0.75;    // keyframe when tracking less than this of the reference
  int min_close_points = 100;       // keyframe when fewer close points are tracked...
  int close_points_to_create = 70;  // ...and at least this many new ones could be made
  double projection_radius = 15.0;  // px at level 0, motion-model search
  // The local-map search's window, times the view-angle and pyramid-level window (2.5 or 4 px
  // times the level's scale). ORB-SLAM2 uses 3 for RGB-D. Under fast hand-held rotation with
  // blur (TUM freiburg1 rpy) the map points land farther from where the pose predicts them than
  // 1x finds, and tracking drifts; 3 fixes that but costs accuracy on slow footage (fr2_desk), so
  // 1 stays the default and configs/tum_fr1.yaml sets 3 (docs/results.md, TUM fr1_rpy).
  double local_map_radius = 1.0;
  // With a rolling shutter (camera.readout_s), the rows are first moved by the motion model's
  // velocity, the motion of the frames before; where the hand turns back, that is the wrong
  // motion. true: once the pose is found, the rows are moved again by the motion to this frame
  // as tracked, and the pose is optimised once more against the same matches.
  bool rolling_shutter_refit = true;
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
  // reference's neighbourhood saw, and descriptor matching against those candidates finds
  // almost nothing (the synthetic loop). 0: off.
  int relocalization_prior_frames = 30;
  double relocalization_radius_factor = 4.0;
  // While the map has at most this many keyframes, a camera lost straight from tracking (not
  // after frames it could not see) on a frame with min_initial_depth_features features with
  // depth starts the map again from the next frame, when that one is lost too and follows it
  // (Tracker::Restart): the trajectory goes on from the motion model's prediction for the lost
  // frame. A young map is mostly what the first frames took in before the front end could tell
  // movers (the first frame has no flow): with movers filling half of fast-turning real frames
  // (the mixed play over fr1_rpy) it held too little of the room, tracking was lost on the 8th
  // frame, and relocalizing against it failed for the other 292. ORB-SLAM2 resets such a map
  // and its trajectory. 0: off.
  int restart_below_keyframes = 5;
  // With the consistency check on, a frame it cannot judge (relocalized after a loss of
  // consistency.frame_gap frames or more: no tracked frame to measure scene flow from) is never
  // made a keyframe, as the map would take in whatever the front end missed on the mover that
  // filled the view. The next frame is judged (over a shorter baseline) and may be one.
  bool keyframes_only_from_judged_frames = true;
  // With the check's static motion on, a frame's view of the static world is narrow when fewer
  // than keyframes_min_static_samples of its grid samples confirm its pose (tracked back
  // consistency.frame_gap frames; consistency.static_motion) and fewer than
  // keyframes_min_static_features of its features labelled static have depth: so little of the
  // static world is in view that nothing vouches for the pose (a person a few decimetres from the
  // lens). A narrow frame after a narrow tracked frame is never made a keyframe, which would
  // write its error into the map that the frames after it, and the relocalization after the
  // loss, stand on. Both measures, because each alone is fooled: the samples are few wherever the
  // check cannot track or explain them, even with the static room in full view, and features
  // labelled static may lie on the person. Two frames, because one is no evidence: a frame whose
  // past frame was covered has few samples. Either 0 turns the rule off (docs/results.md:
  // Robustness to small perturbations).
  int keyframes_min_static_samples = 15;
  int keyframes_min_static_features = 300;
  SceneFlowOptions consistency;  // the scene-flow consistency check and map hygiene
  void Check(const std::string& path = "tracking.") const;  // Error names path + setting
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("min_initial_depth_features", o.min_initial_depth_features);
    visit("min_inliers", o.min_inliers);
    visit("max_frames_between_keyframes", o.max_frames_between_keyframes);
    visit("min_frames_between_keyframes", o.min_frames_between_keyframes);
    visit("reference_ratio", o.reference_ratio);
    visit("min_close_points", o.min_close_points);
    visit("close_points_to_create", o.close_points_to_create);
    visit("projection_radius", o.projection_radius);
    visit("local_map_radius", o.local_map_radius);
    visit("rolling_shutter_refit", o.rolling_shutter_refit);
    visit("relocalization_candidates", o.relocalization_candidates);
    visit("relocalization_place_candidates", o.relocalization_place_candidates);
    visit("relocalization_prior_frames", o.relocalization_prior_frames);
    visit("restart_below_keyframes", o.restart_below_keyframes);
    visit("relocalization_radius_factor", o.relocalization_radius_factor);
    visit("keyframes_only_from_judged_frames", o.keyframes_only_from_judged_frames);
    visit("keyframes_min_static_samples", o.keyframes_min_static_samples);
    visit("keyframes_min_static_features", o.keyframes_min_static_features);
    visit("consistency", o.consistency);
  }
};

// Label the consistency check gives the features it judges dynamic (the front end's labels are
// 1 and 2).
inline constexpr uint8_t kSceneFlowLabel = 3;
// The front end's label for features of segments selected by motion (DynamicLabel::
// kMovingUnknown): the check judges them again (SceneFlowOptions::recheck_motion_selected).
inline constexpr uint8_t kMotionSelectedLabel = 2;

// What the consistency check needs besides the frame's features: this frame's images and the
// front end's segmentation.
struct ConsistencyInput {
  cv::Mat gray;      // CV_8U, image size
  cv::Mat depth;     // CV_32F metres, registered to the colour image (0 = none)
  cv::Mat segments;  // CV_32S segment per pixel (−1: none) at any size of the image's aspect
  std::vector<uint8_t> locked_segments;  // per segment: dynamic whatever its scene flow
  // Whether features labelled kMotionSelectedLabel came from the front end's motion selection
  // (the check may return them to static), not from a caller's mask (ground truth in oracle
  // mode: final).
  bool motion_selected_recheckable = false;
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
  // What the local-map search added to the matches (those of the motion model or the fallback
  // before it), and what the keyframe decision saw: the reference keyframe's points that enough
  // keyframes see, and the close points tracked and untracked (-1: no decision was made).
  int local_map_matches = 0;
  int reference_matches = -1;
  int close_tracked = -1, close_untracked = -1;
  bool keyframe = false;
  bool relocalized = false;  // tracked again after lost frames
  bool restarted = false;    // the map started again from this frame (restart_below_keyframes)
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
  // Features the front end selected by motion that the check found static and returned.
  int check_readmitted = 0;
  int culled_points = 0;
  // Static motion (static_motion.h): grid samples followed back with depth at both ends, those
  // the rough pose explains, those the chosen pose explains, and whether the widest motion
  // replaced the rough pose.
  int check_samples = 0;
  int check_rough_samples = 0;
  int check_static_samples = 0;
  bool check_replaced = false;
  // Segments (ids of ConsistencyInput::segments) the check turned dynamic as a whole.
  std::vector<int> check_segments;
};

// The Tracker's motion-only pose optimisation (Tracker::OptimizeAndCount), for the parts that
// end with one: re-estimates frame.T_camera_world from the frame's matched map points, marks
// each matched feature an outlier or not and unmatches the outliers; returns the inliers (0,
// pose unchanged, below 10 matches). Its solve runs without the map lock.
using RefinePose = std::function<int(Frame& frame)>;

}  // namespace sdoslam
