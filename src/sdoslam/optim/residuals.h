#pragma once

#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <vector>

#include "sdoslam/core/geometry.h"

namespace sdoslam {

// A camera pose T_camera_world as a Ceres parameter block of 7 numbers [qx qy qz qw tx ty tz].
// Its tangent space is a left perturbation δ = [δω, δt]:  R ← Exp(δω)·R,  t ← Exp(δω)·t + δt.
// Residuals write their Jacobian with respect to δ into the first 6 columns of the 7-wide
// block Jacobian (the 7th stays 0) and PlusJacobian is [I₆; 0], so Ceres' product of the two is
// exactly the tangent Jacobian: a common way to give Ceres analytic Lie-group Jacobians.
class PoseManifold : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 7; }
  int TangentSize() const override { return 6; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

void PoseToParameters(const Eigen::Isometry3d& T_camera_world, double* parameters);
Eigen::Isometry3d PoseFromParameters(const double* parameters);

// The rotation Exp(w) (angle |w| about w), and the left Jacobian of SO(3) at w:
// Exp(w + ε) ≈ Exp(J_l(w)·ε)·Exp(w) for small ε.
Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& w);
Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& w);

// The whitened reprojection error of a camera-frame point `p` (in front of the camera):
// sqrt_information · (π(p) − observed), with observed = (u, v) for N = 2, or (u, v, u_R) with the
// virtual right coordinate u_R = u − bf/z for N = 3; and, where asked, its derivative by p.
// The residuals below and motion-only optimisation share it.
template <int N>
void WhitenedProjectionError(const PinholeIntrinsics& k, const Eigen::Vector3d& p,
                             const Eigen::Matrix<double, N, 1>& observed, double sqrt_information,
                             Eigen::Matrix<double, N, 1>* residual,
                             Eigen::Matrix<double, N, 3>* d_residual_d_p);

// Reprojection error of a world point in a camera, whitened by the keypoint's level:
// sqrt_information · (π(T·X) − observed). Blocks: pose (7), point (3).
class ReprojectionError : public ceres::SizedCostFunction<2, 7, 3> {
 public:
  ReprojectionError(const Eigen::Vector2d& observed, double sqrt_information,
                    const PinholeIntrinsics& intrinsics)
      : observed_(observed), sqrt_information_(sqrt_information), k_(intrinsics) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector2d observed_;
  double sqrt_information_;
  PinholeIntrinsics k_;
};

// The same with the virtual right-image coordinate u_R = u − bf/z of an RGB-D keypoint
// (ORB-SLAM2's treatment of depth): constrains depth along with the image position.
class StereoReprojectionError : public ceres::SizedCostFunction<3, 7, 3> {
 public:
  StereoReprojectionError(const Eigen::Vector3d& observed, double sqrt_information,
                          const PinholeIntrinsics& intrinsics)
      : observed_(observed), sqrt_information_(sqrt_information), k_(intrinsics) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector3d observed_;
  double sqrt_information_;
  PinholeIntrinsics k_;
};

// A motion-only problem for ceres::TinySolver: every observation's residual rows, Huber's loss
// applied inside, as functions of a perturbation δ = [δω, δt] of the starting pose T₀:
// T(δ) = [Exp(δω) | δt]·T₀, the chart of PoseManifold::Plus. TinySolver, Ceres' solver for small
// dense problems, runs the same Levenberg–Marquardt as Ceres' trust-region minimiser without its
// per-solve bookkeeping (a program, an evaluator, validity checks of every residual and Jacobian
// entry, the product with the manifold's Jacobian), which was about 90 % of OptimizePose's
// cost, far more than the residuals' own arithmetic (docs/performance.md, Tracking).
//
// The loss is applied as Ceres applies Huber's (its Corrector; ρ'' ≤ 0, so no Triggs term), with
// one row more per observation so that the cost stays exact: the rows are √ρ'·r with Jacobian
// √ρ'·J, then e = √(ρ − ρ'·s) with Jacobian 0. Their squares sum to ρ(s), so the solver minimises
// Σ ρ(s)/2; the gradient √ρ'·Jᵀ·√ρ'·r = ρ'·Jᵀr is the robust one; and the model's change,
// |r̂ + Ĵδ|² − |r̂|², is the one Ceres' own correction gives. Inside the threshold ρ' = 1, e = 0.
// An observation that is switched off (an outlier of the last round) gives zero rows.
class RobustPoseResiduals {
 public:
  using Scalar = double;
  enum { NUM_RESIDUALS = Eigen::Dynamic, NUM_PARAMETERS = 6 };

  // The vectors are held by reference and must outlive the object.
  RobustPoseResiduals(const PinholeIntrinsics& k, const Eigen::Isometry3d& start,
                      const std::vector<Eigen::Vector3d>& points,
                      const std::vector<PointObservation>& observations,
                      const std::vector<bool>& active);
  // Per observation: its 2 (3 with depth) whitened errors, then the loss's remainder.
  int NumResiduals() const { return rows_; }

  // The pose at δ.
  Eigen::Isometry3d Pose(const double* delta) const;

  // Residuals, and where asked the Jacobian (column-major, NumResiduals() × 6, as TinySolver
  // keeps it). A point behind the camera makes every residual infinite and returns false:
  // TinySolver then rejects the step and shrinks its trust region, as Ceres does when an
  // evaluation fails.
  bool operator()(const double* delta, double* residuals, double* jacobian) const;

 private:
  template <int N>
  void RobustRows(const Eigen::Vector3d& p, const Eigen::Matrix<double, N, 1>& observed,
                  double sqrt_information, double huber_threshold2,
                  const Eigen::Matrix3d& d_p_d_rotation, double* residual_out, double* jacobian,
                  int row) const;

  PinholeIntrinsics k_;
  Eigen::Isometry3d start_;
  const std::vector<Eigen::Vector3d>& points_;
  const std::vector<PointObservation>& observations_;
  const std::vector<bool>& active_;
  int rows_ = 0;
};

}  // namespace sdoslam
