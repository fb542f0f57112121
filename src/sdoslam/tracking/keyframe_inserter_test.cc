#include "sdoslam/tracking/keyframe_inserter.h"

#include <gtest/gtest.h>

#include "sdoslam/testing/room_frames.h"

namespace sdoslam {
namespace {

// One rendering of the static room; its features' matches, labels and depths are then set by
// hand. Close: depth at most 3 m (the geometry's close_depth).
class KeyFrameInserterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const testing::RoomFrames::View view = room_.Render(1.0, 0);
    frame_ =
        std::make_unique<Frame>(40, 4.0, view.bgr, view.depth, room_.geometry(), room_.extractor());
    frame_->T_camera_world = view.T_world_camera.inverse();
    for (size_t i = 0; i < frame_->size(); ++i) {
      if (IsClose(i)) close_.push_back(i);
    }
    placeholder_ = other_map_.AddMapPoint(Eigen::Vector3d::Zero(), other_map_.AddKeyFrame(*frame_));
  }

  bool IsClose(size_t i) const {
    return frame_->HasDepth(static_cast<int>(i)) &&
           frame_->depth[i] <= room_.geometry()->close_depth;
  }
  // Every close feature matched (to a placeholder: the decision only looks at whether there is
  // a match), all others not.
  void TrackAllClose() {
    std::fill(frame_->map_points.begin(), frame_->map_points.end(), nullptr);
    for (size_t i : close_) frame_->map_points[i] = placeholder_;
  }

  // Reference 200 matches; the last keyframe 5 frames ago; local mapping busy.
  KeyFrameDecisionInput Input(int inliers) const {
    return {.inliers = inliers,
            .reference_matches = 200,
            .last_keyframe_frame = frame_->index - 5,
            .mapping_idle = false};
  }

  testing::RoomFrames room_;
  std::unique_ptr<Frame> frame_;
  std::vector<size_t> close_;
  Map other_map_;
  MapPoint* placeholder_ = nullptr;  // of other_map_
  TrackerOptions options_;
};

// What frames.csv logs of the decision: close features with depth, matched as inliers or not;
// far ones, those without depth and outliers' matches counted as the decision counts them.
TEST_F(KeyFrameInserterTest, ClosePointsAreCountedAsTheDecisionSeesThem) {
  ASSERT_GE(close_.size(), 4u);
  TrackAllClose();
  ClosePoints close = CountClosePoints(*frame_);
  EXPECT_EQ(close.tracked, static_cast<int>(close_.size()));
  EXPECT_EQ(close.untracked, 0);
  frame_->outlier[close_[0]] = true;  // an outlier's match does not count as tracked
  frame_->map_points[close_[1]] = nullptr;
  for (size_t i = 0; i < frame_->size(); ++i) {
    if (!IsClose(i)) frame_->map_points[i] = placeholder_;  // far or no depth: never counted
  }
  close = CountClosePoints(*frame_);
  EXPECT_EQ(close.tracked, static_cast<int>(close_.size()) - 2);
  EXPECT_EQ(close.untracked, 2);
}

TEST_F(KeyFrameInserterTest, AFrameThatTracksMostOfTheReferenceNeedsNone) {
  ASSERT_GE(close_.size(), static_cast<size_t>(options_.min_close_points));
  TrackAllClose();
  KeyFrameDecisionInput input = Input(190);  // above 0.75 · 200
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, input));
  input.mapping_idle = true;
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, input));
  input.last_keyframe_frame = frame_->index - 100;
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, input));
}

TEST_F(KeyFrameInserterTest, BelowTheReferenceRatioOneIsMadeWhenMappingIdlesOrAfterLong) {
  TrackAllClose();
  KeyFrameDecisionInput input = Input(140);  // below 0.75 · 200, above 0.25 · 200
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, input));
  input.mapping_idle = true;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, input));
  input.mapping_idle = false;
  input.last_keyframe_frame =
      frame_->index - static_cast<size_t>(options_.max_frames_between_keyframes) + 1;
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, input));
  input.last_keyframe_frame = frame_->index - options_.max_frames_between_keyframes;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, input));
}

TEST_F(KeyFrameInserterTest, WeakTrackingNeedsOneAtOnceButNotWithFifteenInliersOrFewer) {
  TrackAllClose();
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, Input(40)));  // below 0.25 · 200
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, Input(16)));
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, Input(15)));
}

TEST_F(KeyFrameInserterTest, TooFewTrackedClosePointsNeedOne) {
  // The frame tracks 190 of the reference's 200 (no ratio trigger), but fewer than
  // min_close_points of its close points: a keyframe when more than close_points_to_create
  // others could be made.
  const size_t can_make = static_cast<size_t>(options_.close_points_to_create);
  ASSERT_GT(close_.size(), can_make + 1);
  ASSERT_LT(close_.size() - can_make, static_cast<size_t>(options_.min_close_points));
  TrackAllClose();
  for (size_t k = 0; k < can_make; ++k) frame_->map_points[close_[k]] = nullptr;
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, Input(190)));
  frame_->map_points[close_[can_make]] = nullptr;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, Input(190)));
  // Matched outliers count as untracked.
  TrackAllClose();
  for (size_t k = 0; k <= can_make; ++k) frame_->outlier[close_[k]] = true;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, Input(190)));
  // Features labelled dynamic do not count: nothing could be made from them.
  std::fill(frame_->outlier.begin(), frame_->outlier.end(), false);
  TrackAllClose();
  for (size_t k = 0; k <= can_make; ++k) {
    frame_->map_points[close_[k]] = nullptr;
    frame_->label[close_[k]] = 1;
  }
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, Input(190)));
}

TEST_F(KeyFrameInserterTest, SoonAfterAKeyFrameOnlyFewInliersMakeOne) {
  options_.min_frames_between_keyframes = 3;
  const size_t spacing = 3;
  // Too few tracked close points (as in TooFewTrackedClosePointsNeedOne), the reference ratio
  // missed too (140 of 200), mapping idle: every trigger but few inliers.
  TrackAllClose();
  for (size_t k = 0; k <= static_cast<size_t>(options_.close_points_to_create); ++k)
    frame_->map_points[close_[k]] = nullptr;
  KeyFrameDecisionInput input = Input(140);
  input.mapping_idle = true;
  input.last_keyframe_frame = frame_->index - spacing + 1;
  EXPECT_FALSE(NeedKeyFrame(options_, *frame_, input));
  input.last_keyframe_frame = frame_->index - spacing;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, input));
  // The map's second keyframe is made at once.
  input.last_keyframe_frame = frame_->index - 1;
  input.good_keyframes = 1;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, input));
  // Fewer inliers than a quarter of the reference's matches: one at once, even the frame after.
  input = Input(40);
  input.last_keyframe_frame = frame_->index - 1;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, input));
  // 0: ORB-SLAM2's rule, a keyframe the frame after the last.
  options_.min_frames_between_keyframes = 0;
  input = Input(140);
  input.mapping_idle = true;
  input.last_keyframe_frame = frame_->index - 1;
  EXPECT_TRUE(NeedKeyFrame(options_, *frame_, input));
}

TEST_F(KeyFrameInserterTest, ReferenceMatchesCountPointsSeenByEnoughKeyFrames) {
  Map map;
  KeyFrame* a = map.AddKeyFrame(*frame_);
  MapPoint* once = map.AddMapPoint(Eigen::Vector3d(0, 0, 1), a);
  map.AddObservation(once, a, 0);
  EXPECT_EQ(ReferenceMatches(map, *a), 1);  // one keyframe: seen once is enough
  KeyFrame* b = map.AddKeyFrame(*frame_);
  MapPoint* twice = map.AddMapPoint(Eigen::Vector3d(0, 0, 2), a);
  map.AddObservation(twice, a, 1);
  map.AddObservation(twice, b, 1);
  EXPECT_EQ(ReferenceMatches(map, *a), 1);  // two keyframes: twice
  KeyFrame* c = map.AddKeyFrame(*frame_);
  EXPECT_EQ(ReferenceMatches(map, *a), 0);  // more: three times
  map.AddObservation(twice, c, 1);
  EXPECT_EQ(ReferenceMatches(map, *a), 1);
  map.AddObservation(once, b, 0);
  map.AddObservation(once, c, 0);
  EXPECT_EQ(ReferenceMatches(map, *a), 2);
}

TEST_F(KeyFrameInserterTest, CreateKeyFrameMakesThePointsOfTheCloseStaticFeatures) {
  Map map;
  std::fill(frame_->map_points.begin(), frame_->map_points.end(), nullptr);
  // A feature already matched keeps its point; one labelled dynamic gets none.
  KeyFrame* earlier = map.AddKeyFrame(*frame_);
  MapPoint* existing = map.AddMapPoint(Eigen::Vector3d(0, 0, 1), earlier);
  map.AddObservation(existing, earlier, static_cast<int>(close_[0]));
  frame_->map_points[close_[0]] = existing;
  frame_->label[close_[1]] = 1;
  const size_t points_before = map.points().size();
  ASSERT_GT(close_.size(), static_cast<size_t>(options_.min_close_points) + 2);
  size_t far = 0;
  for (size_t i = 0; i < frame_->size(); ++i)
    far += frame_->HasDepth(static_cast<int>(i)) && !IsClose(i);
  ASSERT_GT(far, 0u);

  KeyFrame* kf = CreateKeyFrame(&map, options_, *frame_);

  ASSERT_NE(kf, nullptr);
  EXPECT_NE(kf, earlier);
  EXPECT_TRUE(kf->pose().isApprox(frame_->T_camera_world));
  EXPECT_EQ(kf->frame.map_points[close_[0]], existing);
  EXPECT_EQ(kf->frame.map_points[close_[1]], nullptr);
  for (size_t k = 2; k < close_.size(); ++k) {
    const MapPoint* p = kf->frame.map_points[close_[k]];
    ASSERT_NE(p, nullptr) << "close feature " << close_[k];
    EXPECT_EQ(p->observations.count(kf->id), 1u);
    EXPECT_LT((p->position - frame_->UnprojectWorld(static_cast<int>(close_[k]))).norm(), 1e-9);
  }
  // There are more than min_close_points close ones: beyond 3 m only the nearest feature (the
  // one gone through when the count is checked) gets a point.
  EXPECT_EQ(map.points().size(), points_before + (close_.size() - 2) + 1);
}

// Features the front end keeps unmapped (seen moving lately) are static, but make no point.
TEST_F(KeyFrameInserterTest, UnmappableFeaturesMakeNoPoints) {
  Map map;
  std::fill(frame_->map_points.begin(), frame_->map_points.end(), nullptr);
  // The left half of the image is unmapped.
  cv::Mat unmapped(frame_->geometry->camera.height(), frame_->geometry->camera.width(), CV_8U,
                   cv::Scalar(0));
  unmapped.colRange(0, unmapped.cols / 2).setTo(255);
  frame_->SetUnmappable(unmapped);
  size_t left = 0;
  for (size_t i : close_) left += frame_->keypoints[i].pt.x < unmapped.cols / 2 - 1;
  ASSERT_GT(left, 10u);
  KeyFrame* kf = CreateKeyFrame(&map, options_, *frame_);
  size_t left_points = 0, right_points = 0;
  for (size_t i = 0; i < kf->frame.size(); ++i) {
    if (kf->frame.map_points[i] == nullptr) continue;
    (kf->frame.keypoints[i].pt.x < unmapped.cols / 2 - 1 ? left_points : right_points)++;
    EXPECT_TRUE(kf->frame.IsStatic(static_cast<int>(i)));
  }
  EXPECT_EQ(left_points, 0u);
  EXPECT_GT(right_points, 10u);
  for (size_t i : close_) EXPECT_TRUE(frame_->IsStatic(static_cast<int>(i)));  // still tracked
  frame_->SetUnmappable(cv::Mat());  // cleared: every feature may make a point again
  for (size_t i = 0; i < frame_->size(); ++i) EXPECT_TRUE(frame_->MakesPoints(static_cast<int>(i)));
}

TEST_F(KeyFrameInserterTest, FarFeaturesMakeUpMinClosePoints) {
  Map map;
  std::fill(frame_->map_points.begin(), frame_->map_points.end(), nullptr);
  // Only 20 close features: the nearest far ones make up the rest.
  for (size_t k = 20; k < close_.size(); ++k) frame_->label[close_[k]] = 1;
  int static_with_depth = 0;
  for (size_t i = 0; i < frame_->size(); ++i)
    static_with_depth +=
        frame_->HasDepth(static_cast<int>(i)) && frame_->IsStatic(static_cast<int>(i));
  ASSERT_GT(static_with_depth, options_.min_close_points + 1);
  CreateKeyFrame(&map, options_, *frame_);
  EXPECT_EQ(map.points().size(), static_cast<size_t>(options_.min_close_points + 1));
}

}  // namespace
}  // namespace sdoslam
