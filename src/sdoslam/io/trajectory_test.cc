#include "sdoslam/io/trajectory.h"

#include <gtest/gtest.h>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

std::string ErrorOf(const std::filesystem::path& path) {
  try {
    ReadTumTrajectory(path);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Trajectory, TumRoundTripKeepsMicrosecondsAndPoses) {
  testing::TempDir dir;
  Trajectory trajectory;
  for (int k = 0; k < 5; ++k) {
    StampedPose pose;
    pose.timestamp = 1311868164.363181 + 0.033333 * k;
    pose.T_world_camera.linear() =
        Eigen::AngleAxisd(0.3 * k, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    pose.T_world_camera.translation() = Eigen::Vector3d(0.1 * k, -1.5, 2.0 + k);
    trajectory.push_back(pose);
  }
  WriteTumTrajectory(dir / "t.txt", trajectory);
  const Trajectory back = ReadTumTrajectory(dir / "t.txt");
  ASSERT_EQ(back.size(), trajectory.size());
  for (size_t k = 0; k < back.size(); ++k) {
    EXPECT_NEAR(back[k].timestamp, trajectory[k].timestamp, 5e-7);
    EXPECT_TRUE(back[k].T_world_camera.isApprox(trajectory[k].T_world_camera, 1e-8));
  }
  EXPECT_NE(testing::ReadText(dir / "t.txt").find("1311868164.363181 "), std::string::npos);
}

TEST(Trajectory, ReadsTumConventionTranslationAndQuaternionOrder) {
  testing::TempDir dir;
  // 90 degrees about z: qz = qw = sqrt(0.5). Slightly off-unit norm is normalised.
  testing::WriteText(dir / "t.txt", "# comment\n1.0 1 2 3 0 0 0.7072 0.7072\n");
  const Trajectory t = ReadTumTrajectory(dir / "t.txt");
  ASSERT_EQ(t.size(), 1u);
  EXPECT_TRUE(t[0].T_world_camera.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  const Eigen::Vector3d x_axis = t[0].T_world_camera.linear() * Eigen::Vector3d::UnitX();
  EXPECT_TRUE(x_axis.isApprox(Eigen::Vector3d::UnitY(), 1e-9));
}

TEST(Trajectory, BadRowsAreRejectedWithFileAndLine) {
  testing::TempDir dir;
  const auto path = dir / "bad.txt";
  testing::WriteText(path, "1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n");
  EXPECT_EQ(ErrorOf(path),
            path.string() + ":2: expected 8 columns (timestamp tx ty tz qx qy qz qw), found 7");
  testing::WriteText(path, "1.0 0 nan 0 0 0 0 1\n");
  EXPECT_NE(ErrorOf(path).find(":1: ty is nan"), std::string::npos);
  testing::WriteText(path, "1.0 0 0 0 0 0 0 2\n");
  EXPECT_NE(ErrorOf(path).find(":1: quaternion norm is 2"), std::string::npos);
  testing::WriteText(path, "1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n");
  EXPECT_NE(ErrorOf(path).find(":2: timestamp 1.0 does not increase"), std::string::npos);
  EXPECT_EQ(ErrorOf(dir / "missing.txt"), "file not found: " + (dir / "missing.txt").string());
}

TEST(Trajectory, KittiIsRowMajorThreeByFour) {
  testing::TempDir dir;
  StampedPose pose;
  pose.T_world_camera.linear() =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.T_world_camera.translation() = Eigen::Vector3d(4, 5, 6);
  WriteKittiTrajectory(dir / "k.txt", {pose, pose});
  std::istringstream in(testing::ReadText(dir / "k.txt"));
  std::string line;
  int lines = 0;
  while (std::getline(in, line)) {
    ++lines;
    std::istringstream fields(line);
    std::vector<double> v;
    for (double x; fields >> x;) v.push_back(x);
    ASSERT_EQ(v.size(), 12u);
    const double expected[12] = {0, -1, 0, 4, 1, 0, 0, 5, 0, 0, 1, 6};
    for (int k = 0; k < 12; ++k) EXPECT_NEAR(v[k], expected[k], 1e-9) << k;
  }
  EXPECT_EQ(lines, 2);
}

}  // namespace
}  // namespace sdoslam
