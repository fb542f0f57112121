#include "sdoslam/optim/optimizer.h"

#include <ceres/tiny_solver.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

ceres::CostFunction* MakeResidual(const PinholeIntrinsics& k, const PointObservation& m) {
  const double sqrt_info = std::sqrt(m.inv_sigma2);
  if (m.stereo()) {
    return new StereoReprojectionError(Eigen::Vector3d(m.pixel.x(), m.pixel.y(), m.right_u),
                                       sqrt_info, k);
  }
  return new ReprojectionError(m.pixel, sqrt_info, k);
}

// Whitened squared error of an observation, or +inf behind the camera.
double Chi2(const PinholeIntrinsics& k, const Eigen::Isometry3d& T, const Eigen::Vector3d& X,
            const PointObservation& m) {
  const Eigen::Vector3d p = T * X;
  if (p.z() <= 1e-6) return std::numeric_limits<double>::infinity();
  return ReprojectionChi2(k, p, m);
}

// Huber's ρ(s) for a squared error s and a threshold a² (as RobustPoseResiduals applies it).
double Huber(double s, double threshold2) {
  return s <= threshold2 ? s : 2 * std::sqrt(threshold2 * s) - threshold2;
}

ceres::Problem::Options ProblemOptions() {
  ceres::Problem::Options o;
  // Residuals are built per solve; let the problem own them (and the loss functions, which
  // are shared and so owned here explicitly instead).
  o.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  o.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  return o;
}

// Up to this many free poses the bundle adjustment's reduced camera system is solved densely.
constexpr long kMaxDenseSchurPoses = 60;

}  // namespace

PoseOptimizationResult OptimizePose(const PinholeIntrinsics& k, const Eigen::Isometry3d& initial,
                                    const std::vector<Eigen::Vector3d>& points,
                                    const std::vector<PointObservation>& observations,
                                    const PoseOptimizationOptions& options) {
  PoseOptimizationResult result;
  result.T_camera_world = initial;
  result.inlier.assign(observations.size(), true);
  if (observations.empty()) return result;
  // The start made orthonormal again (through its quaternion, as Ceres' parameters were): the
  // result becomes the next frame's start through the motion model, a product of poses and an
  // inverse that assumes orthonormality, so rounding off orthonormality would otherwise grow
  // frame by frame (fr2_desk_50 conventional went 3.3 -> 68 mm before this).
  double start[7];
  PoseToParameters(initial, start);
  Eigen::Isometry3d T = PoseFromParameters(start);
  // A point behind the camera cannot be evaluated: such an observation starts as an outlier
  // and comes back if a round's pose puts it in front. `cost` is twice the next round's starting
  // cost, Σ ρ(s) over its observations, for the stopping rule below; read off the χ² values the
  // classification computes anyway instead of from another evaluation of every residual.
  double cost = 0;
  for (size_t i = 0; i < observations.size(); ++i) {
    const double chi2 = Chi2(k, T, points[i], observations[i]);
    result.inlier[i] = std::isfinite(chi2);
    if (result.inlier[i]) cost += Huber(chi2, ReprojectionChi2Threshold(observations[i].stereo()));
  }
  // The solver keeps its work matrices between rounds (the residual count stays the same).
  ceres::TinySolver<RobustPoseResiduals> solver;
  for (int round = 0; round < options.rounds; ++round) {
    if (std::count(result.inlier.begin(), result.inlier.end(), true) < 3) break;
    // Each round starts at δ = 0 from the last round's pose; the residuals read result.inlier,
    // so a round's outliers add nothing to the next round's solve.
    const RobustPoseResiduals residuals(k, T, points, observations, result.inlier);
    // Ceres' default stopping rules, which TinySolver states differently: the cost's change
    // relative to the cost (TinySolver's is absolute, on twice the cost), and a step under 1e-8
    // of the pose's parameters [q t] (TinySolver's bound is ε·(|δ| + ε), and δ starts at 0).
    Eigen::Matrix<double, 6, 1> delta = Eigen::Matrix<double, 6, 1>::Zero();
    solver.options.function_tolerance = 1e-6 * cost;
    solver.options.parameter_tolerance =
        1e-4 * std::sqrt(std::sqrt(1 + T.translation().squaredNorm()));
    // TinySolver counts its first evaluation as an iteration.
    solver.options.max_num_iterations = options.iterations_per_round + 1;
    solver.Solve(residuals, &delta);
    T = residuals.Pose(delta.data());
    // Reclassify every observation, including earlier outliers, at the new pose.
    // The inliers lie within Huber's threshold (the same χ² bound), where ρ(s) = s.
    bool changed = false;
    cost = 0;
    for (size_t i = 0; i < observations.size(); ++i) {
      const double chi2 = Chi2(k, T, points[i], observations[i]);
      const bool inlier = chi2 <= ReprojectionChi2Threshold(observations[i].stereo());
      changed |= inlier != result.inlier[i];
      result.inlier[i] = inlier;
      if (inlier) cost += chi2;
    }
    // The same observations would pose the same problem again, whose minimum this solve found:
    // further rounds would only refine it below the solver's tolerance (4 rounds -> 2.4 on
    // average in fr2_desk_50 sdo).
    if (!changed) break;
  }
  result.T_camera_world = T;
  result.num_inliers = 0;
  for (bool b : result.inlier) result.num_inliers += b;
  return result;
}

void BundleAdjustmentOptions::Check(const std::string& path) const {
  // Ceres refuses a negative iteration count (its solve would fail without a word).
  if (iterations < 0) throw Error(path + "iterations must be >= 0");
  if (refine_iterations < 0) throw Error(path + "refine_iterations must be >= 0");
}

namespace {

// The solver of a bundle adjustment: dense or sparse Schur by the number of free poses, the
// points eliminated first.
ceres::Solver::Options BundleSolverOptions(const ceres::Problem& problem,
                                           BundleAdjustmentProblem* ba,
                                           std::vector<std::array<double, 7>>* poses,
                                           long free_poses) {
  ceres::Solver::Options solver;
  // After the points are eliminated, a local window's reduced camera system has at most a few
  // dozen poses: dense Cholesky solves it faster than a sparse factorisation, whose block
  // bookkeeping dominates at that size (local BA 17 % faster per observation on static_room,
  // same ATE). A global BA over a large map stays sparse.
  solver.linear_solver_type =
      free_poses <= kMaxDenseSchurPoses ? ceres::DENSE_SCHUR : ceres::SPARSE_SCHUR;
  if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(
          solver.sparse_linear_algebra_library_type)) {
    solver.linear_solver_type = ceres::DENSE_SCHUR;
  }
  // The points are eliminated and the poses form the reduced camera system, as Ceres' own
  // ordering would choose for this bipartite problem; given here, Ceres does not search for an
  // independent set of the parameter blocks at each solve (local BA on the mixed play,
  // sequential: 411 -> 389 ms over 28 keyframes, the same trajectory byte for byte). A group's
  // blocks are taken in address order, which is their order in `ba->points` and `poses`.
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (auto& point : ba->points) {
    if (problem.HasParameterBlock(point.data())) ordering->AddElementToGroup(point.data(), 0);
  }
  for (auto& pose : *poses) ordering->AddElementToGroup(pose.data(), 1);
  solver.linear_solver_ordering = std::move(ordering);
  return solver;
}

// Per observation of `ba` at `poses`: whether it lies in front of its camera (in_front_only),
// or whether its reprojection error passes the χ² test.
void MarkInliers(const PinholeIntrinsics& k, const BundleAdjustmentProblem& ba,
                 const std::vector<std::array<double, 7>>& poses, bool in_front_only,
                 std::vector<bool>* inlier) {
  for (size_t o = 0; o < ba.observations.size(); ++o) {
    const auto& obs = ba.observations[o];
    const Eigen::Isometry3d T = PoseFromParameters(poses[static_cast<size_t>(obs.pose)].data());
    const Eigen::Vector3d& point = ba.points[static_cast<size_t>(obs.point)];
    (*inlier)[o] = in_front_only ? (T * point).z() > 1e-6
                                 : Chi2(k, T, point, obs.measurement) <=
                                       ReprojectionChi2Threshold(obs.measurement.stereo());
  }
}

}  // namespace

std::vector<bool> BundleAdjust(const PinholeIntrinsics& k, BundleAdjustmentProblem* ba,
                               const BundleAdjustmentOptions& options, BundleAdjustmentStats* stats,
                               const std::atomic<bool>* stop) {
  BundleAdjustmentStats counted;
  // Ends the solve once `stop` is raised (registered only when there is one); Ceres then keeps
  // the best solution so far.
  struct StopWhenRaised : ceres::IterationCallback {
    const std::atomic<bool>* stop = nullptr;
    bool* stopped = nullptr;
    ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
      if (!stop->load(std::memory_order_relaxed)) return ceres::SOLVER_CONTINUE;
      *stopped = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
  } stop_when_raised;
  stop_when_raised.stop = stop;
  stop_when_raised.stopped = &counted.stopped;
  const auto free_poses = std::count(ba->pose_fixed.begin(), ba->pose_fixed.end(), false);
  std::vector<std::array<double, 7>> poses(ba->poses.size());
  for (size_t i = 0; i < poses.size(); ++i) PoseToParameters(ba->poses[i], poses[i].data());
  PoseManifold manifold;
  ceres::HuberLoss huber_mono(std::sqrt(kChi2Mono)), huber_stereo(std::sqrt(kChi2Stereo));
  std::vector<bool> inlier(ba->observations.size(), true);

  auto solve = [&](int iterations) {
    ceres::Problem problem(ProblemOptions());
    for (size_t i = 0; i < poses.size(); ++i) {
      problem.AddParameterBlock(poses[i].data(), 7, &manifold);
      if (ba->pose_fixed[i]) problem.SetParameterBlockConstant(poses[i].data());
    }
    for (size_t o = 0; o < ba->observations.size(); ++o) {
      if (!inlier[o]) continue;
      const auto& obs = ba->observations[o];
      problem.AddResidualBlock(MakeResidual(k, obs.measurement),
                               obs.measurement.stereo() ? &huber_stereo : &huber_mono,
                               poses[static_cast<size_t>(obs.pose)].data(),
                               ba->points[static_cast<size_t>(obs.point)].data());
    }
    ceres::Solver::Options solver = BundleSolverOptions(problem, ba, &poses, free_poses);
    solver.max_num_iterations = iterations;
    solver.num_threads = 1;
    solver.logging_type = ceres::SILENT;
    if (stop != nullptr) solver.callbacks.push_back(&stop_when_raised);
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    counted.iterations += static_cast<int>(summary.iterations.size());
  };
  auto classify = [&] { MarkInliers(k, *ba, poses, /*in_front_only=*/false, &inlier); };
  counted.observations = static_cast<int>(ba->observations.size());
  // A residual cannot be evaluated behind its camera, and Ceres gives up on the whole problem
  // when one fails at the start (seen after loop corrections on walking_xyz): such an
  // observation starts as an outlier; it comes back if the solution puts it in front.
  MarkInliers(k, *ba, poses, /*in_front_only=*/true, &inlier);
  if (!ba->observations.empty()) {
    solve(options.iterations);
    classify();
    if (options.refine_iterations > 0 && !counted.stopped) {
      solve(options.refine_iterations);
      classify();
    }
  }
  for (size_t i = 0; i < poses.size(); ++i) ba->poses[i] = PoseFromParameters(poses[i].data());
  if (stats != nullptr) *stats = counted;
  return inlier;
}

}  // namespace sdoslam
