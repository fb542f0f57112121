// Rolling-shutter compensation: features seen by rows exposed at different times, moved to the
// camera of the middle row's exposure.
#include "sdoslam/map/frame.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/core.hpp>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

// freiburg1's calibration (configs/tum_fr1.yaml): strong radial distortion, so the row a feature
// is detected on differs from its undistorted one by several pixels near the edges.
Camera Freiburg1() {
  return Camera(LoadCameraConfig(testing::SourceDir() / "configs" / "tum_fr1.yaml"));
}

// A camera turning at constant angular velocity while its centre moves at constant velocity:
// its pose s frame intervals after the middle row's, T(s) = [exp(s w) | s v].
Eigen::Isometry3d PoseAfter(double s, const Eigen::AngleAxisd& turn, const Eigen::Vector3d& v) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(s * turn.angle(), turn.axis()).toRotationMatrix();
  T.translation() = s * v;
  return T;
}

struct Seen {
  cv::Point2f detected;  // distorted, where the row that saw it put it
  Eigen::Vector3d in_row_camera;
};

// Where a rolling-shutter camera sees the point `x` (given in the middle row's camera): the row
// v whose exposure time puts the point on row v, found by fixed-point iteration.
Seen RollingShutterView(const Camera& camera, const Eigen::Vector3d& x, double readout_frames,
                        const Eigen::AngleAxisd& turn, const Eigen::Vector3d& v) {
  Seen seen;
  Eigen::Vector2d pixel = camera.Distort(camera.Project(x));
  for (int k = 0; k < 50; ++k) {
    const double s = (pixel.y() - 0.5 * camera.height()) / camera.height() * readout_frames;
    seen.in_row_camera = PoseAfter(s, turn, v) * x;
    pixel = camera.Distort(camera.Project(seen.in_row_camera));
  }
  seen.detected = cv::Point2f(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()));
  return seen;
}

class RollingShutterTest : public ::testing::Test {
 protected:
  RollingShutterTest()
      : camera_(Freiburg1()),
        extractor_(OrbOptions{}),
        geometry_(std::make_shared<FrameGeometry>(camera_, extractor_, 40.0, 3.0)) {}

  // A frame holding the points `x` (middle row's camera), each as the rolling shutter saw it:
  // detected position, its undistortion and the depth measured at its row's time.
  Frame FrameSeeing(const std::vector<Eigen::Vector3d>& x, bool with_depth) {
    const cv::Mat blank(camera_.height(), camera_.width(), CV_8U, cv::Scalar(0));
    Frame frame(0, 0.0, blank, cv::Mat(), geometry_, extractor_);
    std::vector<cv::Point2f> detected;
    std::vector<float> depth;
    for (const Eigen::Vector3d& p : x) {
      const Seen seen = RollingShutterView(camera_, p, kReadout, turn_, velocity_);
      detected.push_back(seen.detected);
      depth.push_back(with_depth ? static_cast<float>(seen.in_row_camera.z()) : 0.0f);
    }
    const size_t n = x.size();
    for (const cv::Point2f& d : detected) frame.keypoints.emplace_back(d, 7.0f);
    frame.undistorted = camera_.UndistortPoints(detected);
    frame.depth = depth;
    frame.right_u.assign(n, -1.0f);
    for (size_t i = 0; i < n; ++i)
      if (depth[i] > 0) frame.right_u[i] = frame.undistorted[i].x - 40.0f / depth[i];
    frame.descriptors = cv::Mat::zeros(static_cast<int>(n), 32, CV_8U);
    frame.map_points.assign(n, nullptr);
    frame.outlier.assign(n, false);
    frame.label.assign(n, 0);
    frame.colors.assign(n, cv::Vec3b(0, 0, 0));
    return frame;
  }

  // Points over the whole image (top rows to bottom rows) at 0.8-3 m.
  static std::vector<Eigen::Vector3d> Scene(const Camera& camera, double depth_scale) {
    std::vector<Eigen::Vector3d> x;
    for (int row = 30; row < 470; row += 40)
      for (int col = 40; col < 620; col += 60) {
        const double z = depth_scale * (0.8 + 0.2 * ((row + col) % 12));
        x.push_back(camera.Unproject({col, row}, z));
      }
    return x;
  }

  // The largest distance between each feature's undistorted position and the middle row
  // camera's projection of its point.
  double WorstPixelError(const Frame& frame, const std::vector<Eigen::Vector3d>& x) const {
    double worst = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      const Eigen::Vector2d p = camera_.Project(x[i]);
      worst = std::max(
          worst, (p - Eigen::Vector2d(frame.undistorted[i].x, frame.undistorted[i].y)).norm());
    }
    return worst;
  }

  static constexpr double kReadout = 0.7;  // of a frame interval
  Camera camera_;
  OrbExtractor extractor_;
  std::shared_ptr<const FrameGeometry> geometry_;
  // A fast hand-held turn: 2.5 degrees and 1.5 cm a frame (75 deg/s at 30 Hz).
  const Eigen::AngleAxisd turn_{2.5 * M_PI / 180, Eigen::Vector3d(0.3, 1.0, -0.4).normalized()};
  const Eigen::Vector3d velocity_{0.010, -0.006, 0.009};
  RowMotion Motion(double readout) const {
    return RowMotion(PoseAfter(1.0, turn_, velocity_), readout);
  }
};

TEST_F(RollingShutterTest, FeaturesWithDepthLandWhereTheMiddleRowsCameraSeesThem) {
  const std::vector<Eigen::Vector3d> x = Scene(camera_, 1.0);
  Frame frame = FrameSeeing(x, /*with_depth=*/true);
  // As detected, rows far from the middle are pixels off: what the compensation is for.
  EXPECT_GT(WorstPixelError(frame, x), 5.0);
  frame.CompensateRollingShutter(Motion(kReadout));
  EXPECT_LT(WorstPixelError(frame, x), 0.01);
  for (size_t i = 0; i < x.size(); ++i) {
    EXPECT_NEAR(frame.depth[i], x[i].z(), 1e-5) << i;
    EXPECT_NEAR(frame.right_u[i], frame.undistorted[i].x - 40.0 / frame.depth[i], 1e-3) << i;
  }
  EXPECT_TRUE(frame.row_motion.active());
  // The features can be found by position where they now are.
  const std::vector<int> near =
      frame.FeaturesInArea(frame.undistorted[7].x, frame.undistorted[7].y, 0.5);
  EXPECT_NE(std::find(near.begin(), near.end(), 7), near.end());
}

TEST_F(RollingShutterTest, TheOppositeSenseOrNoReadoutLeavesTheRowsOff) {
  const std::vector<Eigen::Vector3d> x = Scene(camera_, 1.0);
  Frame backwards = FrameSeeing(x, true);
  backwards.CompensateRollingShutter(Motion(-kReadout));
  EXPECT_GT(WorstPixelError(backwards, x), 10.0);
  Frame none = FrameSeeing(x, true);
  const std::vector<cv::Point2f> before = none.undistorted;
  none.CompensateRollingShutter(Motion(0.0));
  EXPECT_FALSE(none.row_motion.active());
  for (size_t i = 0; i < x.size(); ++i) EXPECT_EQ(none.undistorted[i], before[i]);
}

// Without depth (and in the check's rays, UndistortToMiddleRow) only the turn is undone: exact
// for distant points, where a few millimetres of translation do not show.
TEST_F(RollingShutterTest, DistantPointsTurnBackWithoutDepth) {
  const std::vector<Eigen::Vector3d> x = Scene(camera_, 200.0);
  Frame frame = FrameSeeing(x, /*with_depth=*/false);
  std::vector<cv::Point2f> detected;
  for (const cv::KeyPoint& k : frame.keypoints) detected.push_back(k.pt);
  frame.CompensateRollingShutter(Motion(kReadout));
  EXPECT_LT(WorstPixelError(frame, x), 0.05);
  for (float d : frame.depth) EXPECT_EQ(d, 0.0f);
  const std::vector<cv::Point2f> turned = UndistortToMiddleRow(camera_, Motion(kReadout), detected);
  for (size_t i = 0; i < x.size(); ++i) {
    EXPECT_NEAR(turned[i].x, frame.undistorted[i].x, 1e-3);
    EXPECT_NEAR(turned[i].y, frame.undistorted[i].y, 1e-3);
  }
  // Inactive: the plain undistortion.
  const std::vector<cv::Point2f> plain = UndistortToMiddleRow(camera_, RowMotion{}, detected);
  const std::vector<cv::Point2f> expected = camera_.UndistortPoints(detected);
  for (size_t i = 0; i < x.size(); ++i) EXPECT_EQ(plain[i], expected[i]);
}

}  // namespace
}  // namespace sdoslam
