#include "sdoslam/tracking/scene_flow.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <random>

namespace sdoslam {
namespace {

// A camera at the origin looking along +z; points straight ahead at `depth`.
bool Exceeds(const SceneFlowOptions& o, const Eigen::Vector3d& flow, double depth) {
  return ExceedsSceneFlowThreshold(o, flow, Eigen::Vector3d(0, 0, depth), Eigen::Vector3d::Zero(),
                                   depth, 500.0);
}

TEST(SceneFlowThreshold, AcrossTheRayFollowsThePixelNoise) {
  SceneFlowOptions o;  // min_flow 1 cm, 3 σ, 1 px
  // Across the ray at depth z: 0.01 + 3·√2·z/500 → 1 m: 18.5 mm; 4 m: 43.9 mm.
  EXPECT_FALSE(Exceeds(o, {0.018, 0, 0}, 1.0));
  EXPECT_TRUE(Exceeds(o, {0.019, 0, 0}, 1.0));
  EXPECT_FALSE(Exceeds(o, {0.043, 0, 0}, 4.0));
  EXPECT_TRUE(Exceeds(o, {0.045, 0, 0}, 4.0));
}

TEST(SceneFlowThreshold, AlongTheRayFollowsTheDepthNoise) {
  SceneFlowOptions o;
  // σ_z(1 m) = 0.0012 + 0.0019·0.36 = 1.884 mm → limit 0.01 + 3√2·1.884 mm = 17.99 mm.
  EXPECT_FALSE(Exceeds(o, {0, 0, 0.0175}, 1.0));
  EXPECT_TRUE(Exceeds(o, {0, 0, -0.0185}, 1.0));
  // σ_z(3 m) = 0.0012 + 0.0019·6.76 = 14.04 mm → limit 69.6 mm: depth noise dominates far away,
  // while the same flow across the ray (limit 35.5 mm) is caught.
  EXPECT_FALSE(Exceeds(o, {0, 0, 0.068}, 3.0));
  EXPECT_TRUE(Exceeds(o, {0, 0, 0.071}, 3.0));
  EXPECT_TRUE(Exceeds(o, {0.068, 0, 0}, 3.0));
  EXPECT_NEAR(DepthNoiseSigma(o, 3.0), 0.014044, 1e-6);
}

TEST(SceneFlowThreshold, SplitsFlowAlongAnObliqueRay) {
  SceneFlowOptions o;
  // A point at 45° to the right, 2 m deep: a flow along its ray is judged by the depth noise
  // (σ_z(2·√2 m)), not the tighter across-ray limit.
  const Eigen::Vector3d point(2.0, 0, 2.0);
  const Eigen::Vector3d ray = point.normalized();
  const double depth = point.norm();
  const double along_limit = 0.01 + 3 * std::sqrt(2.0) * DepthNoiseSigma(o, depth);
  const double across_limit = 0.01 + 3 * std::sqrt(2.0) * depth / 500.0;
  ASSERT_GT(along_limit, across_limit + 0.01);
  EXPECT_FALSE(ExceedsSceneFlowThreshold(o, 0.95 * along_limit * ray, point,
                                         Eigen::Vector3d::Zero(), depth, 500.0));
  const Eigen::Vector3d across(ray.z(), 0, -ray.x());
  EXPECT_TRUE(ExceedsSceneFlowThreshold(o, 1.05 * across_limit * across, point,
                                        Eigen::Vector3d::Zero(), depth, 500.0));
}

TEST(ClassifyBySceneFlow, SegmentsAboveTheRatioTurnDynamicAsAWhole) {
  SceneFlowOptions o;  // 30 %, at least 3 measured features
  // Segment 0: 2 of 5 measured exceed (40 %) plus one unmeasured feature -> all 6 dynamic.
  // Segment 1: 1 of 5 exceeds (20 %) -> only that feature.
  // Segment 2: 2 of 2 exceed, too few to judge the segment -> only those two; its unmeasured
  //            feature stays static.
  // Segment 3: locked (movable class), nothing exceeds -> dynamic.
  // No segment: an exceeding feature is dynamic on its own.
  const std::vector<int> segment = {0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 2, 2, 2, 3, 3, -1, -1};
  const std::vector<uint8_t> measured = {1, 1, 1, 1, 1, 0, 1, 1, 1, 1, 1, 1, 1, 0, 1, 1, 1, 1};
  const std::vector<uint8_t> exceeds = {1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0};
  const std::vector<uint8_t> locked = {0, 0, 0, 1};
  const std::vector<uint8_t> expected = {1, 1, 1, 1, 1, 1, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 0};
  EXPECT_EQ(ClassifyBySceneFlow(o, measured, exceeds, segment, locked), expected);
  o.segment_ratio = 0.45;  // segment 0 (40 %) no longer turns as a whole
  const std::vector<uint8_t> stricter = {1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 0};
  EXPECT_EQ(ClassifyBySceneFlow(o, measured, exceeds, segment, locked), stricter);
  // Segment 0 too large to be an object: its features are judged one by one even at 30 %.
  o.segment_ratio = 0.3;
  const std::vector<uint8_t> large = {1, 0, 0, 0};
  EXPECT_EQ(ClassifyBySceneFlow(o, measured, exceeds, segment, locked, large), stricter);
}

TEST(ClassifyBySceneFlow, LargeSegmentsAreThoseAboveTheAreaShare) {
  cv::Mat segments(10, 10, CV_32S, cv::Scalar(-1));
  segments(cv::Rect(0, 0, 10, 3)).setTo(0);  // 30 %
  segments(cv::Rect(0, 3, 2, 5)).setTo(2);   // 10 %; segment 1 is absent
  const std::vector<uint8_t> expected = {1, 0, 0};
  EXPECT_EQ(LargeSegments(segments, 0.2), expected);
  EXPECT_EQ(LargeSegments(segments, 0.3), std::vector<uint8_t>(3, 0));  // not more than 30 %
}

// 60×80 random noise (seeded) and the same upsampled to 240×320: texture for Lucas–Kanade.
cv::Mat Texture(unsigned seed, cv::Mat* noise_out = nullptr) {
  std::mt19937 rng(seed);
  cv::Mat noise(60, 80, CV_8U), texture;
  for (int y = 0; y < noise.rows; ++y)
    for (int x = 0; x < noise.cols; ++x) noise.at<uint8_t>(y, x) = static_cast<uint8_t>(rng());
  cv::resize(noise, texture, cv::Size(320, 240), 0, 0, cv::INTER_CUBIC);
  if (noise_out != nullptr) *noise_out = noise;
  return texture;
}

TEST(TrackPointsBack, RecoversAKnownShift) {
  // A textured image and the same moved by (+3.5, −2.25) px: a point p of the moved (current)
  // image lies at p − (3.5, −2.25) in the previous one.
  cv::Mat noise;
  const cv::Mat previous = Texture(7, &noise);
  cv::Mat current;
  const cv::Matx23d shift(1, 0, 3.5, 0, 1, -2.25);
  cv::warpAffine(previous, current, shift, previous.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  std::vector<cv::Point2f> points = {{100, 100}, {200, 150}, {60, 180}, {1, 120}};
  std::vector<cv::Point2f> back;
  std::vector<uint8_t> found;
  // The default window (even, so its samples lie half a pixel off the point's grid) and an odd
  // one find the same shift: an even window is centred on the point too.
  for (const int window : {SceneFlowOptions{}.track_window, 15}) {
    SceneFlowOptions o;
    o.track_window = window;
    TrackPointsBack(o, current, previous, points, &back, &found);
    for (size_t i = 0; i < 3; ++i) {
      ASSERT_TRUE(found[i]) << i << " window " << window;
      EXPECT_NEAR(back[i].x, points[i].x - 3.5, 0.05) << i << " window " << window;
      EXPECT_NEAR(back[i].y, points[i].y + 2.25, 0.05) << i << " window " << window;
    }
    EXPECT_FALSE(found[3]);  // its correspondence lies outside the previous image
  }

  // Something else now covers the neighbourhood of a point (an occluder): no correspondence.
  cv::Mat other;
  cv::resize(noise.t(), other, cv::Size(60, 60), 0, 0, cv::INTER_CUBIC);
  other.copyTo(current(cv::Rect(170, 120, 60, 60)));
  TrackPointsBack(SceneFlowOptions{}, current, previous, {{200, 150}, {100, 100}}, &back, &found);
  EXPECT_FALSE(found[0]);
  EXPECT_TRUE(found[1]);
}

TEST(TrackPointsBack, StartsAtTheGuessesAndSkipsTheRoundTripOnlyNearThem) {
  const cv::Mat previous = Texture(11);
  // 30 px: beyond what one pyramid level with a 21 px window reaches from the point itself.
  cv::Mat current;
  cv::warpAffine(previous, current, cv::Matx23d(1, 0, 30.37, 0, 1, -0.61), previous.size(),
                 cv::INTER_LINEAR, cv::BORDER_REFLECT);
  const std::vector<cv::Point2f> points = {{120, 100}, {200, 150}};
  const std::vector<cv::Point2f> truth = {{89.63f, 100.61f}, {169.63f, 150.61f}};
  SceneFlowOptions o;
  o.track_levels = 0;
  std::vector<cv::Point2f> back;
  std::vector<uint8_t> found;
  TrackPointsBack(o, current, previous, points, &back, &found);
  EXPECT_FALSE(found[0] && std::abs(back[0].x - truth[0].x) < 0.2f);
  const std::vector<cv::Point2f> guesses = {{90.0f, 100.3f}, {170.1f, 150.9f}};
  TrackPointsBack(o, current, previous, points, &back, &found, &guesses);
  for (size_t i = 0; i < 2; ++i) {
    ASSERT_TRUE(found[i]) << i;
    EXPECT_NEAR(back[i].x, truth[i].x, 0.1) << i;
    EXPECT_NEAR(back[i].y, truth[i].y, 0.1) << i;
  }
  // A round trip nothing can pass: only correspondences near their guesses skip it.
  o.max_round_trip_px = 1e-6;
  TrackPointsBack(o, current, previous, points, &back, &found, &guesses);
  EXPECT_EQ(found, (std::vector<uint8_t>{1, 1}));
  const std::vector<cv::Point2f> far_guesses = {{87.6f, 100.6f}, {170.1f, 150.9f}};
  TrackPointsBack(o, current, previous, points, &back, &found, &far_guesses);
  EXPECT_EQ(found, (std::vector<uint8_t>{0, 1}));  // found 2 px from its guess: checked, fails
  o.skip_round_trip_px = 0;
  TrackPointsBack(o, current, previous, points, &back, &found, &guesses);
  EXPECT_EQ(found, (std::vector<uint8_t>{0, 0}));
}

// Pyramids built once (the checker keeps one per frame) must give exactly what OpenCV's own
// per-call pyramids give, and must not share the caller's image, which the next frame reuses.
TEST(TrackPointsBack, OnKeptPyramidsMatchesOpenCvOnImagesAndOwnsTheImage) {
  cv::Mat previous = Texture(5);
  cv::Mat current;
  cv::warpAffine(previous, current, cv::Matx23d(0.998, 0.03, 4.3, -0.03, 0.998, 1.7),
                 previous.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  std::vector<cv::Point2f> points;
  for (int y = 30; y < previous.rows - 30; y += 37)
    for (int x = 30; x < previous.cols - 30; x += 41) points.emplace_back(x + 0.3f, y + 0.6f);
  SceneFlowOptions o;
  o.max_round_trip_px = 1e9;  // only the forward call decides `found`
  o.max_track_error = 1e9;
  std::vector<cv::Point2f> opencv_back;
  std::vector<uint8_t> opencv_found;
  std::vector<float> error;
  cv::calcOpticalFlowPyrLK(
      current, previous, points, opencv_back, opencv_found, error,
      cv::Size(o.track_window, o.track_window), o.track_levels,
      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, o.track_iterations, 0.03));
  // The images handed over are views into larger buffers with room around them: the kind of
  // image OpenCV would take as a pyramid's level 0 as it is, if allowed to reuse it.
  const auto in_larger_buffer = [](const cv::Mat& image) {
    cv::Mat buffer;
    cv::copyMakeBorder(image, buffer, 40, 40, 40, 40, cv::BORDER_REFLECT);
    return buffer(cv::Rect(40, 40, image.cols, image.rows));
  };
  cv::Mat current_view = in_larger_buffer(current), previous_view = in_larger_buffer(previous);
  const LkPyramid current_pyramid = BuildLkPyramid(o, current_view);
  const LkPyramid previous_pyramid = BuildLkPyramid(o, previous_view);
  previous_view.setTo(0);  // the caller reuses its buffers
  current_view.setTo(0);
  std::vector<cv::Point2f> back;
  std::vector<uint8_t> found;
  TrackPointsBack(o, current_pyramid, previous_pyramid, points, &back, &found);
  ASSERT_EQ(back.size(), points.size());
  size_t tracked = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(found[i], opencv_found[i] && back[i].x >= 0 && back[i].y >= 0) << i;
    if (!opencv_found[i]) continue;
    ++tracked;
    EXPECT_EQ(back[i].x, opencv_back[i].x) << i;  // bit for bit
    EXPECT_EQ(back[i].y, opencv_back[i].y) << i;
  }
  EXPECT_GE(tracked, points.size() * 9 / 10);
}

// The pyramid's images are the image and cv::pyrDown of it, level after level, bit for bit
// (GridCorners takes level 1 instead of halving the image again); past the top level, none.
TEST(LkPyramidImage, IsTheImageHalvedLevelByLevel) {
  cv::Mat image;
  cv::resize(Texture(3), image, cv::Size(641, 479), 0, 0, cv::INTER_LINEAR);  // odd sizes
  SceneFlowOptions o;
  o.track_levels = 2;
  const LkPyramid pyramid = BuildLkPyramid(o, image);
  cv::Mat expected = image;
  for (int level = 0; level <= o.track_levels; ++level) {
    SCOPED_TRACE(level);
    if (level > 0) cv::pyrDown(expected, expected);
    const cv::Mat got = LkPyramidImage(pyramid, level);
    ASSERT_EQ(got.size(), expected.size());
    ASSERT_EQ(got.type(), CV_8UC1);
    EXPECT_EQ(cv::norm(got, expected, cv::NORM_INF), 0.0);
  }
  EXPECT_TRUE(LkPyramidImage(pyramid, o.track_levels + 1).empty());
}

TEST(DepthCandidates, OffersBothSurfacesOfADepthEdge) {
  cv::Mat depth(20, 20, CV_32F, cv::Scalar(3.0f));
  depth(cv::Rect(0, 0, 10, 20)).setTo(1.2f);  // a near surface on the left half
  depth.at<float>(5, 14) = 0;                 // a hole
  // On the edge: the pixel's own depth first, then the nearest and farthest of the window.
  EXPECT_EQ(DepthCandidates(depth, {9.4f, 10.f}, 2), (std::vector<float>{1.2f, 3.0f}));
  EXPECT_EQ(DepthCandidates(depth, {10.6f, 10.f}, 2), (std::vector<float>{3.0f, 1.2f}));
  // Away from the edge there is one surface; radius 0 reads the pixel alone.
  EXPECT_EQ(DepthCandidates(depth, {16.f, 10.f}, 2), std::vector<float>{3.0f});
  EXPECT_EQ(DepthCandidates(depth, {10.f, 10.f}, 0), std::vector<float>{3.0f});
  // A hole at the pixel: the window still gives the surface; outside the image: nothing.
  EXPECT_EQ(DepthCandidates(depth, {14.f, 5.f}, 1), std::vector<float>{3.0f});
  EXPECT_TRUE(DepthCandidates(depth, {14.f, 5.f}, 0).empty());
  EXPECT_TRUE(DepthCandidates(depth, {-3.f, 5.f}, 2).empty());
}

TEST(SegmentsAt, ReadsAReducedSegmentImage) {
  cv::Mat segments(120, 160, CV_32S, cv::Scalar(-1));
  segments(cv::Rect(40, 30, 20, 10)).setTo(7);
  const std::vector<int> ids =
      SegmentsAt(segments, cv::Size(640, 480), {{170, 125}, {239, 159}, {241, 125}, {5, 5}});
  EXPECT_EQ(ids, (std::vector<int>{7, 7, -1, -1}));
  EXPECT_EQ(SegmentsAt(cv::Mat(), cv::Size(640, 480), {{1, 1}}), std::vector<int>{-1});
}

TEST(SceneFlowOptions, CheckRejectsNonsense) {
  SceneFlowOptions o;
  EXPECT_NO_THROW(o.Check());
  o.segment_ratio = 1.5;
  EXPECT_THROW(o.Check(), std::exception);
  o = SceneFlowOptions{};
  o.track_window = 4;
  EXPECT_THROW(o.Check(), std::exception);
  o.track_window = 20;  // even windows are as good as odd ones
  EXPECT_NO_THROW(o.Check());
  o = SceneFlowOptions{};
  o.frame_gap = 0;
  EXPECT_THROW(o.Check(), std::exception);
  o = SceneFlowOptions{};
  o.min_established_kept = 1.5;
  EXPECT_THROW(o.Check(), std::exception);
  o = SceneFlowOptions{};
  o.established_observations = 0;
  EXPECT_THROW(o.Check(), std::exception);
  o = SceneFlowOptions{};
  o.static_motion.min_extra_samples = -1;
  EXPECT_THROW(o.Check(), std::exception);
}

}  // namespace
}  // namespace sdoslam
