#include "sdoslam/optim/pose_graph.h"

#include <ceres/ceres.h>
#include <ceres/product_manifold.h>

#include <array>
#include <cmath>
#include <string>

#include "sdoslam/core/error.h"
#include "sdoslam/optim/residuals.h"

namespace sdoslam {
namespace {

// Residual of one edge on the 7-number poses of residuals.h ([qx qy qz qw tx ty tz], the layout
// of Eigen's quaternion followed by the translation). Automatic differentiation: the
// quaternion products would make hand-written Jacobians long and error-prone, and the edges
// are cheap next to the sparse factorisation.
class RelativePoseError {
 public:
  RelativePoseError(const Eigen::Isometry3d& T_i_j, double sqrt_weight, double sqrt_rotation_weight)
      : q_measured_inverse_(Eigen::Quaterniond(T_i_j.rotation()).conjugate()),
        R_measured_inverse_(T_i_j.rotation().transpose()),
        t_measured_(T_i_j.translation()),
        sqrt_weight_(sqrt_weight),
        sqrt_rotation_weight_(sqrt_rotation_weight) {}

  template <typename T>
  bool operator()(const T* pose_i, const T* pose_j, T* residuals) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(pose_i), q_j(pose_j);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_i(pose_i + 4), t_j(pose_j + 4);
    // T_i · T_j⁻¹
    const Eigen::Quaternion<T> q_ij = q_i * q_j.conjugate();
    const Eigen::Matrix<T, 3, 1> t_ij = t_i - q_ij * t_j;
    // E = measured⁻¹ · (T_i · T_j⁻¹)
    const Eigen::Quaternion<T> q_e = q_measured_inverse_.template cast<T>() * q_ij;
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residuals);
    r.template head<3>() =
        T(sqrt_weight_) * (R_measured_inverse_.template cast<T>() * (t_ij - t_measured_.cast<T>()));
    // q and −q are the same rotation; r is odd in q_e, so the cost is not affected by the sign.
    r.template tail<3>() = T(2.0 * sqrt_weight_ * sqrt_rotation_weight_) * q_e.vec();
    return true;
  }

 private:
  Eigen::Quaterniond q_measured_inverse_;
  Eigen::Matrix3d R_measured_inverse_;
  Eigen::Vector3d t_measured_;
  double sqrt_weight_, sqrt_rotation_weight_;
};

}  // namespace

void PoseGraphProblem::Check() const {
  if (fixed.size() != poses.size()) {
    throw Error("pose graph: " + std::to_string(poses.size()) + " poses but " +
                std::to_string(fixed.size()) + " fixed flags; they must be the same size");
  }
  bool any_fixed = false;
  for (bool f : fixed) any_fixed = any_fixed || f;
  if (!any_fixed && !poses.empty()) {
    throw Error(
        "pose graph: no fixed node; fix at least one (the gauge: without it the whole "
        "graph may drift)");
  }
  const int n = static_cast<int>(poses.size());
  for (size_t k = 0; k < edges.size(); ++k) {
    const Edge& e = edges[k];
    const std::string name = "pose graph: edge " + std::to_string(k);
    if (e.i < 0 || e.i >= n || e.j < 0 || e.j >= n) {
      throw Error(name + " links nodes " + std::to_string(e.i) + " and " + std::to_string(e.j) +
                  " but there are " + std::to_string(n) + " nodes");
    }
    if (e.i == e.j) throw Error(name + " links node " + std::to_string(e.i) + " to itself");
    if (!(e.weight > 0 && std::isfinite(e.weight))) {
      throw Error(name + " has weight " + std::to_string(e.weight) +
                  "; it must be positive and finite");
    }
  }
}

void PoseGraphOptions::Check(const std::string& path) const {
  if (max_iterations < 1) throw Error(path + "max_iterations must be >= 1");
  if (!(rotation_weight > 0 && std::isfinite(rotation_weight)))
    throw Error(path + "rotation_weight must be positive and finite");
}

PoseGraphSummary OptimizePoseGraph(PoseGraphProblem* graph, const PoseGraphOptions& options) {
  options.Check();
  graph->Check();
  PoseGraphSummary result;
  if (graph->edges.empty()) {
    result.converged = true;  // nothing to fit, nothing moves
    return result;
  }

  std::vector<std::array<double, 7>> poses(graph->poses.size());
  for (size_t i = 0; i < poses.size(); ++i) PoseToParameters(graph->poses[i], poses[i].data());
  ceres::ProductManifold<ceres::EigenQuaternionManifold, ceres::EuclideanManifold<3>> manifold;

  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;  // one for all poses
  ceres::Problem problem(problem_options);
  // Only nodes on an edge become parameter blocks: a node without one has nothing to move it.
  std::vector<bool> added(poses.size(), false);
  auto add = [&](int node) {
    const size_t i = static_cast<size_t>(node);
    if (added[i]) return;
    added[i] = true;
    problem.AddParameterBlock(poses[i].data(), 7, &manifold);
    if (graph->fixed[i]) problem.SetParameterBlockConstant(poses[i].data());
  };
  const double sqrt_rotation_weight = std::sqrt(options.rotation_weight);
  for (const PoseGraphProblem::Edge& e : graph->edges) {
    add(e.i);
    add(e.j);
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<RelativePoseError, 6, 7, 7>(
            new RelativePoseError(e.T_i_j, std::sqrt(e.weight), sqrt_rotation_weight)),
        nullptr, poses[static_cast<size_t>(e.i)].data(), poses[static_cast<size_t>(e.j)].data());
  }

  ceres::Solver::Options solver;
  solver.minimizer_type = ceres::TRUST_REGION;
  solver.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // The normal equations of a pose graph are sparse (a 6x6 block per node and per edge) and
  // small enough to factor directly. SuiteSparse (Debian's Ceres has it) orders them by AMD,
  // deterministically; Eigen's sparse Cholesky is the fallback; dense QR, the last resort, suits
  // small graphs only.
  solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
    solver.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
    if (!ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE))
      solver.linear_solver_type = ceres::DENSE_QR;
  }
  // Start nearly at Gauss–Newton. Ceres' default radius (1e4) damps by 1e-4 of the diagonal,
  // which swamps the graph's slow modes: a long chain bends with eigenvalues ~(π/n)² of the
  // diagonal (4e-5 at 500 nodes), so each iteration moved them a fraction of the way (12
  // iterations instead of 4 on the 500-node test). A step that fails still shrinks the radius.
  solver.initial_trust_region_radius = 1e10;
  solver.max_num_iterations = options.max_iterations;
  // One thread: the order of the Jacobian's evaluation and of the sums is fixed, so the result
  // is bit-identical run to run.
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);

  for (size_t i = 0; i < poses.size(); ++i) {
    if (added[i] && !graph->fixed[i]) graph->poses[i] = PoseFromParameters(poses[i].data());
  }
  result.iterations = summary.num_successful_steps + summary.num_unsuccessful_steps;
  result.initial_cost = summary.initial_cost;
  result.final_cost = summary.final_cost;
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  return result;
}

}  // namespace sdoslam
