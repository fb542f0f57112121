#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace sdoslam {

// Poses linked by measured relative poses: the essential graph of loop closing. RGB-D depth is
// metric, so the poses are SE(3) (ORB-SLAM's Sim(3) is for monocular scale drift).
struct PoseGraphProblem {
  std::vector<Eigen::Isometry3d> poses;  // T_camera_world per node, refined in place
  std::vector<bool> fixed;               // per node; at least one (the gauge)
  struct Edge {
    int i = 0, j = 0;
    // Measured pose of node j in node i's frame: T_i_world · T_j_world⁻¹.
    Eigen::Isometry3d T_i_j = Eigen::Isometry3d::Identity();
    double weight = 1.0;  // information scale of the whole residual
  };
  std::vector<Edge> edges;

  // Throws Error naming the problem: sizes differ, no fixed node, an edge's node out of range or
  // linking a node to itself, a weight not positive and finite.
  void Check() const;
};

struct PoseGraphOptions {
  // Levenberg–Marquardt iterations at most. From odometry-chained poses a loop closes in a few
  // (the residual is nearly linear in the tangent space unless the drift is tens of degrees);
  // the rest is margin for large rotational drift.
  int max_iterations = 20;
  // Weight of the rotation residual (radians) against the translation residual (metres). 1 is
  // ORB-SLAM2's identity information on essential-graph edges: keyframes are 0.1–1 m and a few
  // degrees apart and odometry drifts ~1 % in both, so neither part dominates.
  double rotation_weight = 1.0;

  // Throws Error naming the setting as path + name (loop closing passes its config path).
  void Check(const std::string& path = "pose_graph.") const;
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("max_iterations", o.max_iterations);
    visit("rotation_weight", o.rotation_weight);
  }
};

struct PoseGraphSummary {
  int iterations = 0;  // Levenberg–Marquardt steps, taken or not
  // Ceres' cost, ½ Σ weight·|r|², before and after.
  double initial_cost = 0, final_cost = 0;
  bool converged = false;  // a tolerance was met (false: out of iterations, or failed)
};

// Moves the poses that are not fixed to fit the edges best in least squares. Each edge's
// residual is the error E = T_i_j⁻¹ · (T_i · T_j⁻¹) between its measurement and the current
// relative pose, as the 6-vector [t_E; √rotation_weight · 2·vec(q_E)] (2·vec(q) is the rotation
// vector to second order), times √weight. Each pose is a quaternion and a translation on
// Ceres' product manifold. Single-threaded with a deterministic sparse ordering, so the result
// is bit-identical run to run. Throws Error on an invalid problem or options.
PoseGraphSummary OptimizePoseGraph(PoseGraphProblem* problem, const PoseGraphOptions& options = {});

}  // namespace sdoslam
