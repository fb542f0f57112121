// Loop closing end to end lives in slam/system_test.cc (the long loop); here, its options.
#include "sdoslam/loop/loop_closer.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

TEST(LoopClosingOptionsTest, RejectsImpossibleSettings) {
  LoopClosingOptions o;
  EXPECT_NO_THROW(o.Check());
  o.min_projected_inliers = o.min_inliers - 1;
  EXPECT_THROW(o.Check(), Error);
  o = LoopClosingOptions{};
  o.min_matches = 2;
  EXPECT_THROW(o.Check(), Error);
  o = LoopClosingOptions{};
  o.verify_neighbours = -1;
  EXPECT_THROW(o.Check(), Error);
}

// A loop is closed when it moves the keyframe's centre by 1 cm or turns it by 1 degree; less
// is within what the map already agrees on.
TEST(LoopClosingTest, ClosesOnlyALoopThatCorrectsEnough) {
  const LoopClosingOptions o;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(0.5, -1.0, 2.0);
  const Eigen::Vector3d centre = pose.inverse().translation();
  // The corrected pose with the camera's centre moved by `shift` (world) and the camera turned
  // by `degrees` about its own optical axis.
  auto corrected = [&](const Eigen::Vector3d& shift, double degrees) {
    Eigen::Isometry3d T = pose;
    T.linear() =
        Eigen::AngleAxisd(degrees * M_PI / 180.0, Eigen::Vector3d::UnitZ()) * pose.linear();
    T.translation() = -T.linear() * (centre + shift);
    return T;
  };
  EXPECT_FALSE(CorrectsEnough(o, pose, pose));
  EXPECT_FALSE(CorrectsEnough(o, pose, corrected(Eigen::Vector3d(0.006, 0, 0.006), 0.7)));
  EXPECT_TRUE(CorrectsEnough(o, pose, corrected(Eigen::Vector3d(0, 0.011, 0), 0)));
  EXPECT_TRUE(CorrectsEnough(o, pose, corrected(Eigen::Vector3d::Zero(), 1.2)));
  // A turn about the camera's centre moves no centre, whatever the world position.
  EXPECT_FALSE(CorrectsEnough(o, pose, corrected(Eigen::Vector3d::Zero(), 0.9)));
  LoopClosingOptions every = o;
  every.min_correction_m = 0;
  every.min_correction_deg = 0;
  EXPECT_TRUE(CorrectsEnough(every, pose, pose));
  every.min_correction_m = -0.1;
  EXPECT_THROW(every.Check(), Error);
}

}  // namespace
}  // namespace sdoslam
