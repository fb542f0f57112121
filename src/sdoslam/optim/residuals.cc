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

bool ReprojectionError::Evaluate(double const* const* parameters, double* residuals,
                                 double** jacobians) const {
  const CameraPoint c = Transform(parameters[0], parameters[1], jacobians != nullptr);
  if (c.p.z() <= 1e-6) return false;  // behind the camera: let the solver step back
  const double iz = 1.0 / c.p.z();
  residuals[0] = sqrt_information_ * (k_.fx * c.p.x() * iz + k_.cx - observed_.x());
  residuals[1] = sqrt_information_ * (k_.fy * c.p.y() * iz + k_.cy - observed_.y());
  if (jacobians != nullptr) {
    Eigen::Matrix<double, 2, 3> d;
    d << k_.fx * iz, 0, -k_.fx * c.p.x() * iz * iz, 0, k_.fy * iz, -k_.fy * c.p.y() * iz * iz;
    WriteJacobians<2>(sqrt_information_ * d, c, jacobians);
  }
  return true;
}

bool StereoReprojectionError::Evaluate(double const* const* parameters, double* residuals,
                                       double** jacobians) const {
  const CameraPoint c = Transform(parameters[0], parameters[1], jacobians != nullptr);
  if (c.p.z() <= 1e-6) return false;
  const double iz = 1.0 / c.p.z();
  const double u = k_.fx * c.p.x() * iz + k_.cx;
  residuals[0] = sqrt_information_ * (u - observed_.x());
  residuals[1] = sqrt_information_ * (k_.fy * c.p.y() * iz + k_.cy - observed_.y());
  residuals[2] = sqrt_information_ * (u - k_.bf * iz - observed_.z());
  if (jacobians != nullptr) {
    Eigen::Matrix<double, 3, 3> d;
    d << k_.fx * iz, 0, -k_.fx * c.p.x() * iz * iz,  //
        0, k_.fy * iz, -k_.fy * c.p.y() * iz * iz,   //
        k_.fx * iz, 0, -k_.fx * c.p.x() * iz * iz + k_.bf * iz * iz;
    WriteJacobians<3>(sqrt_information_ * d, c, jacobians);
  }
  return true;
}

}  // namespace sdoslam
