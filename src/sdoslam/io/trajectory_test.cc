#include "sdoslam/io/trajectory.h"

#include <gtest/gtest.h>
#include <sys/stat.h>

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
  // Finite but absurd: its square overflowed ATE to inf, printed with exit code 0.
  testing::WriteText(path, "1.0 0 0 0 0 0 0 1\n2.0 1e308 0 0 0 0 0 1\n");
  EXPECT_NE(ErrorOf(path).find(":2: tx is 1e+308 m (more than"), std::string::npos) << ErrorOf(path);
  testing::WriteText(path, "1.0 0 0 -2e6 0 0 0 1\n");
  EXPECT_NE(ErrorOf(path).find(":1: tz is -2e+06 m"), std::string::npos);
  testing::WriteText(path, "1.0 0 0 0 0 0 0 2\n");
  EXPECT_NE(ErrorOf(path).find(":1: quaternion norm is 2"), std::string::npos);
  testing::WriteText(path, "1.0 0 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 1\n");
  EXPECT_NE(ErrorOf(path).find(":2: timestamp 1.000000 does not increase"), std::string::npos);
  EXPECT_EQ(ErrorOf(dir / "missing.txt"), "file not found: " + (dir / "missing.txt").string());
  // A timestamp beyond any time in seconds (1e308 was read as such; nanoseconds would be too).
  testing::WriteText(path, "1.0 0 0 0 0 0 0 1\n1e308 0 0 0 0 0 0 1\n");
  EXPECT_NE(ErrorOf(path).find(path.string() + ":2: timestamp 1e308 is not a time in seconds"),
            std::string::npos)
      << ErrorOf(path);
  testing::WriteText(path, "1311868164000000000 0 0 0 0 0 0 1\n");
  EXPECT_NE(ErrorOf(path).find(":1: timestamp 1311868164000000000 is not a time in seconds"),
            std::string::npos);
  // A ground truth that is a FIFO blocked `eval`; a folder is no trajectory either.
  ASSERT_EQ(mkfifo((dir / "fifo.txt").c_str(), 0600), 0);
  EXPECT_EQ(ErrorOf(dir / "fifo.txt"), (dir / "fifo.txt").string() + ": not a regular file");
  EXPECT_EQ(ErrorOf(dir.path()), dir.path().string() + ": not a regular file");
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

namespace sdoslam {
namespace {

TEST(Trajectory, InterpolatesBetweenSamplesAndRefusesGapsAndTheOutside) {
  // A camera turning about z at 1 rad/s while moving along x at 2 m/s, sampled at 10 Hz.
  auto truth = [](double t) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(t, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(2 * t, 1, 0);
    return T;
  };
  Trajectory samples;
  for (int k = 0; k <= 10; ++k) samples.push_back({0.1 * k, truth(0.1 * k)});
  samples.erase(samples.begin() + 6);  // a drop-out between 0.5 and 0.7 s
  for (double t : {0.0, 0.03, 0.25, 0.49, 0.6, 0.71, 1.0}) {
    const auto T = InterpolatePose(samples, t, 0.15);
    ASSERT_TRUE(T.has_value()) << t;
    EXPECT_LT((T->translation() - truth(t).translation()).norm(), 1e-9) << t;
    EXPECT_LT(Eigen::AngleAxisd(T->linear().transpose() * truth(t).linear()).angle(), 1e-9) << t;
  }
  EXPECT_FALSE(InterpolatePose(samples, 0.6, 0.08).has_value());   // 0.1 s to either sample
  EXPECT_TRUE(InterpolatePose(samples, 0.45, 0.08).has_value());   // before the drop-out
  EXPECT_FALSE(InterpolatePose(samples, -0.01, 1.0).has_value());  // before the first sample
  EXPECT_FALSE(InterpolatePose(samples, 1.01, 1.0).has_value());   // after the last
}

}  // namespace
}  // namespace sdoslam
