#include "sdoslam/optim/residuals.h"

namespace sdoslam {
namespace {

Eigen::Matrix3d ExpSO3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-12) return Eigen::Matrix3d::Identity() + Hat(w);
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

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

}  // namespace sdoslam
