#include "sdoslam/tracking/tracker.h"

#include <algorithm>

#include "sdoslam/matching/matcher.h"
#include "sdoslam/optim/optimizer.h"
#include "sdoslam/tracking/initializer.h"
#include "sdoslam/tracking/keyframe_inserter.h"
#include "sdoslam/tracking/local_map.h"

namespace sdoslam {
namespace {

// Features labelled static (by the front end and the check) that have depth.
int StaticFeaturesWithDepth(const Frame& frame) {
  int count = 0;
  for (size_t i = 0; i < frame.size(); ++i) count += frame.IsStaticWithDepth(static_cast<int>(i));
  return count;
}

}  // namespace

Tracker::Tracker(Map* map, const TrackerOptions& options, KeyFramePlaces* places)
    : map_(map),
      options_(options),
      checker_(map, options.consistency),
      relocalizer_(map, options, places) {
  options_.Check();
}

TrackingResult Tracker::Track(Frame frame, KeyFrame** new_keyframe, bool mapping_idle,
                              bool mapping_accepts, const ConsistencyInput* consistency,
                              std::unique_lock<std::mutex>* map_lock) {
  map_lock_.Begin(map_lock);
  TrackingResult result =
      TrackFrame(std::move(frame), new_keyframe, mapping_idle, mapping_accepts, consistency);
  map_lock_.End();
  // Nothing of this frame's matching is held past this point (see Map::CollectGarbage).
  local_points_.clear();
  map_->FrameFinished();
  return result;
}

void Tracker::FollowMapChanges() {
  // Local mapping may have culled the reference keyframe: its features are gone, its parent
  // (never culled) stands in for it.
  while (reference_ != nullptr && reference_->bad) reference_ = reference_->parent;
  // The frames remembered for the scene flow sit where their keyframes are now: local BA and
  // loop closing move keyframes, and a pose kept from tracking time would make the check see
  // the room move by as much (real fr1_rpy: local BA moves a fresh keyframe by centimetres).
  checker_.FollowMap();
  if (map_->correction_epoch() != correction_epoch_) {
    // Loop closing moved the map: the last frame moves with the reference keyframe, or the
    // motion model would predict in the old map.
    const Eigen::Isometry3d change = map_->CorrectionSince(reference_, correction_epoch_);
    correction_epoch_ = map_->correction_epoch();
    if (last_frame_ != nullptr) last_frame_->T_camera_world = last_frame_->T_camera_world * change;
  }
}

KeyFrame* Tracker::StartMap(Frame& frame, const Eigen::Isometry3d& T_camera_world,
                            KeyFrame** new_keyframe, TrackingResult* result) {
  KeyFrame* first = InitializeMap(map_, options_, frame, T_camera_world);
  if (first == nullptr) return nullptr;
  reference_ = first;
  last_keyframe_frame_ = frame.index;
  state_ = TrackingState::kOk;
  result->keyframe = true;
  *new_keyframe = first;
  result->inliers = first->TrackedPoints(1);
  last_frame_ = std::make_unique<Frame>(first->frame);
  return first;
}

TrackingResult Tracker::Initialize(Frame& frame, KeyFrame** new_keyframe,
                                   const ConsistencyInput* consistency, TrackingResult result) {
  StartMap(frame, Eigen::Isometry3d::Identity(), new_keyframe, &result);
  result.state = state_;
  trajectory_.push_back({frame.timestamp, state_ == TrackingState::kOk ? reference_ : nullptr,
                         Eigen::Isometry3d::Identity()});
  if (consistency != nullptr) {
    checker_.RememberFrame(frame.index, state_ == TrackingState::kOk, Eigen::Isometry3d::Identity(),
                           *consistency, state_ == TrackingState::kOk ? reference_ : nullptr);
  }
  return result;
}

bool Tracker::Restart(Frame& frame, KeyFrame** new_keyframe, const ConsistencyInput* consistency,
                      TrackingResult* result) {
  const bool young = options_.restart_below_keyframes > 0 &&
                     map_->GoodKeyFrames() <= static_cast<size_t>(options_.restart_below_keyframes);
  std::unique_ptr<Frame> candidate = std::move(restart_candidate_);
  if (!young || !CanStartMap(options_, frame)) return false;
  // The frame before was lost too and could be the new map's first: the map starts again when
  // this one follows it (a view that holds still from one frame to the next; noise, a flash or
  // a shaken lens does not).
  const Eigen::Isometry3d carried_on =
      (has_velocity_ ? velocity_ : Eigen::Isometry3d::Identity()) * last_frame_->T_camera_world;
  if (candidate == nullptr || candidate->index + 1 != frame.index ||
      !FollowsCandidate(frame, *candidate)) {
    // Straight from tracking, or on from such a candidate: after frames the camera could not see
    // (a covered lens) the motion model no longer knows where it is, and relocalization is the
    // way back.
    if (state_ == TrackingState::kOk || candidate != nullptr) {
      restart_candidate_ = std::make_unique<Frame>(frame);
      restart_candidate_->T_camera_world = candidate ? candidate->T_camera_world : carried_on;
      std::fill(restart_candidate_->map_points.begin(), restart_candidate_->map_points.end(),
                nullptr);
    }
    return false;
  }
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  if (StartMap(frame, frame.T_camera_world, new_keyframe, result) == nullptr) return false;
  velocity_ = frame.T_camera_world * candidate->T_camera_world.inverse();
  velocity_seconds_ = frame.timestamp - candidate->timestamp;
  has_velocity_ = true;
  result->restarted = true;
  result->state = state_;
  result->T_camera_world = frame.T_camera_world;
  trajectory_.push_back({frame.timestamp, reference_, Eigen::Isometry3d::Identity()});
  // The frames remembered for the scene flow have their poses in the map that was left.
  checker_.Forget();
  if (consistency != nullptr)
    checker_.RememberFrame(frame.index, true, frame.T_camera_world, *consistency, reference_);
  return true;
}

bool Tracker::FollowsCandidate(Frame& frame, const Frame& candidate) {
  // The motion model's search against the candidate's points from depth (MakeTemporaryPoints
  // and TrackWithMotionModel work on the last frame).
  std::unique_ptr<Frame> last = std::move(last_frame_);
  last_frame_ = std::make_unique<Frame>(candidate);
  MakeTemporaryPoints();
  frame.T_camera_world = candidate.T_camera_world;
  bool follows = TrackWithMotionModel(frame);
  int inliers = 0;
  for (const MapPoint* p : frame.map_points) inliers += p != nullptr;
  follows = follows && inliers >= options_.min_inliers;
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  std::fill(frame.outlier.begin(), frame.outlier.end(), false);
  temporary_points_.clear();
  last_frame_ = std::move(last);
  return follows;
}

bool Tracker::TrackPose(Frame& frame, TrackingResult* result) {
  bool ok = false;
  if (state_ == TrackingState::kOk) {
    MakeTemporaryPoints();
    if (has_velocity_) {
      frame.T_camera_world = velocity_ * last_frame_->T_camera_world;
      ok = TrackWithMotionModel(frame);
    }
    if (!ok) {
      frame.T_camera_world = last_frame_->T_camera_world;
      ok = TrackReferenceKeyFrame(frame);
    }
  } else {
    ok = relocalizer_.Relocalize(frame, RelocalizationPrior(), &reference_, &frame_stamp_,
                                 Refiner());
  }
  if (ok) ok = TrackLocalMap(frame, result);
  if (!ok && state_ == TrackingState::kOk) {
    // Before calling a tracked camera lost: the wide search around the prediction. The frame
    // after a relocalization has no velocity and only the reference keyframe's descriptors to
    // go on, and a mover that fills most of the view leaves the narrow windows too few matches
    // (synthetic loop, threaded: a frame with 48 % of the room in view lost right after one
    // relocalized at 23 %). The failed TrackLocalMap has already counted its points as visible
    // and found; on this rare path they are counted twice for the frame.
    result->matches = 0;
    ok = relocalizer_.RelocalizeNearPrediction(frame, RelocalizationPrior(), &frame_stamp_,
                                               Refiner()) &&
         TrackLocalMap(frame, result);
  }
  return ok;
}

void Tracker::DropTemporaryPoints(Frame& frame, TrackingResult* result) {
  // Drop the temporary points (no observations) and outliers from this frame, and the
  // temporaries from the last frame, before the temporaries are freed.
  for (size_t i = 0; i < frame.size(); ++i) {
    MapPoint*& p = frame.map_points[i];
    if (p != nullptr && (p->bad || p->observations.empty() || frame.outlier[i])) p = nullptr;
  }
  for (MapPoint*& p : last_frame_->map_points) {
    if (p != nullptr && p->observations.empty()) p = nullptr;
  }
  temporary_points_.clear();
  result->feature_tracked.assign(frame.size(), 0);
  for (size_t i = 0; i < frame.size(); ++i)
    result->feature_tracked[i] = frame.map_points[i] != nullptr;
}

void Tracker::DecideKeyFrame(Frame& frame, const KeyFrameChoice& choice, KeyFrame** new_keyframe,
                             TrackingResult* result) {
  // Enough of the static world in view to vouch for the pose, on this frame or the one before
  // it (see TrackerOptions).
  const bool narrow_static_view =
      choice.consistency != nullptr && options_.consistency.static_motion.enabled &&
      result->check_static_samples < options_.keyframes_min_static_samples &&
      StaticFeaturesWithDepth(frame) < options_.keyframes_min_static_features;
  const bool static_view_vouches = !narrow_static_view || !last_narrow_static_view_;
  last_narrow_static_view_ = narrow_static_view;
  result->reference_matches = ReferenceMatches(*map_, *reference_);
  const ClosePoints close = CountClosePoints(frame);
  result->close_tracked = close.tracked;
  result->close_untracked = close.untracked;
  if (choice.mapping_accepts && (choice.judged || !options_.keyframes_only_from_judged_frames) &&
      static_view_vouches &&
      NeedKeyFrame(options_, frame,
                   {.inliers = result->inliers,
                    .reference_matches = result->reference_matches,
                    .last_keyframe_frame = last_keyframe_frame_,
                    .mapping_idle = choice.mapping_idle,
                    .good_keyframes = map_->GoodKeyFrames()})) {
    *new_keyframe = CreateKeyFrame(map_, options_, frame);
    reference_ = *new_keyframe;
    last_keyframe_frame_ = frame.index;
    result->keyframe = true;
  }
}

TrackingResult Tracker::TrackFrame(Frame frame, KeyFrame** new_keyframe, bool mapping_idle,
                                   bool mapping_accepts, const ConsistencyInput* consistency) {
  if (!options_.consistency.enabled) consistency = nullptr;
  // A rolling shutter's rows moved with the camera: the motion model says how far. A lost camera
  // (no velocity) is found again from the rows as they are.
  const double readout_s = frame.geometry->camera.options().readout_s;
  // The rows as the shutter saw them, for the refit (TrackingOptions::rolling_shutter_refit).
  std::vector<cv::Point2f> seen_undistorted;
  std::vector<float> seen_depth, seen_right_u;
  if (readout_s > 0 && state_ == TrackingState::kOk && has_velocity_ && velocity_seconds_ > 0) {
    if (options_.rolling_shutter_refit) {
      seen_undistorted = frame.undistorted;
      seen_depth = frame.depth;
      seen_right_u = frame.right_u;
    }
    frame.CompensateRollingShutter(RowMotion(velocity_, readout_s / velocity_seconds_));
  }
  FollowMapChanges();
  *new_keyframe = nullptr;
  ++frame_stamp_;
  TrackingResult result;
  result.index = frame.index;
  result.timestamp = frame.timestamp;
  result.features = static_cast<int>(frame.size());
  for (size_t i = 0; i < frame.size(); ++i)
    result.features_with_depth += frame.HasDepth(static_cast<int>(i));
  result.feature_labels = frame.label;
  result.feature_points.reserve(frame.size());
  for (const cv::KeyPoint& k : frame.keypoints) result.feature_points.push_back(k.pt);
  if (state_ == TrackingState::kNotInitialized)
    return Initialize(frame, new_keyframe, consistency, std::move(result));

  bool ok = TrackPose(frame, &result);
  const double seconds_since_last = last_frame_ ? frame.timestamp - last_frame_->timestamp : 0;
  if (ok && !seen_undistorted.empty() && seconds_since_last > 0) {
    frame.undistorted = std::move(seen_undistorted);
    frame.depth = std::move(seen_depth);
    frame.right_u = std::move(seen_right_u);
    frame.CompensateRollingShutter(
        RowMotion(frame.T_camera_world * last_frame_->T_camera_world.inverse(),
                  readout_s / seconds_since_last));
    OptimizeAndCount(frame);
  }
  if (ok) {
    restart_candidate_.reset();
  } else if (Restart(frame, new_keyframe, consistency, &result)) {
    return result;
  }
  // Whether this frame's features were judged for scene flow (or need not be).
  const bool judged = consistency == nullptr || checker_.CanJudge(frame.index);
  if (ok && consistency != nullptr) {
    const std::vector<MapPoint*> judged_dynamic =
        checker_.CheckSceneFlow(frame, *consistency, Refiner(), map_lock_, &result);
    checker_.CheckLandmarks(frame, *consistency, judged_dynamic, local_points_, &result);
    result.feature_labels = frame.label;
  }
  DropTemporaryPoints(frame, &result);

  result.relocalized = ok && state_ == TrackingState::kLost;
  state_ = ok ? TrackingState::kOk : TrackingState::kLost;
  result.state = state_;
  result.T_camera_world = frame.T_camera_world;
  bool first_velocity = false;
  RowMotion first_rows_moved;  // set where first_velocity finds a rolling shutter
  if (ok) {
    // After frames lost, the last tracked frame is several frames back: its motion to this one
    // is no velocity, and the motion that was (kept for the next relocalization) stays.
    first_velocity = frames_lost_ == 0 && !has_velocity_;
    if (frames_lost_ == 0) {
      velocity_ = frame.T_camera_world * last_frame_->T_camera_world.inverse();
      velocity_seconds_ = frame.timestamp - last_frame_->timestamp;
      has_velocity_ = true;
    }
    frames_lost_ = 0;
    DecideKeyFrame(frame,
                   {.mapping_idle = mapping_idle,
                    .mapping_accepts = mapping_accepts,
                    .judged = judged,
                    .consistency = consistency},
                   new_keyframe, &result);
    if (first_velocity && readout_s > 0 && velocity_seconds_ > 0) {
      first_rows_moved = RowMotion(velocity_, readout_s / velocity_seconds_);
      CompensateRecentKeyFrames(frame.index, first_rows_moved);
    }
    trajectory_.push_back(
        {frame.timestamp, reference_, frame.T_camera_world * reference_->pose().inverse()});
    last_frame_ = std::make_unique<Frame>(result.keyframe ? (*new_keyframe)->frame : frame);
  } else {
    has_velocity_ = false;
    ++frames_lost_;
    trajectory_.push_back({frame.timestamp, nullptr, Eigen::Isometry3d::Identity()});
  }
  if (consistency != nullptr) {
    checker_.RememberFrame(frame.index, ok, frame.T_camera_world, *consistency,
                           ok ? reference_ : nullptr, frame.row_motion);
    if (first_rows_moved.active()) checker_.CompensateRecentFrames(frame.index, first_rows_moved);
  }
  return result;
}

void Tracker::CompensateRecentKeyFrames(size_t index, const RowMotion& motion) {
  for (const auto& [id, owned] : map_->keyframes()) {
    KeyFrame* keyframe = owned.get();
    Frame& seen = keyframe->frame;
    if (keyframe->bad || seen.row_motion.active() || seen.index + 2 < index) continue;
    seen.CompensateRollingShutter(motion);
    for (size_t i = 0; i < seen.size(); ++i) {
      MapPoint* point = seen.map_points[i];
      if (point == nullptr || point->bad || point->reference != keyframe ||
          !seen.HasDepth(static_cast<int>(i)))
        continue;
      point->position = seen.UnprojectWorld(static_cast<int>(i));
      point->UpdateFromObservations();
    }
  }
}

void Tracker::MakeTemporaryPoints() {
  // ORB-SLAM2's "visual odometry" points: close features of the last frame that have no map
  // point get a temporary one from their depth, so the motion model has more to match.
  Frame& last = *last_frame_;
  std::vector<std::pair<float, int>> by_depth;
  for (size_t i = 0; i < last.size(); ++i) {
    const int feature = static_cast<int>(i);
    if (last.MakesPoints(feature) && last.HasDepth(feature))
      by_depth.emplace_back(last.depth[i], feature);
  }
  std::sort(by_depth.begin(), by_depth.end());
  int count = 0;
  for (const auto& [depth, i] : by_depth) {
    MapPoint*& existing = last.map_points[static_cast<size_t>(i)];
    if (existing == nullptr || existing->bad) {
      auto p =
          std::make_unique<MapPoint>(static_cast<uint64_t>(-1), last.UnprojectWorld(i), reference_);
      p->descriptor = last.descriptors.row(i).clone();
      p->found = 0;
      existing = p.get();
      last.outlier[static_cast<size_t>(i)] = false;
      temporary_points_.push_back(std::move(p));
    }
    if (++count > options_.min_close_points && depth > last.geometry->close_depth) break;
  }
}

Relocalizer::Prior Tracker::RelocalizationPrior() const {
  return {*last_frame_, velocity_, frames_lost_};
}

RefinePose Tracker::Refiner() {
  return [this](Frame& frame) { return OptimizeAndCount(frame); };
}

int Tracker::OptimizeAndCount(Frame& frame) {
  std::vector<int> index;
  std::vector<Eigen::Vector3d> points;
  std::vector<PointObservation> observations;
  for (size_t i = 0; i < frame.size(); ++i) {
    const MapPoint* p = frame.map_points[i];
    if (p == nullptr || p->bad) continue;
    index.push_back(static_cast<int>(i));
    points.push_back(p->position);
    observations.push_back(frame.Observation(static_cast<int>(i)));
  }
  if (index.size() < 10) return 0;
  const PoseOptimizationResult r = map_lock_.WithoutMapLock([&] {
    return OptimizePose(frame.geometry->intrinsics, frame.T_camera_world, points, observations);
  });
  frame.T_camera_world = r.T_camera_world;
  int inliers = 0;
  for (size_t k = 0; k < index.size(); ++k) {
    const size_t i = static_cast<size_t>(index[k]);
    frame.outlier[i] = !r.inlier[k];
    if (r.inlier[k]) {
      ++inliers;
    } else {
      frame.map_points[i] = nullptr;
    }
  }
  return inliers;
}

bool Tracker::TrackWithMotionModel(Frame& frame) {
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  int matches = SearchByProjection(frame, *last_frame_, options_.projection_radius);
  if (matches < 20) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    matches = SearchByProjection(frame, *last_frame_, 2 * options_.projection_radius);
  }
  if (matches < 20) return false;
  return OptimizeAndCount(frame) >= 10;
}

bool Tracker::TrackReferenceKeyFrame(Frame& frame) {
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  // Brute force, not vocabulary-guided as ORB-SLAM does here: guided matching finds about two
  // thirds of the matches, and with it five sequences came out 0.1-0.7 mm worse (real-background
  // carried_box 5.5 -> 6.2 mm, walking_xyz 300 frames 6.3 -> 6.9). One keyframe's brute-force
  // search (10^6 descriptor distances) costs a few milliseconds, and only frames the motion
  // model misses pay it.
  const int matches = SearchByDescriptor(frame, *reference_);
  if (matches < 15) return false;
  return OptimizeAndCount(frame) >= 10;
}

bool Tracker::TrackLocalMap(Frame& frame, TrackingResult* result) {
  LocalMap local = FindLocalMap(*map_, frame);
  if (local.reference != nullptr) reference_ = local.reference;

  // Local points, not yet matched in this frame.
  for (size_t i = 0; i < frame.size(); ++i) {
    MapPoint* p = frame.map_points[i];
    if (p == nullptr || p->bad) continue;
    p->last_seen_frame = frame_stamp_;
    ++p->visible;
  }
  result->local_map_matches =
      SearchLocalPoints(frame, local.points, frame_stamp_, options_.local_map_radius);
  local_points_ = std::move(local.points);
  for (const MapPoint* p : frame.map_points) result->matches += p != nullptr && !p->bad;
  OptimizeAndCount(frame);
  int inliers = 0;
  for (size_t i = 0; i < frame.size(); ++i) {
    MapPoint* p = frame.map_points[i];
    if (p == nullptr || p->bad || frame.outlier[i]) continue;
    ++p->found;
    if (!p->observations.empty()) ++inliers;
  }
  result->inliers = inliers;
  return inliers >= options_.min_inliers;
}

}  // namespace sdoslam
