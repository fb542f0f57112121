#include "sdoslam/tracking/scene_flow_checker.h"

#include <algorithm>
#include <cmath>
#include <set>

#include "sdoslam/tracking/static_motion.h"

namespace sdoslam {

SceneFlowChecker::SceneFlowChecker(Map* map, const SceneFlowOptions& options)
    : map_(map), options_(options) {}

void SceneFlowChecker::RememberFrame(size_t index, bool tracked,
                                     const Eigen::Isometry3d& T_camera_world,
                                     const ConsistencyInput& input, const KeyFrame* reference,
                                     const RowMotion& row_motion) {
  // Copied (the pyramid holds its own copy of the image): the caller may reuse its buffers for
  // the next frame.
  CurrentPyramid(index, input.gray);
  history_.push_back({index, std::move(current_pyramid_), input.depth.clone(), T_camera_world,
                      tracked, reference,
                      reference != nullptr ? T_camera_world * reference->pose().inverse()
                                           : Eigen::Isometry3d::Identity(),
                      row_motion});
  current_pyramid_.clear();
  while (static_cast<int>(history_.size()) > options_.frame_gap) history_.pop_front();
}

const LkPyramid& SceneFlowChecker::CurrentPyramid(size_t index, const cv::Mat& gray) {
  if (current_pyramid_.empty() || current_index_ != index) {
    current_pyramid_ = BuildLkPyramid(options_, gray);
    current_index_ = index;
  }
  return current_pyramid_;
}

const SceneFlowChecker::PastFrame* SceneFlowChecker::TrackedPastFrame(size_t index) const {
  for (const PastFrame& p : history_) {
    if (p.tracked && p.index < index) return &p;
  }
  return nullptr;
}

void SceneFlowChecker::CompensateRecentFrames(size_t index, const RowMotion& motion) {
  for (PastFrame& past : history_) {
    if (!past.row_motion.active() && past.index + 2 >= index) past.row_motion = motion;
  }
}

void SceneFlowChecker::FollowMap() {
  for (PastFrame& past : history_) {
    if (past.reference != nullptr)
      past.T_camera_world = ComposeWithReference(past.reference, past.T_camera_reference);
  }
}

namespace {

// Inliers of the frame's matches; `established`: those of them that are established landmarks
// (observed by at least `established_observations` keyframes).
int CountInliers(const Frame& frame, int established_observations, int* established) {
  int inliers = 0;
  *established = 0;
  for (size_t i = 0; i < frame.size(); ++i) {
    const MapPoint* p = frame.map_points[i];
    if (p == nullptr || p->bad || frame.outlier[i] || p->observations.empty()) continue;
    ++inliers;
    *established += static_cast<int>(p->observations.size()) >= established_observations;
  }
  return inliers;
}

// Where a static point seen at `pixel` (undistorted: `undistorted`) at `depth` was in an earlier
// frame at the rough pose; `pixel` itself when that falls outside the image. `T_earlier_camera`:
// this camera (rough pose) in the earlier frame's. Lucas–Kanade starts its search there: static
// points then need a step or two instead of a search from scratch.
cv::Point2f WhereStaticWas(const Camera& camera, const Eigen::Isometry3d& T_earlier_camera,
                           const cv::Point2f& pixel, const cv::Point2f& undistorted, double depth) {
  const Eigen::Vector3d in_past =
      T_earlier_camera * camera.Unproject({undistorted.x, undistorted.y}, depth);
  if (in_past.z() > 0) {
    const Eigen::Vector2d p = camera.Distort(camera.Project(in_past));
    if (p.x() >= 0 && p.y() >= 0 && p.x() < camera.width() && p.y() < camera.height())
      return cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
  return pixel;
}

}  // namespace

bool SceneFlowChecker::MakeEnds(const Camera& camera, const PastFrame& earlier,
                                const cv::Mat& current_depth, const cv::Point2f& past_pixel,
                                const cv::Point2f& past_undistorted, const cv::Point2f& pixel,
                                const cv::Point2f& undistorted, Ends* e) const {
  const int r = options_.depth_window_radius;
  e->past_depths = DepthCandidates(earlier.depth, past_pixel, r);
  e->current_depths = DepthCandidates(current_depth, pixel, r);
  if (e->past_depths.empty() || e->current_depths.empty()) return false;
  const Eigen::Isometry3d T_world_earlier = earlier.T_camera_world.inverse();
  e->past_origin = T_world_earlier.translation();
  e->past_direction =
      T_world_earlier.linear() * camera.Unproject({past_undistorted.x, past_undistorted.y}, 1);
  e->current_direction = camera.Unproject({undistorted.x, undistorted.y}, 1);
  return true;
}

void SceneFlowChecker::RetryOverNearPast(const Frame& frame, const ConsistencyInput& input,
                                         const PastFrame& past,
                                         const std::vector<cv::Point2f>& tracked_points,
                                         const std::vector<size_t>& tracked_slot,
                                         const std::vector<uint8_t>& found,
                                         MapLockReleaser& map_lock, Correspondences* features) {
  const SceneFlowOptions& o = options_;
  const Camera& camera = frame.geometry->camera;
  Correspondences& c = *features;
  const PastFrame* near_past = nullptr;
  for (const PastFrame& p : history_) {
    if (o.retry_gap > 0 && p.tracked && p.index + static_cast<size_t>(o.retry_gap) == frame.index &&
        &p != &past)
      near_past = &p;
  }
  if (near_past == nullptr) return;
  const Eigen::Isometry3d T_near_camera =
      near_past->T_camera_world * frame.T_camera_world.inverse();
  std::vector<size_t> retry;  // indices into tracked_points
  std::vector<cv::Point2f> retry_points, retry_guesses;
  for (size_t t = 0; t < tracked_points.size(); ++t) {
    if (found[t]) continue;
    const size_t i = static_cast<size_t>(c.candidates[tracked_slot[t]]);
    retry.push_back(t);
    retry_points.push_back(tracked_points[t]);
    retry_guesses.push_back(WhereStaticWas(camera, T_near_camera, frame.keypoints[i].pt,
                                           frame.undistorted[i], frame.depth[i]));
  }
  std::vector<cv::Point2f> near_points;
  std::vector<uint8_t> near_found;
  map_lock.WithoutMapLock([&] {
    TrackPointsBack(o, *c.current, near_past->pyramid, retry_points, &near_points, &near_found,
                    &retry_guesses);
  });
  const std::vector<cv::Point2f> near_undistorted =
      UndistortToMiddleRow(camera, near_past->row_motion, near_points);
  for (size_t q = 0; q < retry.size(); ++q) {
    if (!near_found[q]) continue;
    const size_t slot = tracked_slot[retry[q]];
    const size_t i = static_cast<size_t>(c.candidates[slot]);
    c.measured[slot] =
        MakeEnds(camera, *near_past, input.depth, near_points[q], near_undistorted[q],
                 frame.keypoints[i].pt, frame.undistorted[i], &c.ends[slot]);
  }
}

SceneFlowChecker::Correspondences SceneFlowChecker::FollowFeaturesBack(
    const Frame& frame, const ConsistencyInput& input, const PastFrame& past,
    MapLockReleaser& map_lock) {
  const SceneFlowOptions& o = options_;
  const Camera& camera = frame.geometry->camera;
  Correspondences c;
  // Candidates: the features still taken as static. Those with depth get a correspondence in the
  // past frame by Lucas–Kanade, starting where a static point would be at the rough pose.
  std::vector<cv::Point2f> tracked_points, guesses;
  std::vector<size_t> tracked_slot;
  const Eigen::Isometry3d T_past_camera = past.T_camera_world * frame.T_camera_world.inverse();
  // The front end's motion-selected features are judged again (recheck_motion_selected); only
  // with depth, as without it they cannot be measured and would stay out anyway.
  const bool recheck = o.recheck_motion_selected && input.motion_selected_recheckable;
  for (size_t i = 0; i < frame.size(); ++i) {
    const bool rechecked =
        recheck && frame.label[i] == kMotionSelectedLabel && frame.HasDepth(static_cast<int>(i));
    if (!frame.IsStatic(static_cast<int>(i)) && !rechecked) continue;
    c.rechecked.push_back(rechecked);
    if (frame.HasDepth(static_cast<int>(i))) {
      tracked_slot.push_back(c.candidates.size());
      tracked_points.push_back(frame.keypoints[i].pt);
      guesses.push_back(WhereStaticWas(camera, T_past_camera, frame.keypoints[i].pt,
                                       frame.undistorted[i], frame.depth[i]));
    }
    c.candidates.push_back(static_cast<int>(i));
  }
  std::vector<cv::Point2f> past_points;
  std::vector<uint8_t> found;
  map_lock.WithoutMapLock([&] {
    c.current = &CurrentPyramid(frame.index, input.gray);
    TrackPointsBack(o, *c.current, past.pyramid, tracked_points, &past_points, &found, &guesses);
  });
  const std::vector<cv::Point2f> past_undistorted =
      UndistortToMiddleRow(camera, past.row_motion, past_points);
  const size_t n = c.candidates.size();
  c.measured.assign(n, 0);
  c.ends.resize(n);
  for (size_t t = 0; t < tracked_points.size(); ++t) {
    if (!found[t]) continue;
    const size_t slot = tracked_slot[t];
    const size_t i = static_cast<size_t>(c.candidates[slot]);
    c.measured[slot] = MakeEnds(camera, past, input.depth, past_points[t], past_undistorted[t],
                                frame.keypoints[i].pt, frame.undistorted[i], &c.ends[slot]);
  }
  // Features Lucas–Kanade cannot follow back frame_gap frames: on movers most are (they turn,
  // deform and occlude the background over five frames), on the static scene one in five. Over
  // retry_gap frames it follows most of them, and a walking person still moves centimetres.
  RetryOverNearPast(frame, input, past, tracked_points, tracked_slot, found, map_lock, &c);
  std::vector<cv::Point2f> candidate_points;
  for (int i : c.candidates) candidate_points.push_back(frame.keypoints[static_cast<size_t>(i)].pt);
  c.segment =
      SegmentsAt(input.segments, cv::Size(camera.width(), camera.height()), candidate_points);
  return c;
}

std::vector<uint8_t> SceneFlowChecker::UnexplainedByPose(const Frame& frame,
                                                         const Correspondences& features,
                                                         double limit_px) const {
  const PinholeIntrinsics& k = frame.geometry->intrinsics;
  std::vector<uint8_t> unexplained(features.candidates.size(), 0);
  for (size_t slot = 0; slot < features.candidates.size(); ++slot) {
    if (!features.measured[slot]) continue;
    const Ends& e = features.ends[slot];
    const size_t i = static_cast<size_t>(features.candidates[slot]);
    bool explained = false;
    for (float dp : e.past_depths) {
      const Eigen::Vector3d p = frame.T_camera_world * (e.past_origin + dp * e.past_direction);
      if (p.z() <= 1e-6) continue;
      const Eigen::Vector2d uv(k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy);
      if ((uv - Eigen::Vector2d(frame.undistorted[i].x, frame.undistorted[i].y)).norm() <=
          limit_px) {
        explained = true;
        break;
      }
    }
    unexplained[slot] = !explained;
  }
  return unexplained;
}

SceneFlowChecker::StaticWorld SceneFlowChecker::FindStaticWorld(
    Frame& frame, const ConsistencyInput& input, const PastFrame& past,
    const Correspondences& features, MapLockReleaser& map_lock, TrackingResult* result) const {
  const SceneFlowOptions& o = options_;
  const StaticMotionOptions& so = o.static_motion;
  const Camera& camera = frame.geometry->camera;
  const size_t n = features.candidates.size();
  StaticWorld world;
  world.off_static_motion.assign(n, 0);
  if (!so.enabled) return world;
  // A grid of corner samples, one per textured cell, tracked back into the past frame like the
  // features. The samples also vote in the segment rule (sample_votes): ORB features crowd on
  // strong texture and leave plainer objects with too few to judge, a cell's corner stands for
  // its area.
  const LkPyramid& current = *features.current;
  const std::vector<cv::Point2f> samples = map_lock.WithoutMapLock(
      [&] { return GridCorners(so, input.gray, input.depth, LkPyramidImage(current, 1)); });
  const std::vector<cv::Point2f> samples_undistorted =
      UndistortToMiddleRow(camera, frame.row_motion, samples);
  const Eigen::Isometry3d T_past_camera = past.T_camera_world * frame.T_camera_world.inverse();
  std::vector<cv::Point2f> sample_guesses;
  for (size_t s = 0; s < samples.size(); ++s) {
    const cv::Point2f& p = samples[s];
    sample_guesses.push_back(
        WhereStaticWas(camera, T_past_camera, p, samples_undistorted[s],
                       input.depth.at<float>(static_cast<int>(p.y), static_cast<int>(p.x))));
  }
  std::vector<cv::Point2f> sample_past;
  std::vector<uint8_t> sample_found;
  map_lock.WithoutMapLock([&] {
    TrackPointsBack(o, current, past.pyramid, samples, &sample_past, &sample_found,
                    &sample_guesses);
  });
  const std::vector<cv::Point2f> sample_past_undistorted =
      UndistortToMiddleRow(camera, past.row_motion, sample_past);
  const Eigen::Isometry3d T_world_past = past.T_camera_world.inverse();
  std::vector<MotionCorrespondence> correspondences;
  std::vector<cv::Point2f> sample_points;  // those that vote, in sample_ends' order
  for (size_t s = 0; s < samples.size(); ++s) {
    if (!sample_found[s]) continue;
    const int u = static_cast<int>(std::lround(sample_past[s].x));
    const int v = static_cast<int>(std::lround(sample_past[s].y));
    if (u < 0 || v < 0 || u >= past.depth.cols || v >= past.depth.rows) continue;
    const float past_depth = past.depth.at<float>(v, u);
    if (!(past_depth > 0)) continue;
    const Eigen::Vector2d pixel(samples_undistorted[s].x, samples_undistorted[s].y);
    const float z =
        input.depth.at<float>(static_cast<int>(samples[s].y), static_cast<int>(samples[s].x));
    correspondences.push_back({T_world_past * camera.Unproject({sample_past_undistorted[s].x,
                                                                sample_past_undistorted[s].y},
                                                               past_depth),
                               camera.Unproject(pixel, z), pixel});
    if (o.sample_votes) {
      Ends e;
      if (!MakeEnds(camera, past, input.depth, sample_past[s], sample_past_undistorted[s],
                    samples[s], samples_undistorted[s], &e))
        continue;
      world.sample_ends.push_back(std::move(e));
      sample_points.push_back(samples[s]);
    }
  }
  world.sample_segment =
      SegmentsAt(input.segments, cv::Size(camera.width(), camera.height()), sample_points);
  const StaticMotionResult widest = map_lock.WithoutMapLock([&] {
    return FindStaticMotion(so, frame.geometry->intrinsics, correspondences, frame.T_camera_world);
  });
  result->check_samples = static_cast<int>(correspondences.size());
  result->check_rough_samples = widest.rough_inliers;
  result->check_static_samples = widest.inliers;
  if (!widest.replaced) return world;
  frame.T_camera_world = widest.T_camera_world;
  result->check_replaced = true;
  // Features the static world's motion does not explain move, whatever the 3-D thresholds say:
  // near the camera those allow centimetres, as much as a carried box moves.
  world.off_static_motion = UnexplainedByPose(frame, features, 1.5 * so.inlier_px);
  return world;
}

std::vector<uint8_t> SceneFlowChecker::ClassifyUntilSettled(
    Frame& frame, const ConsistencyInput& input, const Correspondences& features,
    const StaticWorld& world, const std::vector<MapPoint*>& matched, const RefinePose& refine_pose,
    TrackingResult* result, std::vector<uint8_t>* segment_dynamic) const {
  const SceneFlowOptions& o = options_;
  const size_t n = features.candidates.size();
  std::vector<uint8_t> dynamic(n, 0), exceeds(n, 0);
  const std::vector<uint8_t> large_segments = LargeSegments(input.segments, o.max_segment_area);
  // Features first, then the voting samples: one list for the segment rule.
  const size_t voters = n + world.sample_ends.size();
  std::vector<uint8_t> voter_measured = features.measured, voter_exceeds(voters, 0);
  voter_measured.resize(voters, 1);
  std::vector<int> voter_segment = features.segment;
  voter_segment.insert(voter_segment.end(), world.sample_segment.begin(),
                       world.sample_segment.end());
  for (int iteration = 1; iteration <= o.max_iterations; ++iteration) {
    result->check_iterations = iteration;
    const Eigen::Isometry3d T_world_camera = frame.T_camera_world.inverse();
    const Eigen::Vector3d centre = T_world_camera.translation();
    // Moving only when no pair of the ends' depths explains the point as static.
    auto all_exceed = [&](const Ends& e) {
      const Eigen::Vector3d direction = T_world_camera.linear() * e.current_direction;
      for (float dc : e.current_depths) {
        const Eigen::Vector3d point = centre + dc * direction;
        for (float dp : e.past_depths) {
          const Eigen::Vector3d flow = point - (e.past_origin + dp * e.past_direction);
          if (!ExceedsSceneFlowThreshold(o, flow, point, centre, dc, frame.geometry->intrinsics.fx))
            return false;
        }
      }
      return true;
    };
    for (size_t k = 0; k < n; ++k) {
      if (features.measured[k])
        exceeds[k] = all_exceed(features.ends[k]) || world.off_static_motion[k];
    }
    for (size_t k = 0; k < n; ++k) voter_exceeds[k] = exceeds[k];
    for (size_t v = 0; v < world.sample_ends.size(); ++v)
      voter_exceeds[n + v] = all_exceed(world.sample_ends[v]);
    std::vector<uint8_t> segments_now;
    std::vector<uint8_t> next =
        ClassifyBySceneFlow(o, voter_measured, voter_exceeds, voter_segment, input.locked_segments,
                            large_segments, &segments_now);
    next.resize(n);  // the samples' own verdicts are not features'
    segment_dynamic->resize(std::max(segment_dynamic->size(), segments_now.size()), 0);
    for (size_t s = 0; s < segments_now.size(); ++s) (*segment_dynamic)[s] |= segments_now[s];
    // A feature once judged dynamic stays so within the frame: the set only grows, so it
    // settles instead of flipping a borderline feature back and forth.
    for (size_t k = 0; k < n; ++k) next[k] |= dynamic[k];
    if (next == dynamic) {
      result->check_converged = true;
      break;
    }
    dynamic = std::move(next);
    for (size_t k = 0; k < n; ++k) {
      const size_t i = static_cast<size_t>(features.candidates[k]);
      frame.map_points[i] = dynamic[k] ? nullptr : matched[i];
      frame.outlier[i] = false;
    }
    refine_pose(frame);
  }
  return dynamic;
}

std::vector<MapPoint*> SceneFlowChecker::CheckSceneFlow(Frame& frame, const ConsistencyInput& input,
                                                        const RefinePose& refine_pose,
                                                        MapLockReleaser& map_lock,
                                                        TrackingResult* result) {
  const SceneFlowOptions& o = options_;
  const PastFrame* past = TrackedPastFrame(frame.index);
  if (past == nullptr) return {};
  // Tracking's pose and how many established landmarks it keeps as inliers.
  const Eigen::Isometry3d tracking_pose = frame.T_camera_world;
  int rough_established = 0;
  CountInliers(frame, o.established_observations, &rough_established);

  const Correspondences features = FollowFeaturesBack(frame, input, *past, map_lock);
  result->check_measured =
      static_cast<int>(std::count(features.measured.begin(), features.measured.end(), 1));
  // Start from the static world's motion, not the majority's (static_motion.h).
  const StaticWorld world = FindStaticWorld(frame, input, *past, features, map_lock, result);

  // Classify at the rough pose, re-estimate the pose without the dynamic features, and repeat
  // until the classification stops changing (a fixed point).
  const std::vector<MapPoint*> matched = frame.map_points;
  const std::vector<bool> rough_outlier = frame.outlier;
  const Eigen::Isometry3d rough_pose = frame.T_camera_world;
  std::vector<uint8_t> segment_dynamic;
  const std::vector<uint8_t> dynamic = ClassifyUntilSettled(frame, input, features, world, matched,
                                                            refine_pose, result, &segment_dynamic);

  int established = 0;
  const int inliers = CountInliers(frame, o.established_observations, &established);
  // The map's hypothesis: landmarks that several keyframes agree on. A check that keeps only a
  // small share of those the rough pose kept has overturned the map on one frame's evidence.
  const bool overturns_map = o.min_established_kept > 0 && rough_established > 0 &&
                             established < o.min_established_kept * rough_established;
  if (inliers < o.min_inliers_kept || overturns_map) {
    // Too little would be left to track, or the map disagrees: keep the rough estimate rather
    // than lose the camera.
    frame.map_points = matched;
    frame.outlier = rough_outlier;
    frame.T_camera_world = overturns_map ? tracking_pose : rough_pose;
    result->check_reverted = true;
    return {};
  }
  result->inliers = inliers;
  for (size_t s = 0; s < segment_dynamic.size(); ++s) {
    const bool locked = s < input.locked_segments.size() && input.locked_segments[s] != 0;
    if (segment_dynamic[s] && !locked) result->check_segments.push_back(static_cast<int>(s));
  }
  std::vector<MapPoint*> judged_dynamic;
  for (size_t k = 0; k < dynamic.size(); ++k) {
    const int i = features.candidates[k];
    if (features.rechecked[k]) {
      // Stays out unless measured and found static.
      if (!dynamic[k] && features.measured[k]) {
        frame.MarkStatic(i);
        ++result->check_readmitted;
      }
      continue;
    }
    if (!dynamic[k]) continue;
    MapPoint* p = matched[static_cast<size_t>(i)];
    if (p != nullptr && !p->bad && !p->observations.empty()) judged_dynamic.push_back(p);
    frame.MarkDynamic(i, kSceneFlowLabel);
    ++result->check_dynamic;
  }
  return judged_dynamic;
}

void SceneFlowChecker::CheckLandmarks(const Frame& frame, const ConsistencyInput& input,
                                      const std::vector<MapPoint*>& judged_dynamic,
                                      const std::vector<MapPoint*>& local_points,
                                      TrackingResult* result) {
  const SceneFlowOptions& o = options_;
  const Camera& camera = frame.geometry->camera;
  std::set<const MapPoint*> handled;
  auto strike = [&](MapPoint* p) {
    if (++p->inconsistent >= o.cull_after) {
      map_->SetBad(p);
      ++result->culled_points;
    }
  };
  for (MapPoint* p : judged_dynamic) {
    handled.insert(p);
    strike(p);
  }
  // Landmarks matched as inliers are consistent.
  for (size_t i = 0; i < frame.size(); ++i) {
    MapPoint* p = frame.map_points[i];
    if (p == nullptr || p->bad || frame.outlier[i]) continue;
    p->inconsistent = 0;
    handled.insert(p);
  }
  // The other local landmarks in view: where the depth image sees through the landmark (a
  // surface behind it, nothing in front) it has moved away. (Lying on a region the front end
  // calls dynamic is no evidence: those regions reach over the background around people.)
  if (!(o.seen_through_max_share > 0)) return;
  const int r = o.depth_window_radius;
  const int width = camera.width(), height = camera.height();
  std::vector<MapPoint*> seen_through;
  int in_view = 0;
  for (MapPoint* p : local_points) {
    if (p->bad || handled.count(p) != 0 || p->observations.empty()) continue;
    const Eigen::Vector3d X = frame.T_camera_world * p->position;
    if (X.z() < 0.1) continue;
    Eigen::Vector2d uv = camera.Project(X);
    if (camera.HasDistortion()) uv = camera.Distort(uv);
    const int u = static_cast<int>(std::lround(uv.x())), v = static_cast<int>(std::lround(uv.y()));
    if (u < r || v < r || u >= width - r || v >= height - r) continue;
    ++in_view;
    const double tolerance = AlongRayLimit(o, X.z());
    int valid = 0, behind = 0;
    for (int y = v - r; y <= v + r; ++y) {
      const float* row = input.depth.ptr<float>(y);
      for (int x = u - r; x <= u + r; ++x) {
        const double d = row[x];
        if (!(d > 0)) continue;
        ++valid;
        behind += d > X.z() + tolerance;
      }
    }
    const int window = (2 * r + 1) * (2 * r + 1);
    if (2 * valid >= window && behind == valid) seen_through.push_back(p);
  }
  // Where much of the view is seen through at once, the frame's pose is off (a blurred frame of
  // a fast turn), not the room gone: no strikes.
  if (seen_through.size() > o.seen_through_max_share * in_view) return;
  for (MapPoint* p : seen_through) strike(p);
}

}  // namespace sdoslam
