#pragma once

#include <ceres/ceres.h>

#include <Eigen/Geometry>

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

}  // namespace sdoslam
