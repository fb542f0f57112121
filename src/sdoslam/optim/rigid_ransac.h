#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

namespace sdoslam {

struct RigidRansacOptions {
  int max_iterations = 300;  // minimal samples drawn at most
  // Adaptive stop: no more samples once one all-inlier sample has been drawn with this
  // probability, given the best inlier ratio so far.
  double confidence = 0.999;
  // A match is an inlier when |T·a − b| < inlier_base + inlier_per_depth2 · z_b², z_b = b.z()
  // (b's depth in its camera). Kinect-type depth noise grows with z²: σ_z ≈ 1.425e-3 · z²
  // (Khoshelham & Elberink 2012). Both points carry it, so their difference has √2 times
  // that, and 3σ of it is ≈ 0.006 · z²; 0.01 leaves room for the depth of a's point, which the
  // test does not see (a loop's other keyframe may have seen the point from farther). The base
  // covers what does not grow with z²: the keypoint's position (1–2 px at its pyramid level is
  // 2–4 mm per metre of depth), depth quantisation near the camera and the depth–colour
  // registration. At 1 m the threshold is 3 cm, at 3 m 11 cm.
  double inlier_base = 0.02;
  double inlier_per_depth2 = 0.01;
  // Fewer inliers than this after the refit: no transform. ORB-SLAM2 asks 20 of its Sim3
  // RANSAC for a loop candidate.
  int min_inliers = 20;
  uint32_t seed = 1;  // of the sampler: the result is a function of the input and the seed

  // Throws Error naming the setting as path + name (loop closing passes its config path).
  void Check(const std::string& path = "rigid_ransac.") const;
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("max_iterations", o.max_iterations);
    visit("confidence", o.confidence);
    visit("inlier_base", o.inlier_base);
    visit("inlier_per_depth2", o.inlier_per_depth2);
    visit("min_inliers", o.min_inliers);
    visit("seed", o.seed);
  }
};

struct RigidRansacResult {
  bool found = false;
  // When found: the transform refitted on all inliers. Otherwise identity, all inlier flags
  // false and num_inliers 0 (a rejected consensus is not a measurement to build on).
  Eigen::Isometry3d T_b_a = Eigen::Isometry3d::Identity();
  std::vector<bool> inlier;  // per match, the size of the input
  int num_inliers = 0;
  int iterations = 0;  // minimal samples drawn (degenerate ones included)
};

// 3-D–3-D RANSAC of the rigid transform (no scale: RGB-D depth is metric) between matched
// points: a[i] in frame A and b[i] in frame B are a match, b[i] ≈ T_b_a · a[i]. For RGB-D loop
// verification and relocalisation, where both sides have depth. Hypotheses come from minimal
// sets of 3 matches by Umeyama's method; near-collinear sets and sets whose pairwise distances
// disagree between the two sides (a rigid motion keeps them) are skipped before fitting. The
// hypothesis with the most inliers wins (ties: smaller summed normalised error), then it is
// refitted on all its inliers and the matches reclassified, until the inlier set stops changing.
// Deterministic for a given seed. Throws Error when a and b differ in size or the options are
// invalid.
RigidRansacResult EstimateRigidTransformRansac(const std::vector<Eigen::Vector3d>& a,
                                               const std::vector<Eigen::Vector3d>& b,
                                               const RigidRansacOptions& options = {});

}  // namespace sdoslam
