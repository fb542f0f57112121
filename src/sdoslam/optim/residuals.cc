#include "sdoslam/optim/residuals.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace sdoslam {

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-12) return Eigen::Matrix3d::Identity() + Hat(w);
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

Eigen::Matrix3d LeftJacobianSO3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  const Eigen::Matrix3d W = Hat(w);
  // Below this angle the closed form loses its digits to cancellation, and the series' next
  // term (W²/6, about 2e-13) is negligible.
  if (angle < 1e-6) return Eigen::Matrix3d::Identity() + 0.5 * W;
  const double a2 = angle * angle;
  return Eigen::Matrix3d::Identity() + (1 - std::cos(angle)) / a2 * W +
         (angle - std::sin(angle)) / (a2 * angle) * W * W;
}

namespace {

// Point in the camera frame and the 3x6 / 3x3 Jacobians of it.
struct CameraPoint {
  Eigen::Vector3d p;
  Eigen::Matrix<double, 3, 6> d_pose;
  Eigen::Matrix3d d_point;
};

CameraPoint Transform(const double* pose, const double* point, bool jacobians) {
  const Eigen::Map<const Eigen::Quaterniond> q(pose);
  const Eigen::Map<const Eigen::Vector3d> t(pose + 4);
  const Eigen::Map<const Eigen::Vector3d> X(point);
  CameraPoint c;
  const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
  c.p = R * X + t;
  if (jacobians) {
    c.d_pose.leftCols<3>() = -Hat(c.p);  // ∂(Exp(δω)p)/∂δω at 0
    c.d_pose.rightCols<3>().setIdentity();
    c.d_point = R;
  }
  return c;
}

template <int N>
void WriteJacobians(const Eigen::Matrix<double, N, 3>& d_residual_d_p, const CameraPoint& c,
                    double** jacobians) {
  if (jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, N, 7, Eigen::RowMajor>> J(jacobians[0]);
    J.template leftCols<6>() = d_residual_d_p * c.d_pose;
    J.col(6).setZero();
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, N, 3, Eigen::RowMajor>> J(jacobians[1]);
    J = d_residual_d_p * c.d_point;
  }
}

}  // namespace

bool PoseManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Map<const Eigen::Quaterniond> q(x);
  const Eigen::Map<const Eigen::Vector3d> t(x + 4);
  const Eigen::Map<const Eigen::Vector3d> dw(delta), dt(delta + 3);
  const Eigen::Quaterniond dq(ExpSO3(dw));
  Eigen::Map<Eigen::Quaterniond> q_out(x_plus_delta);
  Eigen::Map<Eigen::Vector3d> t_out(x_plus_delta + 4);
  q_out = (dq * q).normalized();
  t_out = dq * t + dt;
  return true;
}

bool PoseManifold::PlusJacobian(const double*, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.topRows<6>().setIdentity();
  return true;
}

bool PoseManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const Eigen::Map<const Eigen::Quaterniond> qy(y), qx(x);
  const Eigen::Map<const Eigen::Vector3d> ty(y + 4), tx(x + 4);
  const Eigen::Quaterniond dq = qy * qx.conjugate();
  const Eigen::AngleAxisd aa(dq);
  Eigen::Map<Eigen::Vector3d> rotation_part(y_minus_x), translation_part(y_minus_x + 3);
  rotation_part = aa.angle() * aa.axis();
  translation_part = ty - dq * tx;
  return true;
}

bool PoseManifold::MinusJacobian(const double*, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.leftCols<6>().setIdentity();
  return true;
}

void PoseToParameters(const Eigen::Isometry3d& T, double* parameters) {
  const Eigen::Quaterniond q(T.rotation());
  parameters[0] = q.x();
  parameters[1] = q.y();
  parameters[2] = q.z();
  parameters[3] = q.w();
  parameters[4] = T.translation().x();
  parameters[5] = T.translation().y();
  parameters[6] = T.translation().z();
}

Eigen::Isometry3d PoseFromParameters(const double* parameters) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(parameters[3], parameters[0], parameters[1], parameters[2])
                   .normalized()
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(parameters[4], parameters[5], parameters[6]);
  return T;
}

template <>
void WhitenedProjectionError<2>(const PinholeIntrinsics& k, const Eigen::Vector3d& p,
                                const Eigen::Vector2d& observed, double sqrt_information,
                                Eigen::Vector2d* residual, Eigen::Matrix<double, 2, 3>* d) {
  const double iz = 1.0 / p.z();
  (*residual)[0] = sqrt_information * (k.fx * p.x() * iz + k.cx - observed.x());
  (*residual)[1] = sqrt_information * (k.fy * p.y() * iz + k.cy - observed.y());
  if (d != nullptr) {
    *d << k.fx * iz, 0, -k.fx * p.x() * iz * iz, 0, k.fy * iz, -k.fy * p.y() * iz * iz;
    *d *= sqrt_information;
  }
}

template <>
void WhitenedProjectionError<3>(const PinholeIntrinsics& k, const Eigen::Vector3d& p,
                                const Eigen::Vector3d& observed, double sqrt_information,
                                Eigen::Vector3d* residual, Eigen::Matrix3d* d) {
  const double iz = 1.0 / p.z();
  const double u = k.fx * p.x() * iz + k.cx;
  (*residual)[0] = sqrt_information * (u - observed.x());
  (*residual)[1] = sqrt_information * (k.fy * p.y() * iz + k.cy - observed.y());
  (*residual)[2] = sqrt_information * (u - k.bf * iz - observed.z());
  if (d != nullptr) {
    *d << k.fx * iz, 0, -k.fx * p.x() * iz * iz,  //
        0, k.fy * iz, -k.fy * p.y() * iz * iz,    //
        k.fx * iz, 0, -k.fx * p.x() * iz * iz + k.bf * iz * iz;
    *d *= sqrt_information;
  }
}

bool ReprojectionError::Evaluate(double const* const* parameters, double* residuals,
                                 double** jacobians) const {
  const CameraPoint c = Transform(parameters[0], parameters[1], jacobians != nullptr);
  if (c.p.z() <= 1e-6) return false;  // behind the camera: let the solver step back
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 3> d;
  WhitenedProjectionError<2>(k_, c.p, observed_, sqrt_information_, &r,
                             jacobians != nullptr ? &d : nullptr);
  Eigen::Map<Eigen::Vector2d> out(residuals);
  out = r;
  if (jacobians != nullptr) WriteJacobians<2>(d, c, jacobians);
  return true;
}

bool StereoReprojectionError::Evaluate(double const* const* parameters, double* residuals,
                                       double** jacobians) const {
  const CameraPoint c = Transform(parameters[0], parameters[1], jacobians != nullptr);
  if (c.p.z() <= 1e-6) return false;
  Eigen::Vector3d r;
  Eigen::Matrix3d d;
  WhitenedProjectionError<3>(k_, c.p, observed_, sqrt_information_, &r,
                             jacobians != nullptr ? &d : nullptr);
  Eigen::Map<Eigen::Vector3d> out(residuals);
  out = r;
  if (jacobians != nullptr) WriteJacobians<3>(d, c, jacobians);
  return true;
}

RobustPoseResiduals::RobustPoseResiduals(const PinholeIntrinsics& k, const Eigen::Isometry3d& start,
                                         const std::vector<Eigen::Vector3d>& points,
                                         const std::vector<PointObservation>& observations,
                                         const std::vector<bool>& active)
    : k_(k), start_(start), points_(points), observations_(observations), active_(active) {
  for (const PointObservation& m : observations) rows_ += (m.stereo() ? 3 : 2) + 1;
}

Eigen::Isometry3d RobustPoseResiduals::Pose(const double* delta) const {
  const Eigen::Matrix3d R = ExpSO3(Eigen::Vector3d(delta[0], delta[1], delta[2]));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R * start_.linear();
  T.translation() = R * start_.translation() + Eigen::Vector3d(delta[3], delta[4], delta[5]);
  return T;
}

template <int N>
void RobustPoseResiduals::RobustRows(const Eigen::Vector3d& p,
                                     const Eigen::Matrix<double, N, 1>& observed,
                                     double sqrt_information, double huber_threshold2,
                                     const Eigen::Matrix3d& d_p_d_rotation, double* residual_out,
                                     double* jacobian, int row) const {
  Eigen::Matrix<double, N, 1> r;
  Eigen::Matrix<double, N, 3> d_p;
  WhitenedProjectionError<N>(k_, p, observed, sqrt_information, &r,
                             jacobian != nullptr ? &d_p : nullptr);
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
  if (jacobian == nullptr) return;
  Eigen::Map<Eigen::Matrix<double, N + 1, 6>, 0, Eigen::OuterStride<>> J(
      jacobian + row, N + 1, 6, Eigen::OuterStride<>(rows_));
  J.template topLeftCorner<N, 3>() = sqrt_rho1 * d_p * d_p_d_rotation;
  J.template topRightCorner<N, 3>() = sqrt_rho1 * d_p;
  J.row(N).setZero();
}

bool RobustPoseResiduals::operator()(const double* delta, double* residuals,
                                     double* jacobian) const {
  const Eigen::Isometry3d T = Pose(delta);
  // p = Exp(δω)·T₀X + δt, so ∂p/∂δ = [−[p − δt]ₓ·J_l(δω)  I].
  const Eigen::Vector3d translation_step(delta[3], delta[4], delta[5]);
  const Eigen::Matrix3d chart = jacobian != nullptr
                                    ? LeftJacobianSO3(Eigen::Vector3d(delta[0], delta[1], delta[2]))
                                    : Eigen::Matrix3d::Identity();
  int row = 0;
  for (size_t i = 0; i < observations_.size(); ++i) {
    const PointObservation& m = observations_[i];
    const int rows = (m.stereo() ? 3 : 2) + 1;  // the error, then the loss's remainder
    double* r = residuals + row;
    if (!active_[i]) {
      std::fill(r, r + rows, 0.0);
      if (jacobian != nullptr) {
        for (int c = 0; c < 6; ++c) std::fill_n(jacobian + c * rows_ + row, rows, 0.0);
      }
      row += rows;
      continue;
    }
    const Eigen::Vector3d p = T * points_[i];
    if (p.z() <= 1e-6) {
      std::fill_n(residuals, rows_, std::numeric_limits<double>::infinity());
      return false;
    }
    const double sqrt_information = std::sqrt(m.inv_sigma2);
    const Eigen::Matrix3d d_p_d_rotation = jacobian != nullptr
                                               ? Eigen::Matrix3d(-Hat(p - translation_step) * chart)
                                               : Eigen::Matrix3d::Zero();
    if (m.stereo()) {
      RobustRows<3>(p, Eigen::Vector3d(m.pixel.x(), m.pixel.y(), m.right_u), sqrt_information,
                    kChi2Stereo, d_p_d_rotation, r, jacobian, row);
    } else {
      RobustRows<2>(p, m.pixel, sqrt_information, kChi2Mono, d_p_d_rotation, r, jacobian, row);
    }
    row += rows;
  }
  return true;
}

}  // namespace sdoslam
