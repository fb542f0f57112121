#include "sdoslam/core/geometry.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

namespace sdoslam {
namespace {

const PinholeIntrinsics kK{535.4, 539.2, 320.1, 247.6, 40.0};

TEST(Geometry, HatIsTheCrossProduct) {
  const Eigen::Vector3d v(0.3, -1.7, 2.2);
  for (const Eigen::Vector3d& x :
       {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(-0.4, 2.5, 0.9)}) {
    EXPECT_TRUE((Hat(v) * x).isApprox(v.cross(x), 1e-15)) << x.transpose();
  }
  EXPECT_TRUE(Hat(v).transpose().isApprox(-Hat(v)));  // skew-symmetric
  EXPECT_TRUE((Hat(v) * v).isZero(1e-15));
}

// A point 2 m ahead whose projection is off the observation by known pixels.
TEST(Geometry, ReprojectionChi2IsTheWhitenedSquaredError) {
  const Eigen::Vector3d p(0.2, -0.1, 2.0);
  const double u = kK.fx * 0.2 / 2.0 + kK.cx, v = kK.fy * -0.1 / 2.0 + kK.cy;
  const double ur = u - kK.bf / 2.0;  // 20 px left of u
  PointObservation m;
  m.pixel = Eigen::Vector2d(u + 3.0, v - 4.0);  // 5 px off
  m.inv_sigma2 = 1.0;
  EXPECT_FALSE(m.stereo());
  EXPECT_NEAR(ReprojectionChi2(kK, p, m), 25.0, 1e-9);
  // A keypoint two levels up the pyramid (scale 1.2²) has a wider σ: the same pixels weigh less.
  m.inv_sigma2 = 1.0 / (1.44 * 1.44);
  EXPECT_NEAR(ReprojectionChi2(kK, p, m), 25.0 / (1.44 * 1.44), 1e-9);
  // With a right coordinate its error adds a third term.
  m.inv_sigma2 = 1.0;
  m.right_u = ur - 2.0;
  EXPECT_TRUE(m.stereo());
  EXPECT_NEAR(ReprojectionChi2(kK, p, m), 25.0 + 4.0, 1e-9);
  // At the exact projection the error is zero, mono or stereo.
  m.pixel = Eigen::Vector2d(u, v);
  m.right_u = ur;
  EXPECT_NEAR(ReprojectionChi2(kK, p, m), 0.0, 1e-18);
}

TEST(Geometry, Chi2ThresholdFollowsTheRightCoordinate) {
  EXPECT_EQ(ReprojectionChi2Threshold(false), 5.991);  // χ²(2), 95 %
  EXPECT_EQ(ReprojectionChi2Threshold(true), 7.815);   // χ²(3), 95 %
  PointObservation m;
  EXPECT_EQ(ReprojectionChi2Threshold(m.stereo()), kChi2Mono);  // right_u = -1: no depth
  m.right_u = 0.0;  // a right coordinate at the image's left edge is still one
  EXPECT_EQ(ReprojectionChi2Threshold(m.stereo()), kChi2Stereo);
  // The same error, χ² = 2.6² = 6.76 between the two thresholds, passes with a right coordinate
  // (its u_R agrees) and fails without one.
  const Eigen::Vector3d p(0.0, 0.0, 2.0);
  m.pixel = Eigen::Vector2d(kK.cx + 2.6, kK.cy);
  m.right_u = kK.cx - kK.bf / 2.0;
  EXPECT_NEAR(ReprojectionChi2(kK, p, m), 6.76, 1e-9);
  EXPECT_LE(ReprojectionChi2(kK, p, m), ReprojectionChi2Threshold(m.stereo()));
  m.right_u = -1.0;
  EXPECT_NEAR(ReprojectionChi2(kK, p, m), 6.76, 1e-9);
  EXPECT_GT(ReprojectionChi2(kK, p, m), ReprojectionChi2Threshold(m.stereo()));
}

}  // namespace
}  // namespace sdoslam
