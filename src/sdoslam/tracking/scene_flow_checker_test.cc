#include "sdoslam/tracking/scene_flow_checker.h"

#include <gtest/gtest.h>

#include <map>
#include <opencv2/imgproc.hpp>

#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sensor.h"

namespace sdoslam {
namespace {

constexpr double kDuration = 10.0;
constexpr double kNow = 2.0;  // seconds: the checked frame
constexpr int kGap = 5;       // SceneFlowOptions::frame_gap
constexpr double kFrameTime = 1 / 30.0;
constexpr uint16_t kBox = 1;  // the box's object id
constexpr int kBoxSegment = 0, kStaticSegment = 1;

// The static room seen by a camera on the half-sphere, and a textured box 1.3 m ahead of the
// checked frame's camera that slides sideways at `box_speed` m/s (0: it stands still), rendered
// with sensor noise at the checked frame and the kGap frames before it, with their true poses.
// Segments: the box is segment 0; a patch of the room on the left of the image, clear of the
// box, is segment 1; the rest has none.
class SceneFlowCheckerTest : public ::testing::Test {
 protected:
  void Render(double box_speed) {
    const Camera camera(synth::SyntheticCamera());
    extractor_ = std::make_unique<OrbExtractor>(OrbOptions{});
    geometry_ = std::make_shared<FrameGeometry>(camera, *extractor_, 40.0, 3.0);
    synth::Scenario scenario =
        synth::MakeScenario("static_room", kDuration, synth::CameraMotion::kHalfsphere);
    const Eigen::Isometry3d T_world_now = synth::CameraPoseAt(scenario.motion, kNow, kDuration);
    const Eigen::Vector3d sideways = T_world_now.linear() * Eigen::Vector3d::UnitX();
    scenario.scene.objects.push_back(synth::RigidBox(
        kBox, "box",
        [=](double t) {
          Eigen::Isometry3d T = T_world_now * synth::Pose({0.0, 0.05, 1.3});
          T.translation() += box_speed * (t - kNow) * sideways;
          return T;
        },
        {0.15, 0.15, 0.15}, {0.8f, 0.5f, 0.3f}, 7));
    for (int k = kGap; k >= 0; --k) {
      const double t = kNow - k * kFrameTime;
      const Eigen::Isometry3d T_world_camera = synth::CameraPoseAt(scenario.motion, t, kDuration);
      const synth::RenderedView view = synth::Render(scenario.scene, t, T_world_camera, camera);
      const synth::SensorFrame sensed =
          synth::Sense(view, camera.options(), {}, 1, static_cast<int>(kGap - k));
      View v;
      v.index = static_cast<size_t>(kGap - k);
      v.bgr = sensed.bgr;
      sensed.depth.convertTo(v.depth, CV_32F, 1.0 / 5000.0);
      cv::cvtColor(sensed.bgr, v.gray, cv::COLOR_BGR2GRAY);
      v.instance = view.instance;
      v.T_camera_world = T_world_camera.inverse();
      views_.push_back(v);
    }
    const View& now = views_.back();
    segments_ = cv::Mat(now.instance.size(), CV_32S, cv::Scalar(-1));
    segments_.setTo(kBoxSegment, now.instance == kBox);
    cv::Mat patch = cv::Mat::zeros(now.instance.size(), CV_8U);
    patch(cv::Rect(0, 0, now.instance.cols / 4, now.instance.rows)).setTo(1);
    ASSERT_EQ(cv::countNonZero(patch & (now.instance == kBox)), 0) << "the box reaches the patch";
    segments_.setTo(kStaticSegment, patch);
  }

  struct View {
    size_t index;
    cv::Mat bgr, gray, depth, instance;
    Eigen::Isometry3d T_camera_world;
  };

  ConsistencyInput Input(const View& view) const { return {view.gray, view.depth, segments_, {}}; }

  // The checked frame at its true pose, every feature with depth matched to a landmark made
  // from it (observed by one keyframe, so none is established).
  Frame MatchedFrame() {
    const View& now = views_.back();
    Frame frame(now.index, kNow, now.bgr, now.depth, geometry_, *extractor_);
    frame.T_camera_world = now.T_camera_world;
    KeyFrame* kf = map_.AddKeyFrame(frame);
    for (size_t i = 0; i < frame.size(); ++i) {
      if (!frame.HasDepth(static_cast<int>(i))) continue;
      MapPoint* p = map_.AddMapPoint(frame.UnprojectWorld(static_cast<int>(i)), kf);
      map_.AddObservation(p, kf, static_cast<int>(i));
      frame.map_points[i] = p;
    }
    return frame;
  }

  // Remembers the frames before the checked one (at `shift` away from their true poses).
  void RememberPast(SceneFlowChecker* checker,
                    const Eigen::Isometry3d& shift = Eigen::Isometry3d::Identity()) const {
    for (size_t k = 0; k + 1 < views_.size(); ++k)
      checker->RememberFrame(views_[k].index, true, views_[k].T_camera_world * shift,
                             Input(views_[k]));
  }

  // Features with depth on the box and on the room, at least 4 px from the box's outline
  // (those on it see both); `outline`: the others.
  void Split(const Frame& frame, std::vector<size_t>* box, std::vector<size_t>* room,
             std::vector<size_t>* outline = nullptr) const {
    const cv::Mat on_box = views_.back().instance == kBox;
    cv::Mat inside, near;
    cv::erode(on_box, inside, cv::Mat::ones(9, 9, CV_8U));
    cv::dilate(on_box, near, cv::Mat::ones(9, 9, CV_8U));
    for (size_t i = 0; i < frame.size(); ++i) {
      if (!frame.HasDepth(static_cast<int>(i))) continue;
      const cv::Point p(cvRound(frame.keypoints[i].pt.x), cvRound(frame.keypoints[i].pt.y));
      if (inside.at<uint8_t>(p) != 0) {
        box->push_back(i);
      } else if (near.at<uint8_t>(p) == 0) {
        room->push_back(i);
      } else if (outline != nullptr) {
        outline->push_back(i);
      }
    }
  }

  static double ShareJudgedDynamic(const Frame& frame, const std::vector<size_t>& features) {
    int dynamic = 0;
    for (size_t i : features) {
      const bool judged = frame.label[i] == kSceneFlowLabel;
      EXPECT_EQ(judged, frame.map_points[i] == nullptr) << "feature " << i;
      dynamic += judged;
    }
    return static_cast<double>(dynamic) / static_cast<double>(features.size());
  }

  // Keeps the pose (the true one) and counts the frame's inliers; counts its calls.
  RefinePose KeepPose() {
    return [this](Frame& frame) {
      ++refinements_;
      int inliers = 0;
      for (size_t i = 0; i < frame.size(); ++i) {
        if (frame.map_points[i] == nullptr) continue;
        frame.outlier[i] = false;
        ++inliers;
      }
      return inliers;
    };
  }

  std::unique_ptr<OrbExtractor> extractor_;
  std::shared_ptr<FrameGeometry> geometry_;
  std::vector<View> views_;  // oldest first; the last is the checked frame
  cv::Mat segments_;
  Map map_;
  MapLockReleaser no_lock_;
  int refinements_ = 0;
};

TEST_F(SceneFlowCheckerTest, TheSlidingBoxIsDynamicAndTheRoomIsNot) {
  Render(0.4);  // 6.7 cm over the 5 frames; the threshold across the ray at 1.3 m is 2 cm
  SceneFlowChecker checker(&map_, SceneFlowOptions{});
  RememberPast(&checker);
  Frame frame = MatchedFrame();
  std::vector<size_t> box, room, outline;
  Split(frame, &box, &room, &outline);
  ASSERT_GE(box.size(), 20u);
  ASSERT_GE(room.size(), 200u);
  std::map<const MapPoint*, size_t> feature_of;
  for (size_t i = 0; i < frame.size(); ++i) feature_of[frame.map_points[i]] = i;

  TrackingResult result;
  const std::vector<MapPoint*> judged =
      checker.CheckSceneFlow(frame, Input(views_.back()), KeepPose(), no_lock_, &result);

  EXPECT_FALSE(result.check_reverted);
  EXPECT_FALSE(result.check_replaced);  // the true pose explains the room
  EXPECT_TRUE(frame.T_camera_world.isApprox(views_.back().T_camera_world));
  EXPECT_GE(result.check_iterations, 1);
  EXPECT_GE(refinements_, 1);  // the pose was re-estimated without the box
  EXPECT_GT(result.check_measured, static_cast<int>(room.size()) / 2);
  EXPECT_GE(ShareJudgedDynamic(frame, box), 0.9);
  EXPECT_LE(ShareJudgedDynamic(frame, room), 0.03);
  EXPECT_EQ(result.check_segments, std::vector<int>{kBoxSegment});
  // The landmarks returned are those of the features judged dynamic, nearly all on the box or
  // its outline.
  EXPECT_EQ(static_cast<int>(judged.size()), result.check_dynamic);
  int on_box = 0;
  for (const MapPoint* p : judged) {
    const size_t i = feature_of.at(p);
    EXPECT_EQ(frame.label[i], kSceneFlowLabel);
    on_box += std::find(box.begin(), box.end(), i) != box.end() ||
              std::find(outline.begin(), outline.end(), i) != outline.end();
  }
  EXPECT_GE(on_box, static_cast<int>(0.95 * judged.size()));
}

TEST_F(SceneFlowCheckerTest, AStandingBoxIsStatic) {
  Render(0.0);
  SceneFlowChecker checker(&map_, SceneFlowOptions{});
  RememberPast(&checker);
  Frame frame = MatchedFrame();
  std::vector<size_t> box, room;
  Split(frame, &box, &room);
  ASSERT_GE(box.size(), 20u);

  TrackingResult result;
  checker.CheckSceneFlow(frame, Input(views_.back()), KeepPose(), no_lock_, &result);

  EXPECT_FALSE(result.check_reverted);
  EXPECT_GE(result.check_iterations, 1);
  EXPECT_LE(ShareJudgedDynamic(frame, box), 0.05);
  EXPECT_LE(ShareJudgedDynamic(frame, room), 0.03);
  EXPECT_TRUE(result.check_segments.empty());
}

// The front end's motion selection is a hypothesis the check tests (the paper's quasi-dynamic
// features): features it took out (label 2) on the sliding box stay out, those on a patch of the
// room and on a box that stands return to static. Never a caller's mask (oracle), nor with the
// option off.
TEST_F(SceneFlowCheckerTest, MotionSelectedFeaturesReturnWhenTheyAreStatic) {
  for (const double box_speed : {0.4, 0.0}) {
    views_.clear();
    Render(box_speed);
    for (const int variant : {0, 1, 2}) {  // rechecked; a caller's mask; the option off
      SCOPED_TRACE(::testing::Message() << "box speed " << box_speed << ", variant " << variant);
      SceneFlowOptions options;
      options.recheck_motion_selected = variant != 2;
      SceneFlowChecker checker(&map_, options);
      RememberPast(&checker);
      Frame frame = MatchedFrame();
      std::vector<size_t> box, room, patch;
      Split(frame, &box, &room);
      const int patch_columns = views_.back().instance.cols / 4;
      for (size_t i : room) {
        if (frame.keypoints[i].pt.x < patch_columns - 4) patch.push_back(i);
      }
      ASSERT_GE(box.size(), 20u);
      ASSERT_GE(patch.size(), 20u);
      for (size_t i : box) frame.MarkDynamic(static_cast<int>(i), kMotionSelectedLabel);
      for (size_t i : patch) frame.MarkDynamic(static_cast<int>(i), kMotionSelectedLabel);
      ConsistencyInput input = Input(views_.back());
      input.motion_selected_recheckable = variant != 1;

      TrackingResult result;
      checker.CheckSceneFlow(frame, input, KeepPose(), no_lock_, &result);

      ASSERT_FALSE(result.check_reverted);
      auto share_static = [&](const std::vector<size_t>& features) {
        int returned = 0;
        for (size_t i : features) {
          EXPECT_TRUE(frame.label[i] == 0 || frame.label[i] == kMotionSelectedLabel) << i;
          returned += frame.IsStatic(static_cast<int>(i));
        }
        return static_cast<double>(returned) / static_cast<double>(features.size());
      };
      const double box_static = share_static(box), patch_static = share_static(patch);
      if (variant != 0) {
        EXPECT_EQ(box_static, 0.0);
        EXPECT_EQ(patch_static, 0.0);
        EXPECT_EQ(result.check_readmitted, 0);
        continue;
      }
      EXPECT_GE(patch_static, 0.8);
      if (box_speed > 0) {
        EXPECT_LE(box_static, 0.05);
      } else {
        EXPECT_GE(box_static, 0.8);
      }
      int returned = 0;
      for (size_t i = 0; i < frame.size(); ++i) {
        returned += (std::find(box.begin(), box.end(), i) != box.end() ||
                     std::find(patch.begin(), patch.end(), i) != patch.end()) &&
                    frame.IsStatic(static_cast<int>(i));
      }
      EXPECT_EQ(result.check_readmitted, returned);
      // What returns makes points again; it had no part in the pose.
      for (size_t i : patch) {
        if (frame.IsStatic(static_cast<int>(i))) {
          EXPECT_EQ(frame.map_points[i], nullptr);
        }
      }
    }
  }
}

TEST_F(SceneFlowCheckerTest, NeedsATrackedFrameBeforeAndForgetsAllButTheLastFrameGap) {
  Render(0.4);
  SceneFlowOptions options;
  SceneFlowChecker checker(&map_, options);
  for (size_t k = 0; k + 1 < views_.size(); ++k)
    checker.RememberFrame(views_[k].index, false, views_[k].T_camera_world, Input(views_[k]));
  EXPECT_EQ(checker.remembered(), static_cast<size_t>(options.frame_gap));
  checker.RememberFrame(99, true, views_[0].T_camera_world, Input(views_[0]));
  EXPECT_EQ(checker.remembered(), static_cast<size_t>(options.frame_gap));

  // Remembered frames that were not tracked, or come after it, are no past to check against.
  Frame frame = MatchedFrame();
  const Frame before = frame;
  TrackingResult result;
  EXPECT_TRUE(
      checker.CheckSceneFlow(frame, Input(views_.back()), KeepPose(), no_lock_, &result).empty());
  EXPECT_EQ(result.check_iterations, 0);
  EXPECT_EQ(result.check_dynamic, 0);
  EXPECT_EQ(frame.map_points, before.map_points);
  EXPECT_EQ(frame.label, before.label);
}

TEST_F(SceneFlowCheckerTest, RememberedPosesFollowTheirKeyframeWhenTheMapMoves) {
  Render(0.4);
  // The past frames were tracked against a keyframe 0.2 m off its true place; since then local
  // BA (or loop closing) has moved it there, and the checked frame is tracked in the moved map.
  const Eigen::Isometry3d shift = synth::Pose({0.2, 0.0, 0.0});
  Frame first(views_[0].index, kNow - kGap * kFrameTime, views_[0].bgr, views_[0].depth, geometry_,
              *extractor_);
  first.T_camera_world = views_[0].T_camera_world * shift;
  KeyFrame* reference = map_.AddKeyFrame(first);
  auto remember = [&](SceneFlowChecker* checker) {
    for (size_t k = 0; k + 1 < views_.size(); ++k)
      checker->RememberFrame(views_[k].index, true, views_[k].T_camera_world * shift,
                             Input(views_[k]), reference);
  };
  SceneFlowChecker stale(&map_, SceneFlowOptions{}), following(&map_, SceneFlowOptions{});
  remember(&stale);
  remember(&following);
  reference->frame.T_camera_world = views_[0].T_camera_world;
  {
    Frame frame = MatchedFrame();
    std::vector<size_t> box, room;
    Split(frame, &box, &room);
    TrackingResult result;
    stale.CheckSceneFlow(frame, Input(views_.back()), KeepPose(), no_lock_, &result);
    // Seen from the poses as tracked the whole room moves: the check drops its result, moves
    // the pose to the old map's, or calls the room dynamic.
    EXPECT_TRUE(result.check_reverted || result.check_replaced ||
                ShareJudgedDynamic(frame, room) > 0.5);
  }
  following.FollowMap();
  Frame frame = MatchedFrame();
  std::vector<size_t> box, room;
  Split(frame, &box, &room);
  TrackingResult result;
  following.CheckSceneFlow(frame, Input(views_.back()), KeepPose(), no_lock_, &result);
  EXPECT_FALSE(result.check_reverted);
  EXPECT_FALSE(result.check_replaced);
  EXPECT_GE(ShareJudgedDynamic(frame, box), 0.9);
  EXPECT_LE(ShareJudgedDynamic(frame, room), 0.03);
  // A culled reference hands its frames on through its parent.
  KeyFrame* parent = map_.AddKeyFrame(first);
  parent->frame.T_camera_world = synth::Pose({0.0, 0.1, 0.0}) * views_[0].T_camera_world;
  reference->bad = true;
  reference->parent = parent;
  reference->T_camera_parent = views_[0].T_camera_world * parent->pose().inverse();
  following.FollowMap();
  Frame again = MatchedFrame();
  TrackingResult after_culling;
  following.CheckSceneFlow(again, Input(views_.back()), KeepPose(), no_lock_, &after_culling);
  EXPECT_FALSE(after_culling.check_replaced);
  EXPECT_LE(ShareJudgedDynamic(again, room), 0.03);
}

TEST_F(SceneFlowCheckerTest, CheckLandmarksCullsTheMovedAndTheSeenThroughAndClearsTheMatched) {
  Render(0.4);
  SceneFlowOptions options;
  options.cull_after = 2;
  options.seen_through_max_share = 1;  // a handful of landmarks here: any share counts
  SceneFlowChecker checker(&map_, options);
  RememberPast(&checker);
  Frame frame = MatchedFrame();
  TrackingResult result;
  const ConsistencyInput input = Input(views_.back());
  const std::vector<MapPoint*> judged =
      checker.CheckSceneFlow(frame, input, KeepPose(), no_lock_, &result);
  ASSERT_GE(judged.size(), 10u);

  // Unmatched local landmarks on a ray of the room where the depth window is full: one halfway
  // to the surface (the depth image sees through it), one on it, one behind it.
  const View& now = views_.back();
  const int r = options.depth_window_radius;
  cv::Point pixel(-1, -1);
  for (int v = 2 * r; v < now.depth.rows - 2 * r && pixel.x < 0; v += 3) {
    for (int u = 2 * r; u < now.depth.cols / 4 && pixel.x < 0; u += 3) {
      const cv::Mat window = now.depth(cv::Rect(u - r, v - r, 2 * r + 1, 2 * r + 1));
      double lo, hi;
      cv::minMaxLoc(window, &lo, &hi);
      if (lo > 0.5 && hi - lo < 0.05) pixel = {u, v};
    }
  }
  ASSERT_GE(pixel.x, 0) << "no flat patch of the room";
  const Camera& camera = geometry_->camera;
  const double z = now.depth.at<float>(pixel);
  const Eigen::Isometry3d T_world_camera = frame.T_camera_world.inverse();
  KeyFrame* other = map_.AddKeyFrame(frame);  // their observations
  auto landmark = [&](double depth, int feature) {
    MapPoint* p = map_.AddMapPoint(
        T_world_camera * camera.Unproject(Eigen::Vector2d(pixel.x, pixel.y), depth), other);
    map_.AddObservation(p, other, feature);
    return p;
  };
  MapPoint* in_front = landmark(0.5 * z, 0);
  MapPoint* on = landmark(z, 1);
  MapPoint* behind = landmark(1.5 * z, 2);
  // A matched inlier that was judged inconsistent before, and one judged dynamic before.
  MapPoint* inlier = nullptr;
  for (MapPoint* p : frame.map_points) {
    if (p != nullptr && std::find(judged.begin(), judged.end(), p) == judged.end()) inlier = p;
  }
  ASSERT_NE(inlier, nullptr);
  inlier->inconsistent = 1;
  judged[0]->inconsistent = 1;

  checker.CheckLandmarks(frame, input, judged, {in_front, on, behind, inlier}, &result);

  EXPECT_EQ(in_front->inconsistent, 1);
  EXPECT_FALSE(in_front->bad);
  EXPECT_EQ(on->inconsistent, 0);
  EXPECT_EQ(behind->inconsistent, 0);
  EXPECT_EQ(inlier->inconsistent, 0);
  EXPECT_TRUE(judged[0]->bad);  // its second strike
  for (size_t k = 1; k < judged.size(); ++k) {
    EXPECT_EQ(judged[k]->inconsistent, 1);
    EXPECT_FALSE(judged[k]->bad);
  }
  EXPECT_EQ(result.culled_points, 1);

  // A second frame like it: the seen-through landmark is struck again and culled.
  TrackingResult again;
  checker.CheckLandmarks(frame, input, {}, {in_front, on, behind}, &again);
  EXPECT_TRUE(in_front->bad);
  EXPECT_FALSE(on->bad);
  EXPECT_EQ(again.culled_points, 1);

  // Where more than seen_through_max_share of the landmarks in view are seen through (the pose
  // is off), none is struck.
  SceneFlowOptions strict = options;
  strict.seen_through_max_share = 0.5;
  SceneFlowChecker suspicious(&map_, strict);
  MapPoint* first = landmark(0.5 * z, 3);
  MapPoint* second = landmark(0.5 * z, 4);
  TrackingResult quiet;
  suspicious.CheckLandmarks(frame, input, {}, {first, second, on}, &quiet);
  EXPECT_EQ(first->inconsistent, 0);
  EXPECT_EQ(second->inconsistent, 0);
  // One of three is within the share: struck.
  suspicious.CheckLandmarks(frame, input, {}, {first, on, behind}, &quiet);
  EXPECT_EQ(first->inconsistent, 1);
}

}  // namespace
}  // namespace sdoslam
