#include "sdoslam/optim/optimizer.h"

#include <algorithm>
#include <cmath>
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

// A residual of the pose alone, its point held fixed inside: the same maths as the two-block
// residual (it calls it, asking no Jacobian for the point), but the point is no parameter block.
// Motion-only optimisation made a constant block per observation, and Ceres spent about a fifth
// of the solve adding, sorting and removing them again (callgrind, fr2_desk_50 sdo).
class FixedPointResidual final : public ceres::CostFunction {
 public:
  FixedPointResidual(std::unique_ptr<ceres::CostFunction> pose_and_point,
                     const Eigen::Vector3d& point)
      : inner_(std::move(pose_and_point)), point_(point) {
    set_num_residuals(inner_->num_residuals());
    mutable_parameter_block_sizes()->push_back(inner_->parameter_block_sizes()[0]);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const double* pose_and_point[2] = {parameters[0], point_.data()};
    double* pose_jacobian_only[2] = {jacobians != nullptr ? jacobians[0] : nullptr, nullptr};
    return inner_->Evaluate(pose_and_point, residuals,
                            jacobians != nullptr ? pose_jacobian_only : nullptr);
  }

 private:
  std::unique_ptr<ceres::CostFunction> inner_;
  Eigen::Vector3d point_;
};

// A robust loss that can be switched off: then the residual adds nothing to the cost, the
// gradient or the Gauss-Newton matrix (rho = 0 and its derivatives 0), as if it were removed.
class SwitchableLoss final : public ceres::LossFunction {
 public:
  explicit SwitchableLoss(const ceres::LossFunction* loss) : loss_(loss) {}
  void Evaluate(double squared_norm, double rho[3]) const override {
    if (active) {
      loss_->Evaluate(squared_norm, rho);
    } else {
      rho[0] = rho[1] = rho[2] = 0;
    }
  }
  bool active = true;

 private:
  const ceres::LossFunction* loss_;
};

// Whitened squared error of an observation, or +inf behind the camera.
double Chi2(const PinholeIntrinsics& k, const Eigen::Isometry3d& T, const Eigen::Vector3d& X,
            const PointObservation& m) {
  const Eigen::Vector3d p = T * X;
  if (p.z() <= 1e-6) return std::numeric_limits<double>::infinity();
  return ReprojectionChi2(k, p, m);
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
  double pose[7];
  PoseToParameters(initial, pose);
  PoseManifold manifold;
  ceres::HuberLoss huber_mono(std::sqrt(kChi2Mono)), huber_stereo(std::sqrt(kChi2Stereo));
  // One problem for every round: an outlier's residual stays in it with its loss switched off.
  // Rebuilding the problem per round spent a fifth of the time in allocating and freeing
  // residual blocks (perf, micro_bench BM_OptimizePose).
  std::vector<std::unique_ptr<SwitchableLoss>> losses;
  losses.reserve(observations.size());
  ceres::Problem problem(ProblemOptions());
  problem.AddParameterBlock(pose, 7, &manifold);
  for (size_t i = 0; i < observations.size(); ++i) {
    const PointObservation& m = observations[i];
    losses.push_back(std::make_unique<SwitchableLoss>(m.stereo() ? &huber_stereo : &huber_mono));
    problem.AddResidualBlock(
        new FixedPointResidual(std::unique_ptr<ceres::CostFunction>(MakeResidual(k, m)), points[i]),
        losses.back().get(), pose);
  }

  for (int round = 0; round < options.rounds; ++round) {
    int used = 0;
    for (size_t i = 0; i < observations.size(); ++i) {
      losses[i]->active = result.inlier[i];
      used += result.inlier[i];
    }
    if (used < 3) break;
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.max_num_iterations = options.iterations_per_round;
    solver.num_threads = 1;
    solver.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    // Reclassify every observation, including earlier outliers, at the new pose.
    const Eigen::Isometry3d T = PoseFromParameters(pose);
    for (size_t i = 0; i < observations.size(); ++i) {
      result.inlier[i] = Chi2(k, T, points[i], observations[i]) <=
                         ReprojectionChi2Threshold(observations[i].stereo());
    }
  }
  result.T_camera_world = PoseFromParameters(pose);
  result.num_inliers = 0;
  for (bool b : result.inlier) result.num_inliers += b;
  return result;
}

void BundleAdjustmentOptions::Check(const std::string& path) const {
  // Ceres refuses a negative iteration count (its solve would fail without a word).
  if (iterations < 0) throw Error(path + "iterations must be >= 0");
  if (refine_iterations < 0) throw Error(path + "refine_iterations must be >= 0");
}

std::vector<bool> BundleAdjust(const PinholeIntrinsics& k, BundleAdjustmentProblem* ba,
                               const BundleAdjustmentOptions& options,
                               BundleAdjustmentStats* stats) {
  BundleAdjustmentStats counted;
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
    solver.max_num_iterations = iterations;
    solver.num_threads = 1;
    solver.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    counted.iterations += static_cast<int>(summary.iterations.size());
  };
  auto classify = [&] {
    for (size_t o = 0; o < ba->observations.size(); ++o) {
      const auto& obs = ba->observations[o];
      const Eigen::Isometry3d T = PoseFromParameters(poses[static_cast<size_t>(obs.pose)].data());
      inlier[o] = Chi2(k, T, ba->points[static_cast<size_t>(obs.point)], obs.measurement) <=
                  ReprojectionChi2Threshold(obs.measurement.stereo());
    }
  };
  counted.observations = static_cast<int>(ba->observations.size());
  // A residual cannot be evaluated behind its camera, and Ceres gives up on the whole problem
  // when one fails at the start (seen after loop corrections on walking_xyz): such an
  // observation starts as an outlier; it comes back if the solution puts it in front.
  for (size_t o = 0; o < ba->observations.size(); ++o) {
    const auto& obs = ba->observations[o];
    const Eigen::Isometry3d T = PoseFromParameters(poses[static_cast<size_t>(obs.pose)].data());
    inlier[o] = (T * ba->points[static_cast<size_t>(obs.point)]).z() > 1e-6;
  }
  if (!ba->observations.empty()) {
    solve(options.iterations);
    classify();
    if (options.refine_iterations > 0) {
      solve(options.refine_iterations);
      classify();
    }
  }
  for (size_t i = 0; i < poses.size(); ++i) ba->poses[i] = PoseFromParameters(poses[i].data());
  if (stats != nullptr) *stats = counted;
  return inlier;
}

}  // namespace sdoslam
