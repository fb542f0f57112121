#pragma once

#include <Eigen/Geometry>
#include <atomic>
#include <string>
#include <vector>

#include "sdoslam/core/geometry.h"
#include "sdoslam/optim/residuals.h"

namespace sdoslam {

struct PoseOptimizationOptions {
  int rounds = 4;  // outlier classification rounds, fewer once the classification settles
  int iterations_per_round = 10;
};

struct PoseOptimizationResult {
  Eigen::Isometry3d T_camera_world = Eigen::Isometry3d::Identity();
  std::vector<bool> inlier;  // per observation
  int num_inliers = 0;
};

// Motion-only optimisation (ORB-SLAM's PoseOptimization): the camera pose that minimises the
// Huber-robust reprojection error of fixed world points; after each round observations above the
// χ² threshold are left out of the next (and may come back if they fit again). Observations
// behind the starting camera start out.
PoseOptimizationResult OptimizePose(const PinholeIntrinsics& intrinsics,
                                    const Eigen::Isometry3d& initial_T_camera_world,
                                    const std::vector<Eigen::Vector3d>& points_world,
                                    const std::vector<PointObservation>& observations,
                                    const PoseOptimizationOptions& options = {});

struct BundleAdjustmentProblem {
  std::vector<Eigen::Isometry3d> poses;  // T_camera_world, refined in place
  std::vector<bool> pose_fixed;
  std::vector<Eigen::Vector3d> points;  // world, refined in place
  struct Observation {
    int pose = 0, point = 0;
    PointObservation measurement;
  };
  std::vector<Observation> observations;
};

// What one bundle adjustment cost: the mapping log records it per keyframe, so a cost that
// grows over a long run can be traced to the problem's size or to the solver's iterations.
struct BundleAdjustmentStats {
  int observations = 0;  // residuals of the first pass
  int iterations = 0;    // solver iterations, both passes
  // `stop` was raised: the solve ended early and the second pass was left out.
  bool stopped = false;
};

struct BundleAdjustmentOptions {
  // First pass, all observations with Huber loss. 3, not ORB-SLAM2's 5: the second pass
  // starts where the first stopped and converges within a few iterations either way, so the
  // two extra first-pass iterations bought no accuracy for about 12 % more local-BA work
  // (docs/performance.md, Local mapping).
  int iterations = 3;
  int refine_iterations = 10;  // second pass without the outliers of the first
  void Check(const std::string& path = "mapping.bundle_adjustment.") const;  // both >= 0
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("iterations", o.iterations);
    visit("refine_iterations", o.refine_iterations);
  }
};

// Local bundle adjustment: poses (not fixed) and points jointly. Returns per observation whether
// it is an inlier after the optimisation (χ² test and positive depth). Single-threaded and so
// deterministic. `stop` (optional), once true, ends the solve after the iteration under way and
// leaves out the second pass, as ORB-SLAM's local BA stops for a new keyframe: the solution so
// far is kept and its outliers are still classified.
std::vector<bool> BundleAdjust(const PinholeIntrinsics& intrinsics,
                               BundleAdjustmentProblem* problem,
                               const BundleAdjustmentOptions& options = {},
                               BundleAdjustmentStats* stats = nullptr,
                               const std::atomic<bool>* stop = nullptr);

}  // namespace sdoslam
