#include "sdoslam/optim/residuals.h"

#include <gtest/gtest.h>

namespace sdoslam {
namespace {

const PinholeIntrinsics kIntrinsics{535.4, 539.2, 320.1, 247.6, 40.0};

Eigen::Isometry3d SomePose() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, -1, 0.2).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.1, -0.2, 0.3);
  return T;
}

// Central differences through the manifold's Plus (pose) and plain (point) versus the analytic
// Jacobians of a residual with N outputs.
template <int N>
void ExpectAnalyticMatchesNumeric(const ceres::CostFunction& cost) {
  double pose[7];
  PoseToParameters(SomePose(), pose);
  double point[3] = {0.4, -0.3, 2.5};
  const double* parameters[2] = {pose, point};
  double residual[N], j_pose[N * 7], j_point[N * 3];
  double* jacobians[2] = {j_pose, j_point};
  ASSERT_TRUE(cost.Evaluate(parameters, residual, jacobians));
  const PoseManifold manifold;
  const double h = 1e-6;
  for (int d = 0; d < 6; ++d) {
    double delta[6] = {}, plus[7], minus[7], r_plus[N], r_minus[N];
    delta[d] = h;
    manifold.Plus(pose, delta, plus);
    delta[d] = -h;
    manifold.Plus(pose, delta, minus);
    const double* p_plus[2] = {plus, point};
    const double* p_minus[2] = {minus, point};
    cost.Evaluate(p_plus, r_plus, nullptr);
    cost.Evaluate(p_minus, r_minus, nullptr);
    for (int r = 0; r < N; ++r) {
      EXPECT_NEAR(j_pose[r * 7 + d], (r_plus[r] - r_minus[r]) / (2 * h),
                  1e-4 * (1 + std::abs(j_pose[r * 7 + d])))
          << "pose dim " << d << " residual " << r;
    }
  }
  for (int r = 0; r < N; ++r) EXPECT_EQ(j_pose[r * 7 + 6], 0.0);
  for (int d = 0; d < 3; ++d) {
    double plus[3] = {point[0], point[1], point[2]}, minus[3] = {point[0], point[1], point[2]};
    plus[d] += h;
    minus[d] -= h;
    double r_plus[N], r_minus[N];
    const double* p_plus[2] = {pose, plus};
    const double* p_minus[2] = {pose, minus};
    cost.Evaluate(p_plus, r_plus, nullptr);
    cost.Evaluate(p_minus, r_minus, nullptr);
    for (int r = 0; r < N; ++r) {
      EXPECT_NEAR(j_point[r * 3 + d], (r_plus[r] - r_minus[r]) / (2 * h),
                  1e-4 * (1 + std::abs(j_point[r * 3 + d])));
    }
  }
}

TEST(Residuals, ReprojectionJacobiansMatchNumericDifferences) {
  ExpectAnalyticMatchesNumeric<2>(ReprojectionError({300.0, 200.0}, 1.0 / 1.2, kIntrinsics));
}

TEST(Residuals, StereoReprojectionJacobiansMatchNumericDifferences) {
  ExpectAnalyticMatchesNumeric<3>(StereoReprojectionError({300.0, 200.0, 290.0}, 1.0, kIntrinsics));
}

TEST(Residuals, ZeroAtTheTrueProjectionIncludingTheVirtualRightImage) {
  const Eigen::Isometry3d T = SomePose();
  const Eigen::Vector3d X(0.4, -0.3, 2.5);
  const Eigen::Vector3d p = T * X;
  const double u = kIntrinsics.fx * p.x() / p.z() + kIntrinsics.cx,
               v = kIntrinsics.fy * p.y() / p.z() + kIntrinsics.cy;
  double pose[7];
  PoseToParameters(T, pose);
  const double* parameters[2] = {pose, X.data()};
  double r[3];
  StereoReprojectionError({u, v, u - kIntrinsics.bf / p.z()}, 1.0, kIntrinsics)
      .Evaluate(parameters, r, nullptr);
  EXPECT_NEAR(r[0], 0, 1e-9);
  EXPECT_NEAR(r[1], 0, 1e-9);
  EXPECT_NEAR(r[2], 0, 1e-9);
}

TEST(PoseManifold, PlusIsALeftPerturbationAndMinusInvertsIt) {
  const PoseManifold m;
  double x[7], y[7], back[6];
  PoseToParameters(SomePose(), x);
  const double delta[6] = {0.01, -0.02, 0.03, 0.1, 0.2, -0.3};
  m.Plus(x, delta, y);
  m.Minus(y, x, back);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(back[i], delta[i], 1e-12);
  Eigen::Isometry3d expected = Eigen::Isometry3d::Identity();
  expected.linear() = Eigen::AngleAxisd(Eigen::Vector3d(0.01, -0.02, 0.03).norm(),
                                        Eigen::Vector3d(0.01, -0.02, 0.03).normalized())
                          .toRotationMatrix();
  expected.translation() = Eigen::Vector3d(0.1, 0.2, -0.3);
  EXPECT_TRUE(PoseFromParameters(y).isApprox(expected * SomePose(), 1e-12));
}

// An observation of X from T: (u, v) or (u, v, u_R), off the projection by (offset, −offset/2)
// px, whitened with inv_sigma2 = 1 / 1.44 (a keypoint one pyramid level up).
PointObservation Observed(const Eigen::Isometry3d& T, const Eigen::Vector3d& X, bool stereo,
                          double offset) {
  const Eigen::Vector3d p = T * X;
  PointObservation m;
  m.pixel = Eigen::Vector2d(kIntrinsics.fx * p.x() / p.z() + kIntrinsics.cx + offset,
                            kIntrinsics.fy * p.y() / p.z() + kIntrinsics.cy - 0.5 * offset);
  if (stereo) m.right_u = m.pixel.x() - kIntrinsics.bf / p.z();
  m.inv_sigma2 = 1 / 1.44;
  return m;
}

// δ away from 0 in rotation and translation: the Jacobian there involves the chart's own
// (J_l(δω)) and p − δt, which a Jacobian taken from the tangent at T(δ) gets wrong.
constexpr double kDelta[6] = {0.05, -0.03, 0.02, 0.04, -0.02, 0.03};

TEST(RobustPoseResiduals, PoseIsThePoseManifoldsPlus) {
  const std::vector<Eigen::Vector3d> points;
  const std::vector<PointObservation> observations;
  const std::vector<bool> active;
  const RobustPoseResiduals residuals(kIntrinsics, SomePose(), points, observations, active);
  double x[7], moved[7];
  PoseToParameters(SomePose(), x);
  PoseManifold().Plus(x, kDelta, moved);
  EXPECT_TRUE(residuals.Pose(kDelta).isApprox(PoseFromParameters(moved), 1e-12));
}

TEST(RobustPoseResiduals, JacobianAwayFromTheStartMatchesNumericDifferences) {
  // Within Huber's threshold (the loss is quadratic there, so the rows are the whitened
  // errors themselves): mono and with depth; and one observation switched off.
  const std::vector<Eigen::Vector3d> points = {
      {0.4, -0.3, 2.5}, {-0.6, 0.2, 3.5}, {0.1, 0.5, 1.8}, {0.0, 0.0, 2.0}};
  // Observed from where δ = kDelta puts the camera, so that the errors there are small.
  double x[7], moved[7];
  PoseToParameters(SomePose(), x);
  PoseManifold().Plus(x, kDelta, moved);
  const Eigen::Isometry3d T = PoseFromParameters(moved);
  const std::vector<PointObservation> observations = {
      Observed(T, points[0], false, 1.0), Observed(T, points[1], true, -0.8),
      Observed(T, points[2], true, 0.5), Observed(T, points[3], false, 30.0)};
  const std::vector<bool> active = {true, true, true, false};
  const RobustPoseResiduals residuals(kIntrinsics, SomePose(), points, observations, active);
  const int rows = residuals.NumResiduals();
  ASSERT_EQ(rows, 3 + 4 + 4 + 3);
  Eigen::VectorXd r(rows);
  Eigen::MatrixXd J(rows, 6);  // column-major, as TinySolver passes it
  ASSERT_TRUE(residuals(kDelta, r.data(), J.data()));
  const double h = 1e-6;
  for (int d = 0; d < 6; ++d) {
    double plus[6], minus[6];
    std::copy(kDelta, kDelta + 6, plus);
    std::copy(kDelta, kDelta + 6, minus);
    plus[d] += h;
    minus[d] -= h;
    Eigen::VectorXd r_plus(rows), r_minus(rows);
    ASSERT_TRUE(residuals(plus, r_plus.data(), nullptr));
    ASSERT_TRUE(residuals(minus, r_minus.data(), nullptr));
    for (int i = 0; i < rows; ++i) {
      EXPECT_NEAR(J(i, d), (r_plus[i] - r_minus[i]) / (2 * h), 1e-5 * (1 + std::abs(J(i, d))))
          << "row " << i << " parameter " << d;
    }
  }
  // Inside the threshold the loss's remainder rows are 0; the switched-off observation's rows
  // and Jacobian are 0.
  EXPECT_EQ(r[2], 0.0);
  EXPECT_EQ(r[6], 0.0);
  EXPECT_EQ(r.segment<3>(11).norm(), 0.0);
  EXPECT_EQ(J.bottomRows<3>().norm(), 0.0);
}

TEST(RobustPoseResiduals, SquaredResidualsSumToTheHuberCostAndBehindTheCameraFails) {
  const std::vector<Eigen::Vector3d> points = {{0.4, -0.3, 2.5}, {-0.6, 0.2, 3.5}};
  // 1 px off (inside the threshold) and 12 px off (in Huber's linear part), mono and with depth.
  const std::vector<PointObservation> observations = {Observed(SomePose(), points[0], false, 1.0),
                                                      Observed(SomePose(), points[1], true, 12.0)};
  const std::vector<bool> active = {true, true};
  const RobustPoseResiduals residuals(kIntrinsics, SomePose(), points, observations, active);
  const double zero[6] = {};
  Eigen::VectorXd r(residuals.NumResiduals());
  ASSERT_TRUE(residuals(zero, r.data(), nullptr));
  double expected = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d p = SomePose() * points[i];
    const double s = ReprojectionChi2(kIntrinsics, p, observations[i]);
    const double a2 = ReprojectionChi2Threshold(observations[i].stereo());
    expected += s <= a2 ? s : 2 * std::sqrt(a2 * s) - a2;  // Huber's ρ(s)
  }
  EXPECT_GT(ReprojectionChi2(kIntrinsics, SomePose() * points[1], observations[1]), kChi2Stereo);
  EXPECT_NEAR(r.squaredNorm(), expected, 1e-9 * expected);
  // A step that puts the first point behind the camera: the evaluation fails, every residual
  // infinite, so that TinySolver rejects the step.
  const double behind[6] = {0, 0, 0, 0, 0, -3.0};
  EXPECT_FALSE(residuals(behind, r.data(), nullptr));
  EXPECT_TRUE(std::isinf(r[0]) && std::isinf(r[r.size() - 1]));
}

}  // namespace
}  // namespace sdoslam
