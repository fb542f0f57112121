#include "sdoslam/mapping/local_mapper.h"

#include <gtest/gtest.h>

#include <array>
#include <atomic>

#include "sdoslam/matching/matcher.h"
#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sensor.h"
#include "sdoslam/testing/single_feature_keyframe.h"

namespace sdoslam {
namespace {

TEST(LocalMapper, TriangulatesFeaturesWithoutDepthOntoTheTrueSurface) {
  const Camera camera(synth::SyntheticCamera());
  const OrbExtractor extractor(OrbOptions{});
  auto geometry = std::make_shared<FrameGeometry>(camera, extractor, 40.0, 3.0);
  const synth::Scenario scenario =
      synth::MakeScenario("static_room", 10.0, synth::CameraMotion::kXyz);
  Map map;
  std::vector<KeyFrame*> keyframes;
  std::vector<cv::Mat> true_depth;
  for (double t : {0.0, 0.6}) {  // ~20 cm apart
    const Eigen::Isometry3d T_world_camera = synth::CameraPoseAt(scenario.motion, t, 10.0);
    const synth::RenderedView view = synth::Render(scenario.scene, t, T_world_camera, camera);
    const synth::SensorFrame sensed =
        synth::Sense(view, camera.options(), {}, 3, static_cast<int>(t * 10));
    cv::Mat depth;
    sensed.depth.convertTo(depth, CV_32F, 1.0 / 5000.0);
    if (t > 0) depth.setTo(0.0f);  // the second view has no depth: new points must be triangulated
    Frame frame(keyframes.size(), t, sensed.bgr, depth, geometry, extractor);
    frame.T_camera_world = T_world_camera.inverse();
    if (!keyframes.empty())
      SearchByProjection(frame, keyframes[0]->frame, 15.0);  // as tracking would
    KeyFrame* kf = map.AddKeyFrame(frame);
    if (keyframes.empty()) {
      // Like tracking, make depth points for the nearer features only; far ones stay free.
      std::vector<float> depths;
      for (float d : kf->frame.depth)
        if (d > 0) depths.push_back(d);
      std::nth_element(depths.begin(), depths.begin() + depths.size() / 2, depths.end());
      const float near_limit = depths[depths.size() / 2];
      for (size_t i = 0; i < kf->frame.size(); ++i) {
        if (!kf->frame.HasDepth(static_cast<int>(i)) || kf->frame.depth[i] > near_limit) continue;
        MapPoint* p = map.AddMapPoint(kf->frame.UnprojectWorld(static_cast<int>(i)), kf);
        map.AddObservation(p, kf, static_cast<int>(i));
        p->UpdateFromObservations();
      }
    }
    keyframes.push_back(kf);
    true_depth.push_back(view.depth);
  }
  LocalMapper mapper(&map, LocalMapperOptions{});
  mapper.Process(keyframes[0]);
  const size_t before = map.points().size();
  const MappingResult result = mapper.Process(keyframes[1]);
  EXPECT_GT(result.triangulated_points, 50);
  // Each new point, seen from the second camera, lies at the rendered depth of its pixel.
  int checked = 0, on_surface = 0;
  for (const auto& [id, point] : map.points()) {
    if (id < before || point->bad) continue;
    const auto it = point->observations.find(keyframes[1]->id);
    if (it == point->observations.end()) continue;
    const cv::Point2f pixel =
        keyframes[1]->frame.keypoints[static_cast<size_t>(it->second.second)].pt;
    const float z_true = true_depth[1].at<float>(cvRound(pixel.y), cvRound(pixel.x));
    const double z = (keyframes[1]->pose() * point->position).z();
    ++checked;
    on_surface += std::abs(z - z_true) < 0.05 * z_true;
  }
  ASSERT_GT(checked, 50);
  EXPECT_GT(on_surface, 0.9 * checked);
}

// Options under which every keyframe gets its local BA: the tests below judge the last one's,
// and the eight keyframes come on consecutive frames (mapping.min_frames_between_local_ba would
// leave the last unadjusted).
LocalMapperOptions EveryKeyFrameAdjusted() {
  LocalMapperOptions options;
  options.min_frames_between_local_ba = 0;
  return options;
}

// Eight keyframes 4 cm apart in the rendered room, each tracked against the one before and
// mapped with `options`; returns the last keyframe's mapping result. `waiting`: handed to
// Process as the flag of a keyframe waiting to be mapped. `all` (optional): every keyframe's
// result, in order.
MappingResult MapEightViewsOfTheRoom(const LocalMapperOptions& options,
                                     const std::atomic<bool>* waiting = nullptr,
                                     std::vector<MappingResult>* all = nullptr) {
  const Camera camera(synth::SyntheticCamera());
  const OrbExtractor extractor(OrbOptions{});
  auto geometry = std::make_shared<FrameGeometry>(camera, extractor, 40.0, 3.0);
  const synth::Scenario scenario =
      synth::MakeScenario("static_room", 10.0, synth::CameraMotion::kXyz);
  Map map;
  LocalMapper mapper(&map, options);
  KeyFrame* previous = nullptr;
  MappingResult result;
  for (int i = 0; i < 8; ++i) {
    const double t = 0.12 * i;
    const Eigen::Isometry3d T_world_camera = synth::CameraPoseAt(scenario.motion, t, 10.0);
    const synth::RenderedView view = synth::Render(scenario.scene, t, T_world_camera, camera);
    const synth::SensorFrame sensed = synth::Sense(view, camera.options(), {}, 3, i);
    cv::Mat depth;
    sensed.depth.convertTo(depth, CV_32F, 1.0 / 5000.0);
    Frame frame(static_cast<uint64_t>(i), t, sensed.bgr, depth, geometry, extractor);
    frame.T_camera_world = T_world_camera.inverse();
    if (previous != nullptr) SearchByProjection(frame, previous->frame, 15.0);
    KeyFrame* kf = map.AddKeyFrame(frame);
    for (size_t f = 0; f < kf->frame.size(); ++f) {  // new points where depth is measured
      if (kf->frame.map_points[f] != nullptr || !kf->frame.HasDepth(static_cast<int>(f))) continue;
      MapPoint* p = map.AddMapPoint(kf->frame.UnprojectWorld(static_cast<int>(f)), kf);
      map.AddObservation(p, kf, static_cast<int>(f));
      p->UpdateFromObservations();
    }
    result = mapper.Process(kf, nullptr, waiting);
    if (all != nullptr) all->push_back(result);
    previous = kf;
  }
  return result;
}

TEST(LocalMapper, TheLocalAdjustmentStaysWithinItsObservationBudget) {
  const MappingResult unbounded = MapEightViewsOfTheRoom(EveryKeyFrameAdjusted());
  ASSERT_EQ(unbounded.local_keyframes, 8);  // the whole small map is the window
  ASSERT_GT(unbounded.ba.observations, 2000);
  LocalMapperOptions budgeted = EveryKeyFrameAdjusted();
  budgeted.max_ba_observations = unbounded.ba.observations / 2;
  const MappingResult bounded = MapEightViewsOfTheRoom(budgeted);
  EXPECT_LE(bounded.ba.observations, budgeted.max_ba_observations);
  EXPECT_GT(bounded.ba.observations, budgeted.max_ba_observations / 2);
  EXPECT_LT(bounded.local_keyframes, 8);
  // The neighbours the budget leaves out of the window are held fixed, not forgotten.
  EXPECT_GE(bounded.fixed_keyframes, 1);
  EXPECT_GT(bounded.ba.iterations, 0);
}

// Threaded mapping skips the local BA while another keyframe waits (ORB-SLAM2's rule), unless
// told not to; a lowered flag runs it as usual.
TEST(LocalMapper, AKeyframeWaitingSkipsTheLocalAdjustmentUnlessTurnedOff) {
  const std::atomic<bool> raised{true}, lowered{false};
  const MappingResult skipped = MapEightViewsOfTheRoom(EveryKeyFrameAdjusted(), &raised);
  EXPECT_TRUE(skipped.ba_skipped);
  EXPECT_EQ(skipped.ba.iterations, 0);
  EXPECT_EQ(skipped.ba.observations, 0);
  const MappingResult adjusted = MapEightViewsOfTheRoom(EveryKeyFrameAdjusted(), &lowered);
  EXPECT_FALSE(adjusted.ba_skipped);
  EXPECT_FALSE(adjusted.ba.stopped);
  EXPECT_GT(adjusted.ba.iterations, 2);
  LocalMapperOptions never_stop = EveryKeyFrameAdjusted();
  never_stop.stop_ba_for_new_keyframe = false;
  const MappingResult kept = MapEightViewsOfTheRoom(never_stop, &raised);
  EXPECT_FALSE(kept.ba_skipped);
  EXPECT_FALSE(kept.ba.stopped);
  EXPECT_EQ(kept.ba.iterations, adjusted.ba.iterations);
}

// Keyframes that come close together share one local BA: with min_frames_between_local_ba = 3,
// keyframes of consecutive frames are adjusted on every third one once adjustment starts (the
// map's third keyframe); the others are mapped (triangulated, fused) but not adjusted.
TEST(LocalMapper, KeyframesSoonAfterAnAdjustedOneAreNotAdjusted) {
  std::vector<MappingResult> every, spaced;
  MapEightViewsOfTheRoom(EveryKeyFrameAdjusted(), nullptr, &every);
  LocalMapperOptions options;
  options.min_frames_between_local_ba = 3;
  MapEightViewsOfTheRoom(options, nullptr, &spaced);
  ASSERT_EQ(every.size(), 8u);
  ASSERT_EQ(spaced.size(), 8u);
  for (size_t i = 0; i < 8; ++i) {
    const bool adjusts = i >= 2;  // a BA needs more than two good keyframes
    EXPECT_EQ(every[i].ba.iterations > 0, adjusts) << "keyframe " << i;
    const bool spaced_adjusts = adjusts && (i - 2) % 3 == 0;  // frames 2, 5
    EXPECT_EQ(spaced[i].ba.iterations > 0, spaced_adjusts) << "keyframe " << i;
    EXPECT_EQ(spaced[i].ba_spaced, adjusts && !spaced_adjusts) << "keyframe " << i;
    EXPECT_FALSE(spaced[i].ba_skipped) << "keyframe " << i;  // nothing waited: none gave way
  }
  // Mapping itself goes on for the keyframes left unadjusted.
  EXPECT_GT(spaced[3].fused_points + spaced[3].triangulated_points + spaced[4].fused_points +
                spaced[4].triangulated_points,
            0);
}

// Keyframes that see the place from the same spot, none of them redundant by its points: each
// sees one point that the keyframe before made and makes one of its own (so each has a parent,
// and each point two observers). The crowd rule keeps at most `crowded_keyframes` of them, the
// newest (equal shares), and spares the first keyframe, a distant one and one that looks
// another way.
TEST(LocalMapper, ACrowdedViewpointKeepsAtMostItsQuota) {
  const Camera camera(synth::SyntheticCamera());
  const OrbExtractor extractor(OrbOptions{});
  auto geometry = std::make_shared<FrameGeometry>(camera, extractor, 40.0, 3.0);
  for (const double distance : {0.0, 0.3}) {
    SCOPED_TRACE(distance);
    LocalMapperOptions options;
    options.transient_observations = 0;  // two observers count (ORB-SLAM2's rule)
    options.crowded_distance = distance;
    options.crowded_angle_deg = 15;
    options.crowded_keyframes = 3;
    // Two observations per keyframe cannot hold a pose: the adjustment is left out.
    options.bundle_adjustment.iterations = options.bundle_adjustment.refine_iterations = 0;
    Map map;
    LocalMapper mapper(&map, options);
    cv::RNG rng(7);  // random descriptors lie far apart, so nothing is fused
    std::vector<KeyFrame*> keyframes;
    MapPoint* previous_point = nullptr;
    for (size_t i = 0; i < 10; ++i) {
      // 1 cm steps along x, except keyframe 4 (1 m off) and keyframe 5 (turned by 25 degrees).
      Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
      T_world_camera.translation() =
          Eigen::Vector3d(i == 4 ? 1.0 : 0.01 * static_cast<double>(i), 0, 0);
      if (i == 5)
        T_world_camera.linear() =
            Eigen::AngleAxisd(-25 * M_PI / 180, Eigen::Vector3d::UnitY()).matrix();
      cv::Mat descriptors(2, 32, CV_8U);
      rng.fill(descriptors, cv::RNG::UNIFORM, 0, 256);
      // Feature 0 sees the previous keyframe's point (where it projects), feature 1 makes a new
      // point 2 m ahead of the first keyframe.
      const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
      const Eigen::Vector3d new_point(0.01 * static_cast<double>(i), 0, 2);
      const Eigen::Vector3d seen = previous_point ? previous_point->position : new_point;
      std::vector<cv::Point2f> pixels;
      std::vector<float> depths;
      for (const Eigen::Vector3d& world : std::array<Eigen::Vector3d, 2>{seen, new_point}) {
        const Eigen::Vector3d in_camera = T_camera_world * world;
        const Eigen::Vector2d pixel = camera.Project(in_camera);
        ASSERT_TRUE(in_camera.z() > 0 && pixel.x() > 0 && pixel.x() < 640) << i;
        pixels.emplace_back(static_cast<float>(pixel.x()), static_cast<float>(pixel.y()));
        depths.push_back(static_cast<float>(in_camera.z()));
      }
      KeyFrame* kf = testing::AddKeyFrameWithFeatures(map, i, pixels, depths, descriptors, geometry,
                                                      extractor, T_camera_world);
      kf->frame.map_points[0] = previous_point;  // InsertKeyFrame adds the observation
      previous_point = map.AddMapPoint(new_point, kf);
      map.AddObservation(previous_point, kf, 1);
      mapper.Process(kf);
      keyframes.push_back(kf);
    }
    std::vector<size_t> alive;
    for (size_t i = 0; i < keyframes.size(); ++i)
      if (!keyframes[i]->bad) alive.push_back(i);
    if (distance == 0) {
      EXPECT_EQ(alive.size(), keyframes.size());  // the rule is off, and nothing is redundant
    } else {
      EXPECT_EQ(alive, (std::vector<size_t>{0, 4, 5, 7, 8, 9}));
    }
  }
}

}  // namespace
}  // namespace sdoslam
