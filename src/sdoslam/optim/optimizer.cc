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

// Every observation of a motion-only problem in one residual block, Huber's loss applied to each
// inside it. Ceres spends about a thousand instructions of bookkeeping on a residual block per
// evaluation (its validity checks, the product with the manifold's Jacobian, the loss
// correction), several times a reprojection error's arithmetic: with a block per observation that
// was two thirds of OptimizePose (callgrind, fr2_desk_50 sdo: 1.57 G instructions in 30 frames).
//
// The loss is applied as Ceres applies Huber's (its Corrector; ρ'' ≤ 0, so no Triggs term), with
// one row more per observation so that the cost stays exact: the rows are √ρ'·r with Jacobian
// √ρ'·J, then e = √(ρ − ρ'·s) with Jacobian 0. Their squares sum to ρ(s), so Ceres minimises
// Σ ρ(s)/2; the gradient √ρ'·Jᵀ·√ρ'·r = ρ'·Jᵀr is the robust one; and the model's change,
// |r̂ + Ĵδ|² − |r̂|², is the one Ceres' own correction gives. Inside the threshold ρ' = 1, e = 0.
// An observation that is switched off (an outlier of the last round) gives zero rows.
class RobustPoseResiduals final : public ceres::CostFunction {
 public:
  RobustPoseResiduals(const PinholeIntrinsics& k, const std::vector<Eigen::Vector3d>& points,
                      const std::vector<PointObservation>& observations,
                      const std::vector<bool>& active)
      : k_(k), points_(points), observations_(observations), active_(active) {
    int rows = 0;
    for (const PointObservation& m : observations) rows += (m.stereo() ? 3 : 2) + 1;
    set_num_residuals(rows);
    mutable_parameter_block_sizes()->push_back(7);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Isometry3d T = PoseFromParameters(parameters[0]);
    double* jacobian = jacobians != nullptr ? jacobians[0] : nullptr;
    int row = 0;
    for (size_t i = 0; i < observations_.size(); ++i) {
      const PointObservation& m = observations_[i];
      const int rows = (m.stereo() ? 3 : 2) + 1;  // the error, then the loss's remainder
      double* r = residuals + row;
      double* J = jacobian != nullptr ? jacobian + 7 * row : nullptr;
      row += rows;
      if (!active_[i]) {
        std::fill(r, r + rows, 0.0);
        if (J != nullptr) std::fill(J, J + 7 * rows, 0.0);
        continue;
      }
      const Eigen::Vector3d p = T * points_[i];
      if (p.z() <= 1e-6) return false;  // behind the camera: the solver steps back
      const double sqrt_information = std::sqrt(m.inv_sigma2);
      if (m.stereo()) {
        RobustRows<3>(p, Eigen::Vector3d(m.pixel.x(), m.pixel.y(), m.right_u), sqrt_information,
                      kChi2Stereo, r, J);
      } else {
        RobustRows<2>(p, m.pixel, sqrt_information, kChi2Mono, r, J);
      }
    }
    return true;
  }

 private:
  template <int N>
  void RobustRows(const Eigen::Vector3d& p, const Eigen::Matrix<double, N, 1>& observed,
                  double sqrt_information, double huber_threshold2, double* residual_out,
                  double* jacobian_out) const {
    Eigen::Matrix<double, N, 1> r;
    Eigen::Matrix<double, N, 3> d_p;
    WhitenedProjectionError<N>(k_, p, observed, sqrt_information, &r,
                               jacobian_out != nullptr ? &d_p : nullptr);
    const double s = r.squaredNorm();
    double sqrt_rho1 = 1, remainder = 0;
    if (s > huber_threshold2) {  // Huber: ρ(s) = 2a√s − a², ρ'(s) = a/√s, with a² the threshold
      const double a = std::sqrt(huber_threshold2), root_s = std::sqrt(s);
      sqrt_rho1 = std::sqrt(a / root_s);
      remainder = std::sqrt(std::max(0.0, a * root_s - huber_threshold2));  // √(ρ − ρ'·s)
    }
    Eigen::Map<Eigen::Matrix<double, N + 1, 1>> residual(residual_out);
    residual.template head<N>() = sqrt_rho1 * r;
    residual[N] = remainder;
    if (jacobian_out == nullptr) return;
    // ∂p/∂δ = [−[p]ₓ  I] for the left perturbation of PoseManifold.
    Eigen::Map<Eigen::Matrix<double, N + 1, 7, Eigen::RowMajor>> jacobian(jacobian_out);
    jacobian.template topLeftCorner<N, 3>() = -sqrt_rho1 * d_p * Hat(p);
    jacobian.template block<N, 3>(0, 3) = sqrt_rho1 * d_p;
    jacobian.col(6).setZero();
    jacobian.row(N).setZero();
  }

  PinholeIntrinsics k_;
  const std::vector<Eigen::Vector3d>& points_;
  const std::vector<PointObservation>& observations_;
  const std::vector<bool>& active_;
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
  // A point behind the camera cannot be evaluated, and Ceres gives up on a problem whose first
  // evaluation fails: such an observation starts as an outlier and comes back if a round's pose
  // puts it in front.
  for (size_t i = 0; i < observations.size(); ++i)
    result.inlier[i] = std::isfinite(Chi2(k, initial, points[i], observations[i]));
  // One problem for every round: the residual block reads result.inlier, so a round's outliers
  // add nothing to the next round's solve.
  ceres::Problem problem(ProblemOptions());
  problem.AddParameterBlock(pose, 7, &manifold);
  problem.AddResidualBlock(new RobustPoseResiduals(k, points, observations, result.inlier), nullptr,
                           pose);

  for (int round = 0; round < options.rounds; ++round) {
    if (std::count(result.inlier.begin(), result.inlier.end(), true) < 3) break;
    ceres::Solver::Options solver;
    // Six unknowns: the normal equations (6×6) are cheaper than a QR of the tall Jacobian, and
    // well conditioned at this size (the solve's cost 0.32 -> 0.20 G instructions, same poses
    // to 0.1 mm ATE on fr2_desk_50 and the real-background plays).
    solver.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
    solver.max_num_iterations = options.iterations_per_round;
    solver.num_threads = 1;
    solver.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    // Reclassify every observation, including earlier outliers, at the new pose.
    const Eigen::Isometry3d T = PoseFromParameters(pose);
    bool changed = false;
    for (size_t i = 0; i < observations.size(); ++i) {
      const bool inlier = Chi2(k, T, points[i], observations[i]) <=
                          ReprojectionChi2Threshold(observations[i].stereo());
      changed |= inlier != result.inlier[i];
      result.inlier[i] = inlier;
    }
    // The same observations would pose the same problem again, whose minimum this solve found:
    // further rounds would only refine it below the solver's tolerance (4 rounds -> 2.4 on
    // average in fr2_desk_50 sdo).
    if (!changed) break;
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
    if (stop != nullptr) solver.callbacks.push_back(&stop_when_raised);
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
