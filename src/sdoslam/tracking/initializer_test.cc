#include "sdoslam/tracking/initializer.h"

#include <gtest/gtest.h>

#include "sdoslam/testing/room_frames.h"

namespace sdoslam {
namespace {

class InitializerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const testing::RoomFrames::View view = room_.Render(1.0, 0);
    bgr_ = view.bgr;
    depth_ = view.depth;
  }

  Frame MakeFrame(const cv::Mat& depth) const {
    Frame frame(3, 0.1, bgr_, depth, room_.geometry(), room_.extractor());
    frame.T_camera_world = synth::Pose({1, 2, 3});
    return frame;
  }

  testing::RoomFrames room_;
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
