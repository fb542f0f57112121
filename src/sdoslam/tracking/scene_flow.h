#pragma once

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sdoslam/tracking/static_motion.h"

namespace sdoslam {

// The consistency check of the paper (§III-E): the 3-D motion of every landmark between an
// earlier frame and this one, in the world frame, at the rough pose. Static landmarks have
// near-zero scene flow; features whose scene flow exceeds what sensor noise explains are
// dynamic, and so is a segment with more than `segment_ratio` of them.
struct SceneFlowOptions {
  bool enabled = true;  // only active when the front end hands over segments (mode sdo)
  // Scene flow from frame k − frame_gap to frame k. A longer baseline lets slow objects move
  // further than the noise; correspondences come from pyramidal Lucas–Kanade, which follows a
  // few frames of camera motion easily.
  int frame_gap = 5;
  // Features that Lucas–Kanade cannot follow back frame_gap frames are tried again over this
  // many frames (0: not retried; at most frame_gap − 1).
  int retry_gap = 2;
  // A feature is dynamic when its scene flow exceeds, along the viewing ray,
  //   min_flow + noise_sigmas · √2 · σ_z(z),  σ_z(z) = depth_noise_a + depth_noise_b·(z − 0.4)²
  // (the Kinect's axial noise, Nguyen et al. 2012; √2: two depth readings), or across the ray
  //   min_flow + noise_sigmas · √2 · pixel_sigma · z / f.
  // The threshold thus grows with depth as the sensor's noise does; min_flow absorbs the pose
  // error between the two frames.
  double min_flow = 0.01;  // metres
  double noise_sigmas = 3.0;
  double depth_noise_a = 0.0012;  // metres
  double depth_noise_b = 0.0019;  // 1/metre
  double pixel_sigma = 1.0;       // px: keypoint and Lucas–Kanade error together
  // Segment re-evaluation (paper: 30 %).
  double segment_ratio = 0.3;
  int min_segment_features = 3;  // measured features (and voting samples) a segment needs
  // The static-motion grid's samples (one corner per textured cell) vote in the segment rule
  // beside the features, judged by the same thresholds: a plain object with few ORB features
  // is judged by its area too (helps the carried box and mixed plays; docs/results.md).
  bool sample_votes = true;
  int max_iterations = 5;  // pose re-estimations per frame
  // The check's static set is kept when at least this many inliers remain; below it the frame
  // keeps the rough estimate. Lower than tracking.min_inliers: when a mover fills most of the
  // view (the carried box), the few features left on the room give a better pose than the many
  // on the mover.
  int min_inliers_kept = 15;
  // The map's hypothesis is not overturned on one frame's evidence: when the check keeps fewer
  // than this share of the established landmarks (seen by at least established_observations
  // keyframes) that tracking's pose kept as inliers, the frame keeps tracking's estimate.
  // 0: off.
  double min_established_kept = 0.5;
  int established_observations = 3;
  // Lucas–Kanade: window (px) and pyramid levels; a correspondence whose error per pixel
  // exceeds max_track_error (8-bit intensity units) is left unmeasured. The search starts where
  // a static point would be, so a small window and two levels above the image suffice (a third
  // is rarely needed, and costs time without accuracy). 16 px, not 15: OpenCV walks each window
  // row 8 pixels a step and the rest pixel by pixel, so 16 px rows have no slow 7-pixel tail
  // and cost about half the instructions (measurements: docs/performance.md).
  int track_window = 16;
  int track_levels = 2;
  // Lucas–Kanade's iterations per pyramid level (it also stops at 0.03 px). 10, not OpenCV's
  // customary 20: a static point starts at its prediction and settles in a few; the points
  // that use them all are on movers, slipping anyway (saves time, same accuracy).
  int track_iterations = 10;
  double max_track_error = 20.0;
  // ... and one that, tracked forward again, misses its start by more than this (px): dark or
  // repetitive texture and occlusions make Lucas–Kanade slip, and a slipped correspondence looks
  // exactly like motion.
  double max_round_trip_px = 0.5;
  // A correspondence found within this many px of where a static point would be (the search's
  // start, from the rough pose) skips the round trip: it cannot be judged moving across the ray
  // (min_flow alone is over a pixel at 4 m), so checking it would only cost time. 0: never skip.
  double skip_round_trip_px = 1.0;
  // Map hygiene: a landmark judged inconsistent this many times without a consistent match in
  // between (its feature has large scene flow, or it has moved away: the depth image sees
  // through where it should be) is culled from the map.
  int cull_after = 5;
  // ... and a landmark in view that the depth image sees through (a surface behind it, nothing
  // in front) counts as judged moving: the trace of a thing that moved away. Only in frames where
  // at most this share of the landmarks in view is seen through: after a frame tracked a few
  // pixels off (fast hand-held rotation, blur) a fifth of the view is, and striking them all
  // culled a third of the map on real fr1_rpy frames; where a parked thing leaves, its own
  // landmarks are a small share. 0: seeing through is no strike.
  double seen_through_max_share = 0.1;
  // px: depth window around a feature, its correspondence and a landmark's projection. Corners
  // often sit on depth edges, where one pixel off reads the other surface: a feature only counts
  // as moving when no depth of its windows (nearest, nearest surface, farthest surface) explains
  // it as static, and a landmark is only seen through when its whole window lies behind it.
  int depth_window_radius = 2;
  // A segment larger than this share of the image is never turned dynamic as a whole: one
  // frame's check, started from a rough pose that a large mover dragged along, would otherwise
  // take most of the static scene out at once. Its features are still judged one by one. 0.4,
  // not lower, so that a close object (a box carried 0.6 m ahead covers 26 % of the image) can
  // still turn dynamic as a whole when the front end misses it (docs/results.md, carried_box).
  // The classifier's own cap (classifier.max_segment_area) is 0.5.
  double max_segment_area = 0.4;
  // The paper's quasi-dynamic features (§III-C, E): features the front end took out because their
  // segment was selected by motion boundaries (label 2, not a known movable class) stay out of
  // tracking's pose but are judged like the others, and those the check finds static return to
  // static: they make map points and count for keyframes (they are not matched to the map again
  // within the frame; doing so closed loops on fewer runs of real fr1_rpy). A flow gradient also
  // marks depth gaps and, under blur and fast rotation, DIS's failures: on real fr1_rpy frames a
  // quarter to half of the image became boundary and hundreds of static features a frame left
  // the map. false: the front end's selection is final.
  bool recheck_motion_selected = true;
  // Before classifying, the rough pose is replaced by the motion that explains the largest
  // share of the image (static_motion.h), when that explains clearly more.
  StaticMotionOptions static_motion;
  void Check(
      const std::string& path = "tracking.consistency.") const;  // Error names path + setting

  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("enabled", o.enabled);
    visit("frame_gap", o.frame_gap);
    visit("retry_gap", o.retry_gap);
    visit("min_flow", o.min_flow);
    visit("noise_sigmas", o.noise_sigmas);
    visit("depth_noise_a", o.depth_noise_a);
    visit("depth_noise_b", o.depth_noise_b);
    visit("pixel_sigma", o.pixel_sigma);
    visit("segment_ratio", o.segment_ratio);
    visit("min_segment_features", o.min_segment_features);
    visit("sample_votes", o.sample_votes);
    visit("max_iterations", o.max_iterations);
    visit("min_inliers_kept", o.min_inliers_kept);
    visit("min_established_kept", o.min_established_kept);
    visit("established_observations", o.established_observations);
    visit("track_window", o.track_window);
    visit("track_levels", o.track_levels);
    visit("track_iterations", o.track_iterations);
    visit("max_track_error", o.max_track_error);
    visit("max_round_trip_px", o.max_round_trip_px);
    visit("skip_round_trip_px", o.skip_round_trip_px);
    visit("cull_after", o.cull_after);
    visit("seen_through_max_share", o.seen_through_max_share);
    visit("depth_window_radius", o.depth_window_radius);
    visit("max_segment_area", o.max_segment_area);
    visit("recheck_motion_selected", o.recheck_motion_selected);
    visit("static_motion", o.static_motion);
  }
};

// Axial depth noise σ_z(z) of the options' model, metres.
double DepthNoiseSigma(const SceneFlowOptions& options, double depth);
// The largest motion along the viewing ray that noise explains at `depth`:
// min_flow + noise_sigmas·√2·σ_z(depth).
double AlongRayLimit(const SceneFlowOptions& options, double depth);

// Whether a scene flow (world frame) of a landmark at `point_world`, seen at `depth` from
// `camera_centre` by a camera of focal length `focal_px`, exceeds the noise thresholds.
bool ExceedsSceneFlowThreshold(const SceneFlowOptions& options, const Eigen::Vector3d& flow_world,
                               const Eigen::Vector3d& point_world,
                               const Eigen::Vector3d& camera_centre, double depth, double focal_px);

// Segment re-evaluation. Inputs per feature: whether its scene flow was measured and exceeded
// the threshold, and its segment (−1: none). `locked_segments`: segments that are dynamic
// whatever their count (movable known classes). `large_segments`: segments too large to be one
// object (on real images they span desk, wall and floor); their features are judged one by
// one, never as a whole. Returns per feature whether it is dynamic: exceeding features on their
// own, and every feature of a segment in which more than `segment_ratio` of at least
// `min_segment_features` measured features exceed. `segment_dynamic` (optional) receives the
// verdict per segment.
std::vector<uint8_t> ClassifyBySceneFlow(const SceneFlowOptions& options,
                                         const std::vector<uint8_t>& measured,
                                         const std::vector<uint8_t>& exceeds,
                                         const std::vector<int>& segment,
                                         const std::vector<uint8_t>& locked_segments,
                                         const std::vector<uint8_t>& large_segments = {},
                                         std::vector<uint8_t>* segment_dynamic = nullptr);

// Per segment of a segment image (CV_32S, −1: none): whether it covers more than
// `max_fraction` of the image.
std::vector<uint8_t> LargeSegments(const cv::Mat& segment_image, double max_fraction);

// Follows `points` (pixels of `current_gray`) back into `previous_gray` with pyramidal
// Lucas–Kanade. `found[i]` is 0 where tracking failed, its error exceeded the options' limit, or
// the round trip (back, then forward again) does not return to the point. `guesses` (optional,
// one per point): where each point is expected in `previous_gray`; the search starts there, and
// a point found within options.skip_round_trip_px of its guess skips the round trip.
void TrackPointsBack(const SceneFlowOptions& options, const cv::Mat& current_gray,
                     const cv::Mat& previous_gray, const std::vector<cv::Point2f>& points,
                     std::vector<cv::Point2f>* previous_points, std::vector<uint8_t>* found,
                     const std::vector<cv::Point2f>* guesses = nullptr);

// A grey image's Lucas–Kanade pyramid for the options' window and levels, with its derivatives
// (cv::buildOpticalFlowPyramid). Built once per frame and kept, it spares each
// calcOpticalFlowPyrLK call two pyramids and one image's derivatives: the check follows a
// frame's points back three times. Its own copy of `gray`.
using LkPyramid = std::vector<cv::Mat>;
LkPyramid BuildLkPyramid(const SceneFlowOptions& options, const cv::Mat& gray);

// The image of a BuildLkPyramid pyramid at `level` (0: the image itself; level L is cv::pyrDown
// applied L times), or an empty image where the pyramid has no such level.
cv::Mat LkPyramidImage(const LkPyramid& pyramid, int level);

// TrackPointsBack on pyramids built by BuildLkPyramid with the same options: the same result.
void TrackPointsBack(const SceneFlowOptions& options, const LkPyramid& current,
                     const LkPyramid& previous, const std::vector<cv::Point2f>& points,
                     std::vector<cv::Point2f>* previous_points, std::vector<uint8_t>* found,
                     const std::vector<cv::Point2f>* guesses = nullptr);

// The depths a pixel may have: the one at `pixel` (rounded) and the nearest and farthest valid
// depths within `radius`, without repeats; empty when the window has no valid depth.
std::vector<float> DepthCandidates(const cv::Mat& depth, cv::Point2f pixel, int radius);

// Segment id at each point, from a segment image (CV_32S, any size of the image's aspect).
std::vector<int> SegmentsAt(const cv::Mat& segment_image, cv::Size image_size,
                            const std::vector<cv::Point2f>& points);

}  // namespace sdoslam
