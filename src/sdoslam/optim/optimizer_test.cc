#include "sdoslam/optim/optimizer.h"

#include <gtest/gtest.h>

#include <atomic>
#include <random>

namespace sdoslam {
namespace {

const PinholeIntrinsics kK{535.4, 539.2, 320.1, 247.6, 40.0};

PointObservation Observe(const Eigen::Isometry3d& T, const Eigen::Vector3d& X, bool stereo) {
  const Eigen::Vector3d p = T * X;
  PointObservation m;
  m.pixel = Eigen::Vector2d(kK.fx * p.x() / p.z() + kK.cx, kK.fy * p.y() / p.z() + kK.cy);
  if (stereo) m.right_u = m.pixel.x() - kK.bf / p.z();
  return m;
}

Eigen::Isometry3d TruePose() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.2, Eigen::Vector3d(0, 1, 0.3).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.3, -0.1, 0.2);
  return T;
}

TEST(OptimizePose, RecoversAKnownPoseFromNoisyCorrespondencesWithOutliers) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> xy(-2, 2), depth(1.5, 5);
  std::normal_distribution<double> pixel_noise(0, 0.7);
  const Eigen::Isometry3d T = TruePose();
  std::vector<Eigen::Vector3d> points;
  std::vector<PointObservation> obs;
  std::vector<bool> is_outlier;
  for (int i = 0; i < 300; ++i) {
    Eigen::Vector3d X(xy(rng), xy(rng), depth(rng));
    X = T.inverse() * X;
    PointObservation m = Observe(T, X, i % 2 == 0);
    m.pixel += Eigen::Vector2d(pixel_noise(rng), pixel_noise(rng));
    if (m.right_u >= 0)
      m.right_u = m.pixel.x() - (Observe(T, X, true).pixel.x() - Observe(T, X, true).right_u);
    const bool outlier = i % 5 == 0;  // 20 %: a moving object's features, 30-80 px off
    if (outlier) m.pixel += Eigen::Vector2d(30 + i % 50, -40);
    points.push_back(X);
    obs.push_back(m);
    is_outlier.push_back(outlier);
  }
  Eigen::Isometry3d initial = T;
  initial.translation() += Eigen::Vector3d(0.05, -0.03, 0.04);
  initial.linear() =
      Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitX()).toRotationMatrix() * initial.linear();
  const PoseOptimizationResult r = OptimizePose(kK, initial, points, obs);
  EXPECT_LT((r.T_camera_world.translation() - T.translation()).norm(), 0.005);
  EXPECT_LT(Eigen::AngleAxisd(r.T_camera_world.linear() * T.linear().transpose()).angle(), 0.002);
  int flagged_outliers = 0, kept_inliers = 0;
  for (size_t i = 0; i < obs.size(); ++i) {
    flagged_outliers += is_outlier[i] && !r.inlier[i];
    kept_inliers += !is_outlier[i] && r.inlier[i];
  }
  EXPECT_EQ(flagged_outliers, 60);
  EXPECT_GT(kept_inliers, 0.9 * 240);
  EXPECT_EQ(r.num_inliers, static_cast<int>(std::count(r.inlier.begin(), r.inlier.end(), true)));
}

// 200 points seen from TruePose with 0.7 px noise; every fourth observation is 6-25 px off, in
// the linear part of Huber's loss.
void NoisyProblem(std::vector<Eigen::Vector3d>* points, std::vector<PointObservation>* obs) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> xy(-2, 2), depth(1.5, 5), off(6, 25);
  std::normal_distribution<double> pixel_noise(0, 0.7);
  const Eigen::Isometry3d T = TruePose();
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d X = T.inverse() * Eigen::Vector3d(xy(rng), xy(rng), depth(rng));
    PointObservation m = Observe(T, X, i % 3 != 0);
    const Eigen::Vector2d shift(pixel_noise(rng) + (i % 4 == 0 ? off(rng) : 0), pixel_noise(rng));
    m.pixel += shift;
    if (m.stereo()) m.right_u += shift.x();
    m.inv_sigma2 = i % 2 == 0 ? 1.0 : 1.0 / 1.44;  // keypoints of two pyramid levels
    points->push_back(X);
    obs->push_back(m);
  }
}

// Where NoisyProblem's solves start: TruePose moved by about 5 cm.
Eigen::Isometry3d StartingPose() {
  Eigen::Isometry3d initial = TruePose();
  initial.translation() += Eigen::Vector3d(0.04, 0.02, -0.03);
  return initial;
}

// The pose that minimises Σ ρ(s)/2 over all observations, solved the textbook way: a residual
// block per observation with Ceres' Huber loss, the point a constant block, tight tolerances.
Eigen::Isometry3d ReferenceRobustPose(const Eigen::Isometry3d& initial,
                                      std::vector<Eigen::Vector3d> points,
                                      const std::vector<PointObservation>& obs) {
  double pose[7];
  PoseToParameters(initial, pose);
  PoseManifold manifold;
  ceres::HuberLoss huber_mono(std::sqrt(kChi2Mono)), huber_stereo(std::sqrt(kChi2Stereo));
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  problem.AddParameterBlock(pose, 7, &manifold);
  for (size_t i = 0; i < obs.size(); ++i) {
    const PointObservation& m = obs[i];
    const double sqrt_information = std::sqrt(m.inv_sigma2);
    ceres::CostFunction* cost =
        m.stereo()
            ? static_cast<ceres::CostFunction*>(new StereoReprojectionError(
                  Eigen::Vector3d(m.pixel.x(), m.pixel.y(), m.right_u), sqrt_information, kK))
            : new ReprojectionError(m.pixel, sqrt_information, kK);
    problem.AddResidualBlock(cost, m.stereo() ? &huber_stereo : &huber_mono, pose,
                             points[i].data());
    problem.SetParameterBlockConstant(points[i].data());
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = 200;
  solver.function_tolerance = solver.gradient_tolerance = solver.parameter_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  EXPECT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
  return PoseFromParameters(pose);
}

TEST(OptimizePose, ReachesTheMinimumOfTheHuberCostThatALossPerObservationDefines) {
  std::vector<Eigen::Vector3d> points;
  std::vector<PointObservation> obs;
  NoisyProblem(&points, &obs);
  const Eigen::Isometry3d initial = StartingPose();
  const Eigen::Isometry3d reference = ReferenceRobustPose(initial, points, obs);
  // One round (no observation is dropped), run to convergence.
  const PoseOptimizationResult r = OptimizePose(kK, initial, points, obs, {1, 100});
  // The off observations pull the minimum millimetres away from the truth; a solver with a
  // wrong robust gradient settles elsewhere.
  EXPECT_GT((reference.translation() - TruePose().translation()).norm(), 1e-3);
  EXPECT_LT((r.T_camera_world.translation() - reference.translation()).norm(), 1e-4);
  EXPECT_LT(Eigen::AngleAxisd(r.T_camera_world.linear() * reference.linear().transpose()).angle(),
            5e-5);
}

TEST(OptimizePose, APointBehindTheStartingPoseIsAnOutlierAndThePoseIsStillFound) {
  std::vector<Eigen::Vector3d> points;
  std::vector<PointObservation> obs;
  NoisyProblem(&points, &obs);
  const Eigen::Isometry3d initial = StartingPose();
  // A point 0.5 m behind the starting camera (a wrong match to a point far behind).
  points.push_back(initial.inverse() * Eigen::Vector3d(0.1, 0.1, -0.5));
  PointObservation behind;
  behind.pixel = Eigen::Vector2d(300, 200);
  obs.push_back(behind);
  const PoseOptimizationResult r = OptimizePose(kK, initial, points, obs);
  EXPECT_FALSE(r.inlier.back());
  EXPECT_LT((r.T_camera_world.translation() - TruePose().translation()).norm(), 0.01);
  EXPECT_GT(r.num_inliers, 100);
}

TEST(OptimizePose, ReturnsARotationFromAStartThatHasDriftedFromOne) {
  std::vector<Eigen::Vector3d> points;
  std::vector<PointObservation> obs;
  NoisyProblem(&points, &obs);
  // A start whose rotation is off orthonormal by 1e-5, as a chain of pose products can leave it;
  // a solver that carried that along would hand it to the next frame's start through the motion
  // model, growing frame by frame.
  Eigen::Isometry3d initial = StartingPose();
  initial.linear() = initial.linear() * Eigen::DiagonalMatrix<double, 3>(1 + 1e-5, 1, 1 - 1e-5);
  const PoseOptimizationResult r = OptimizePose(kK, initial, points, obs);
  const Eigen::Matrix3d R = r.T_camera_world.linear();
  EXPECT_LT((R * R.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_LT((r.T_camera_world.translation() - TruePose().translation()).norm(), 0.01);
}

// Four cameras (the first fixed) seeing 200 points; poses and points start perturbed by ~2 cm.
BundleAdjustmentProblem PerturbedProblem(std::vector<Eigen::Isometry3d>* truth) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> xy(-1.5, 1.5), depth(2, 4);
  std::normal_distribution<double> noise(0, 0.02);
  BundleAdjustmentProblem ba;
  for (int c = 0; c < 4; ++c) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(-0.15 * c, 0.05 * c, 0);
    T.linear() = Eigen::AngleAxisd(0.03 * c, Eigen::Vector3d::UnitY()).toRotationMatrix();
    truth->push_back(T);
    Eigen::Isometry3d perturbed = T;
    if (c > 0) perturbed.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    ba.poses.push_back(perturbed);
    ba.pose_fixed.push_back(c == 0);  // gauge
  }
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d X(xy(rng), xy(rng), depth(rng));
    ba.points.push_back(X + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    for (int c = 0; c < 4; ++c)
      ba.observations.push_back({c, i, Observe((*truth)[c], X, c % 2 == 0)});
  }
  return ba;
}

TEST(BundleAdjust, ReducesReprojectionErrorOfAPerturbedProblem) {
  std::vector<Eigen::Isometry3d> truth;
  BundleAdjustmentProblem ba = PerturbedProblem(&truth);
  auto total_error = [&] {
    double e = 0;
    for (const auto& o : ba.observations) {
      const Eigen::Vector3d p = ba.poses[o.pose] * ba.points[o.point];
      e += (Eigen::Vector2d(kK.fx * p.x() / p.z() + kK.cx, kK.fy * p.y() / p.z() + kK.cy) -
            o.measurement.pixel)
               .squaredNorm();
    }
    return std::sqrt(e / ba.observations.size());
  };
  const double before = total_error();
  const auto inliers = BundleAdjust(kK, &ba);
  const double after = total_error();
  EXPECT_GT(before, 5.0);
  EXPECT_LT(after, 0.01);
  EXPECT_EQ(std::count(inliers.begin(), inliers.end(), true),
            static_cast<long>(ba.observations.size()));
  for (int c = 1; c < 4; ++c)
    EXPECT_LT((ba.poses[c].translation() - truth[c].translation()).norm(), 1e-4);
  EXPECT_TRUE(ba.poses[0].isApprox(truth[0]));  // fixed
}

// A point that starts behind the cameras observing it (a wrong match moved by a loop
// correction) cannot be evaluated; it must not stop the others from being adjusted.
TEST(BundleAdjust, APointBehindItsCamerasIsAnOutlierAndTheRestIsStillAdjusted) {
  std::vector<Eigen::Isometry3d> truth;
  BundleAdjustmentProblem ba = PerturbedProblem(&truth);
  const int behind = static_cast<int>(ba.points.size());
  ba.points.push_back(Eigen::Vector3d(0.1, 0.0, -1.0));
  PointObservation centre;
  centre.pixel = Eigen::Vector2d(320, 240);
  for (int c = 1; c < 3; ++c) ba.observations.push_back({c, behind, centre});
  const auto inliers = BundleAdjust(kK, &ba);
  EXPECT_FALSE(inliers[inliers.size() - 1]);
  EXPECT_FALSE(inliers[inliers.size() - 2]);
  EXPECT_EQ(std::count(inliers.begin(), inliers.end(), true),
            static_cast<long>(ba.observations.size()) - 2);
  for (int c = 1; c < 4; ++c)
    EXPECT_LT((ba.poses[c].translation() - truth[c].translation()).norm(), 1e-4);
}

// ORB-SLAM's local BA stops when a new keyframe arrives: a raised stop ends the solve at once
// (the problem as it was, its outliers still classified, no second pass), and a stop that is
// never raised changes nothing.
TEST(BundleAdjust, ARaisedStopEndsTheSolveAndALoweredOneChangesNothing) {
  std::vector<Eigen::Isometry3d> truth;
  const BundleAdjustmentProblem start = PerturbedProblem(&truth);

  BundleAdjustmentProblem stopped = start;
  const std::atomic<bool> raised{true};
  BundleAdjustmentStats stats;
  const auto inliers = BundleAdjust(kK, &stopped, {}, &stats, &raised);
  EXPECT_TRUE(stats.stopped);
  EXPECT_LE(stats.iterations, 1);  // Ceres' iteration 0, the starting point's evaluation
  EXPECT_EQ(inliers.size(), start.observations.size());
  for (size_t c = 0; c < start.poses.size(); ++c)
    EXPECT_TRUE(stopped.poses[c].isApprox(start.poses[c], 1e-12)) << c;

  BundleAdjustmentProblem free = start, lowered = start;
  const std::atomic<bool> never{false};
  BundleAdjustmentStats free_stats, lowered_stats;
  BundleAdjust(kK, &free, {}, &free_stats);
  BundleAdjust(kK, &lowered, {}, &lowered_stats, &never);
  EXPECT_FALSE(lowered_stats.stopped);
  EXPECT_EQ(lowered_stats.iterations, free_stats.iterations);
  EXPECT_GT(free_stats.iterations, 2);
  for (size_t c = 0; c < start.poses.size(); ++c)
    EXPECT_EQ(lowered.poses[c].matrix(), free.poses[c].matrix()) << c;
  EXPECT_LT((free.poses[1].translation() - truth[1].translation()).norm(), 1e-4);
}

}  // namespace
}  // namespace sdoslam
