#include "sdoslam/optim/rigid_ransac.h"

#include <gtest/gtest.h>

#include <functional>
#include <random>
#include <string>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

Eigen::Isometry3d TrueTransform() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(0.6, Eigen::Vector3d(0.2, 1, -0.3).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.8, -0.2, 0.5);
  return T;
}

// Matches between two RGB-D frames: inliers are points of A seen again in B with depth noise
// that grows with z² (and a little lateral noise); outliers are wrong matches, B's point
// anywhere in B's view.
struct Matches {
  std::vector<Eigen::Vector3d> a, b;
  std::vector<bool> is_inlier;
};

Matches MakeMatches(int count, double outlier_fraction, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> xy(-2, 2), depth(1, 4.5), unit(0, 1);
  std::normal_distribution<double> gauss(0, 1);
  const Eigen::Isometry3d T = TrueTransform();
  Matches m;
  const int outliers = static_cast<int>(std::lround(outlier_fraction * count));
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d b_true(xy(rng), xy(rng), depth(rng));
    Eigen::Vector3d b = b_true;
    const double z2 = b.z() * b.z();
    b += Eigen::Vector3d(0.002 * gauss(rng), 0.002 * gauss(rng), 1.425e-3 * z2 * gauss(rng));
    const bool inlier = i >= outliers;  // outliers first: the order must not matter
    if (!inlier) b = Eigen::Vector3d(xy(rng), xy(rng), depth(rng));
    m.a.push_back(T.inverse() * b_true);
    m.b.push_back(b);
    m.is_inlier.push_back(inlier);
  }
  return m;
}

void ExpectRecovers(double outlier_fraction) {
  const Matches m = MakeMatches(300, outlier_fraction, 7);
  const RigidRansacResult r = EstimateRigidTransformRansac(m.a, m.b);
  ASSERT_TRUE(r.found);
  const Eigen::Isometry3d T = TrueTransform();
  EXPECT_LT((r.T_b_a.translation() - T.translation()).norm(), 0.01);
  EXPECT_LT(Eigen::AngleAxisd(r.T_b_a.linear() * T.linear().transpose()).angle(), 0.005);
  ASSERT_EQ(r.inlier.size(), m.a.size());
  int true_positive = 0, flagged = 0, inliers = 0;
  for (size_t i = 0; i < m.a.size(); ++i) {
    true_positive += r.inlier[i] && m.is_inlier[i];
    flagged += r.inlier[i];
    inliers += m.is_inlier[i];
  }
  EXPECT_EQ(r.num_inliers, flagged);
  EXPECT_GT(static_cast<double>(true_positive) / flagged, 0.95) << "precision";
  EXPECT_GT(static_cast<double>(true_positive) / inliers, 0.95) << "recall";
  EXPECT_LE(r.iterations, RigidRansacOptions().max_iterations);
}

TEST(RigidRansac, RecoversATransformWithHalfTheMatchesWrong) { ExpectRecovers(0.5); }

TEST(RigidRansac, RecoversATransformWithSeventyPercentWrong) { ExpectRecovers(0.7); }

TEST(RigidRansac, StopsEarlyWhenAllMatchesAreRight) {
  const Matches m = MakeMatches(100, 0.0, 3);
  const RigidRansacResult r = EstimateRigidTransformRansac(m.a, m.b);
  ASSERT_TRUE(r.found);
  EXPECT_GT(r.num_inliers, 95);
  EXPECT_LT(r.iterations, 10);  // a few samples suffice at ~100 % inliers
}

TEST(RigidRansac, FindsNothingInFewerThanThreeMatches) {
  const Matches m = MakeMatches(2, 0.0, 1);
  const RigidRansacResult r = EstimateRigidTransformRansac(m.a, m.b);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.inlier, std::vector<bool>(2, false));
  EXPECT_FALSE(EstimateRigidTransformRansac({}, {}).found);
}

TEST(RigidRansac, FindsNothingWhenAllPointsAreOnALine) {
  // The rotation about the line is free: any hypothesis would be arbitrary.
  std::vector<Eigen::Vector3d> a, b;
  const Eigen::Isometry3d T = TrueTransform();
  for (int i = 0; i < 50; ++i) {
    a.emplace_back(-1 + 0.04 * i, 0.5 - 0.01 * i, 2 + 0.03 * i);
    b.push_back(T * a.back());
  }
  const RigidRansacResult r = EstimateRigidTransformRansac(a, b);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.num_inliers, 0);
  EXPECT_TRUE(r.T_b_a.isApprox(Eigen::Isometry3d::Identity()));
}

TEST(RigidRansac, FindsNothingWithTooFewInliers) {
  const Matches m = MakeMatches(100, 0.88, 5);  // 12 right matches, 20 needed
  const RigidRansacResult r = EstimateRigidTransformRansac(m.a, m.b);
  EXPECT_FALSE(r.found);
  EXPECT_EQ(r.num_inliers, 0);
  // With a lower bar the same matches are enough.
  RigidRansacOptions options;
  options.min_inliers = 10;
  options.max_iterations = 5000;
  EXPECT_TRUE(EstimateRigidTransformRansac(m.a, m.b, options).found);
}

TEST(RigidRansac, IsDeterministicForASeed) {
  const Matches m = MakeMatches(200, 0.6, 11);
  RigidRansacOptions options;
  options.seed = 42;
  const RigidRansacResult r1 = EstimateRigidTransformRansac(m.a, m.b, options);
  const RigidRansacResult r2 = EstimateRigidTransformRansac(m.a, m.b, options);
  ASSERT_TRUE(r1.found);
  EXPECT_EQ(r1.T_b_a.matrix(), r2.T_b_a.matrix());  // bit for bit
  EXPECT_EQ(r1.inlier, r2.inlier);
  EXPECT_EQ(r1.num_inliers, r2.num_inliers);
  EXPECT_EQ(r1.iterations, r2.iterations);
  // Another seed draws other samples but finds the same transform.
  options.seed = 43;
  const RigidRansacResult r3 = EstimateRigidTransformRansac(m.a, m.b, options);
  ASSERT_TRUE(r3.found);
  EXPECT_LT((r3.T_b_a.translation() - r1.T_b_a.translation()).norm(), 0.01);
}

TEST(RigidRansac, RejectsBadInput) {
  const std::vector<Eigen::Vector3d> three(3, Eigen::Vector3d(0, 0, 1)), two(2);
  testing::ExpectErrorMentioning([&] { EstimateRigidTransformRansac(three, two); },
                                 "3 points in A but 2 in B");
  RigidRansacOptions options;
  options.confidence = 1.0;
  testing::ExpectErrorMentioning([&] { options.Check(); }, "confidence");
  options = {};
  options.min_inliers = 2;
  testing::ExpectErrorMentioning([&] { EstimateRigidTransformRansac(three, three, options); },
                                 "min_inliers");
  options = {};
  options.inlier_base = 0;
  testing::ExpectErrorMentioning([&] { options.Check(); }, "inlier_base");
  options = {};
  options.max_iterations = 0;
  testing::ExpectErrorMentioning([&] { options.Check(); }, "max_iterations");
  EXPECT_NO_THROW(RigidRansacOptions().Check());
}

}  // namespace
}  // namespace sdoslam
