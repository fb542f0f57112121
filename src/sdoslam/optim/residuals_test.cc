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

}  // namespace
}  // namespace sdoslam
