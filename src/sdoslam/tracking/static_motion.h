#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sdoslam/core/geometry.h"

namespace sdoslam {

// Which rigid motion is the static world's? Tracking takes what most matched features agree
// on, and the scene-flow check starts from tracking's pose. A large textured object carried in
// front of the camera breaks that: most features are on it, the pose follows it (or settles
// between it and the room), and the check then judges the real background to move. Here the
// scene is sampled on a uniform grid instead of at features, so each correspondence stands for
// the same image area, and the static world is the rigid motion that explains the largest area:
// a mover is compact, the world surrounds it, whatever their texture.
//
// Hand-written RANSAC: OpenCV's solvePnPRansac scores by inlier count of the correspondences it
// is given and cannot be seeded with, or compared against, a pose of ours; the scoring and the
// comparison with the rough pose are the point here.
struct StaticMotionOptions {
  bool enabled = true;
  int grid_columns = 32;  // sample grid over the image
  int grid_rows = 24;
  // A cell's sample is its strongest corner, if its minimal eigenvalue of the gradient
  // covariance (cv::cornerMinEigenVal, 5 × 5 block, OpenCV's scale for 8-bit images) reaches
  // this: on the TUM desk, the 90th percentile of all pixels is 0.0007, the 99th 0.013.
  double min_corner_strength = 0.002;
  // Corners are looked for on the image at half resolution (3 x 3 block, about 6 x 6 at full
  // resolution) and each sample sits at its corner's full-resolution pixel: about a fifth of the
  // time of full resolution with the 5 x 5 block (docs/performance.md).
  bool half_resolution_corners = true;
  int hypotheses = 200;    // RANSAC draws of three 3-D–3-D correspondences
  double inlier_px = 2.0;  // reprojection error of an inlier, px
  // The widest motion replaces the rough pose only when it explains this share more of the
  // sampled area than the rough pose does: where both explain the scene alike (a static scene,
  // or too little motion since the past frame to tell movers apart) nothing changes.
  double min_gain = 0.15;
  // ... and by at least this many samples: where few textured cells show the room (movers fill
  // the view), a handful of samples is noise, and replacing on it took most of the room out
  // (the real-background mixed play).
  int min_extra_samples = 10;
  // ... and only when it moves the samples' projections by at least this much (px, median over
  // the samples) from where the rough pose puts them. On fast hand-held turns the samples,
  // followed over five blurred frames, are a few pixels off, and among 200 draws one fits that
  // error better than the true motion: on real fr1_rpy frames, where nothing moves, the winner
  // replaced the pose in 53 of 300 frames, 1-3 px from it, and the features it did not explain
  // (up to 600 a frame) were judged moving; configs/tum_fr1.yaml sets 3. 0 (the default): any
  // shift, because on slow footage a mapped crate pushed aside drags the pose by only 1-2 px and
  // replacing it there is right (the real-background pushed_box play, seed 3: 6.1 mm at 0,
  // 8.2 at 3).
  double min_shift_px = 0.0;
  int min_correspondences = 30;
  uint32_t seed = 7;  // RANSAC draws; runs stay repeatable
  void Check(const std::string& path = "tracking.consistency.static_motion.") const;
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("enabled", o.enabled);
    visit("grid_columns", o.grid_columns);
    visit("grid_rows", o.grid_rows);
    visit("min_corner_strength", o.min_corner_strength);
    visit("half_resolution_corners", o.half_resolution_corners);
    visit("hypotheses", o.hypotheses);
    visit("inlier_px", o.inlier_px);
    visit("min_gain", o.min_gain);
    visit("min_extra_samples", o.min_extra_samples);
    visit("min_shift_px", o.min_shift_px);
    visit("min_correspondences", o.min_correspondences);
    visit("seed", o.seed);
  }
};

// One sample seen in a past frame and in this one.
struct MotionCorrespondence {
  Eigen::Vector3d past_world;      // from the past frame's depth and pose
  Eigen::Vector3d current_camera;  // from this frame's depth
  Eigen::Vector2d current_pixel;   // undistorted, this frame
};

struct StaticMotionResult {
  bool replaced = false;  // the widest motion differs from the rough pose (see min_gain)
  Eigen::Isometry3d T_camera_world = Eigen::Isometry3d::Identity();
  int inliers = 0;        // correspondences the chosen pose explains
  int rough_inliers = 0;  // ... the rough pose explains
};

// The samples of an image: in each cell of the options' grid, its strongest corner (the minimal
// eigenvalue of the gradient covariance, Shi–Tomasi), where that reaches min_corner_strength and
// `depth` (CV_32F, 0 = none) has a value. Flat cells give none: Lucas–Kanade slides on them.
// `half_gray`, where given, is cv::pyrDown(gray) made already (a Lucas–Kanade pyramid's first
// level above the image), used at half resolution instead of halving `gray` again.
std::vector<cv::Point2f> GridCorners(const StaticMotionOptions& options, const cv::Mat& gray,
                                     const cv::Mat& depth, const cv::Mat& half_gray = cv::Mat());

// Correspondences that `T_camera_world` reprojects within options.inlier_px.
int CountMotionInliers(const StaticMotionOptions& options, const PinholeIntrinsics& intrinsics,
                       const std::vector<MotionCorrespondence>& matches,
                       const Eigen::Isometry3d& T_camera_world);

// The camera pose that explains the most correspondences, if it explains clearly more than
// `rough_T_camera_world` does; otherwise the rough pose, unchanged.
StaticMotionResult FindStaticMotion(const StaticMotionOptions& options,
                                    const PinholeIntrinsics& intrinsics,
                                    const std::vector<MotionCorrespondence>& matches,
                                    const Eigen::Isometry3d& rough_T_camera_world);

}  // namespace sdoslam
