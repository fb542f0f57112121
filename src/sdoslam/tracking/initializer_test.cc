#include "sdoslam/tracking/initializer.h"

#include <gtest/gtest.h>

#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sensor.h"

namespace sdoslam {
namespace {

class InitializerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const Camera camera(synth::SyntheticCamera());
    extractor_ = std::make_unique<OrbExtractor>(OrbOptions{});
    geometry_ = std::make_shared<FrameGeometry>(camera, *extractor_, 40.0, 3.0);
    const synth::Scenario scenario =
        synth::MakeScenario("static_room", 10.0, synth::CameraMotion::kHalfsphere);
    const Eigen::Isometry3d T_world_camera = synth::CameraPoseAt(scenario.motion, 1.0, 10.0);
    const synth::RenderedView view = synth::Render(scenario.scene, 1.0, T_world_camera, camera);
    const synth::SensorFrame sensed = synth::Sense(view, camera.options(), {}, 1, 0);
    sensed.depth.convertTo(depth_, CV_32F, 1.0 / 5000.0);
    bgr_ = sensed.bgr;
  }

  Frame MakeFrame(const cv::Mat& depth) const {
    Frame frame(3, 0.1, bgr_, depth, geometry_, *extractor_);
    frame.T_camera_world = synth::Pose({1, 2, 3});
    return frame;
  }

  std::unique_ptr<OrbExtractor> extractor_;
  std::shared_ptr<FrameGeometry> geometry_;
  cv::Mat bgr_, depth_;
};

TEST_F(InitializerTest, TheFirstFrameDefinesTheWorldWithAPointPerStaticFeatureWithDepth) {
  Frame frame = MakeFrame(depth_);
  size_t dynamic = 0;
  while (!frame.HasDepth(static_cast<int>(dynamic))) ++dynamic;
  frame.label[dynamic] = 1;  // no point
  int expected = 0;
  for (size_t i = 0; i < frame.size(); ++i)
    expected += frame.HasDepth(static_cast<int>(i)) && frame.IsStatic(static_cast<int>(i));
  ASSERT_GE(expected, TrackerOptions{}.min_initial_depth_features);
  Map map;

  KeyFrame* kf = InitializeMap(&map, TrackerOptions{}, frame);

  ASSERT_NE(kf, nullptr);
  EXPECT_TRUE(kf->pose().isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_TRUE(frame.T_camera_world.isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_EQ(map.keyframes().size(), 1u);
  EXPECT_EQ(static_cast<int>(map.points().size()), expected);
  EXPECT_EQ(kf->frame.map_points[dynamic], nullptr);
  EXPECT_EQ(kf->TrackedPoints(1), expected);
  for (size_t i = 0; i < kf->frame.size(); ++i) {
    const MapPoint* p = kf->frame.map_points[i];
    if (p == nullptr) continue;
    // In the first camera's frame.
    EXPECT_NEAR(p->position.z(), frame.depth[i], 1e-6);
  }
}

TEST_F(InitializerTest, TooFewFeaturesWithDepthLeaveTheMapEmpty) {
  // Depth only in the top tenth of the image.
  cv::Mat depth = cv::Mat::zeros(depth_.size(), CV_32F);
  depth_(cv::Rect(0, 0, depth_.cols, depth_.rows / 10))
      .copyTo(depth(cv::Rect(0, 0, depth_.cols, depth_.rows / 10)));
  Frame frame = MakeFrame(depth);
  Map map;
  EXPECT_EQ(InitializeMap(&map, TrackerOptions{}, frame), nullptr);
  EXPECT_TRUE(map.keyframes().empty());
  EXPECT_TRUE(map.points().empty());
  EXPECT_TRUE(frame.T_camera_world.isApprox(synth::Pose({1, 2, 3})));
}

}  // namespace
}  // namespace sdoslam
