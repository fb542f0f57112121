#include "sdoslam/tracking/tracker.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <set>

#include "sdoslam/core/error.h"
#include "sdoslam/matching/matcher.h"
#include "sdoslam/optim/optimizer.h"
#include "sdoslam/tracking/static_motion.h"

namespace sdoslam {

const char* ToString(TrackingState state) {
  switch (state) {
    case TrackingState::kNotInitialized:
      return "not_initialized";
    case TrackingState::kOk:
      return "ok";
    case TrackingState::kLost:
      return "lost";
  }
  return "?";
}

void TrackerOptions::Check() const {
  if (min_initial_depth_features < 10)
    throw Error("tracking.min_initial_depth_features must be >= 10");
  if (min_inliers < 6) throw Error("tracking.min_inliers must be >= 6");
  if (max_frames_between_keyframes < 1)
    throw Error("tracking.max_frames_between_keyframes must be >= 1");
  if (!(reference_ratio > 0 && reference_ratio < 1))
    throw Error("tracking.reference_ratio must be in (0, 1)");
  if (!(projection_radius > 0)) throw Error("tracking.projection_radius must be positive");
  if (relocalization_candidates < 0) throw Error("tracking.relocalization_candidates must be >= 0");
  if (relocalization_place_candidates < 0)
    throw Error("tracking.relocalization_place_candidates must be >= 0");
  if (relocalization_prior_frames < 0)
    throw Error("tracking.relocalization_prior_frames must be >= 0");
  if (!(relocalization_radius_factor >= 1))
    throw Error("tracking.relocalization_radius_factor must be >= 1");
  consistency.Check();
}

Tracker::Tracker(Map* map, const TrackerOptions& options, KeyFramePlaces* places)
    : map_(map), places_(places), options_(options) {
  options_.Check();
}

TrackingResult Tracker::Track(Frame frame, KeyFrame** new_keyframe, bool mapping_idle,
                              bool mapping_accepts, const ConsistencyInput* consistency,
                              std::unique_lock<std::mutex>* map_lock) {
  map_lock_ = map_lock;
  lock_wait_ms_ = 0;
  TrackingResult result =
      TrackFrame(std::move(frame), new_keyframe, mapping_idle, mapping_accepts, consistency);
  map_lock_ = nullptr;
  // Nothing of this frame's matching is held past this point (see Map::CollectGarbage).
  local_points_.clear();
  map_->FrameFinished();
  return result;
}

TrackingResult Tracker::TrackFrame(Frame frame, KeyFrame** new_keyframe, bool mapping_idle,
                                   bool mapping_accepts, const ConsistencyInput* consistency) {
  if (!options_.consistency.enabled) consistency = nullptr;
  // Local mapping may have culled the reference keyframe: its features are gone, its parent
  // (never culled) stands in for it.
  while (reference_ != nullptr && reference_->bad) reference_ = reference_->parent;
  if (map_->correction_epoch() != correction_epoch_) {
    // Loop closing moved the map: the last frame and the scene-flow history move with the
    // reference keyframe, or the motion model would predict in the old map and the check would
    // see the whole room move.
    const Eigen::Isometry3d change = map_->CorrectionSince(reference_, correction_epoch_);
    correction_epoch_ = map_->correction_epoch();
    if (last_frame_ != nullptr) last_frame_->T_camera_world = last_frame_->T_camera_world * change;
    for (PastFrame& past : history_) past.T_camera_world = past.T_camera_world * change;
  }
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

  if (state_ == TrackingState::kNotInitialized) {
    if (Initialize(frame)) {
      state_ = TrackingState::kOk;
      result.keyframe = true;
      *new_keyframe = last_keyframe_;
      result.inliers = last_keyframe_->TrackedPoints(1);
    }
    result.state = state_;
    trajectory_.push_back({frame.timestamp, state_ == TrackingState::kOk ? reference_ : nullptr,
                           Eigen::Isometry3d::Identity()});
    if (state_ == TrackingState::kOk) last_frame_ = std::make_unique<Frame>(last_keyframe_->frame);
    RememberFrame(frame.index, state_ == TrackingState::kOk, Eigen::Isometry3d::Identity(),
                  consistency);
    return result;
  }

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
    ok = Relocalize(frame);
  }
  if (ok) ok = TrackLocalMap(frame, &result);
  if (!ok && state_ == TrackingState::kOk) {
    // Before calling a tracked camera lost: the wide search around the prediction. The frame
    // after a relocalization has no velocity and only the reference keyframe's descriptors to
    // go on, and a mover that fills most of the view leaves the narrow windows too few matches
    // (synthetic loop, threaded: a frame with 48 % of the room in view lost right after one
    // relocalized at 23 %). The failed TrackLocalMap has already counted its points as visible
    // and found; on this rare path they are counted twice for the frame.
    result.matches = 0;
    ok = RelocalizeNearPrediction(frame) && TrackLocalMap(frame, &result);
  }
  if (ok && consistency != nullptr) {
    const std::vector<MapPoint*> judged_dynamic = CheckSceneFlow(frame, *consistency, &result);
    CheckLandmarks(frame, *consistency, judged_dynamic, &result);
    result.feature_labels = frame.label;
  }
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
  result.feature_tracked.assign(frame.size(), 0);
  for (size_t i = 0; i < frame.size(); ++i)
    result.feature_tracked[i] = frame.map_points[i] != nullptr;

  result.relocalized = ok && state_ == TrackingState::kLost;
  state_ = ok ? TrackingState::kOk : TrackingState::kLost;
  result.state = state_;
  result.T_camera_world = frame.T_camera_world;
  if (ok) {
    // After frames lost, the last tracked frame is several frames back: its motion to this one
    // is no velocity, and the motion that was (kept for the next relocalization) stays.
    if (frames_lost_ == 0) {
      velocity_ = frame.T_camera_world * last_frame_->T_camera_world.inverse();
      has_velocity_ = true;
    }
    frames_lost_ = 0;
    if (mapping_accepts && NeedKeyFrame(frame, result.inliers, mapping_idle)) {
      *new_keyframe = CreateKeyFrame(frame);
      result.keyframe = true;
    }
    trajectory_.push_back(
        {frame.timestamp, reference_, frame.T_camera_world * reference_->pose().inverse()});
    last_frame_ = std::make_unique<Frame>(result.keyframe ? (*new_keyframe)->frame : frame);
  } else {
    has_velocity_ = false;
    ++frames_lost_;
    trajectory_.push_back({frame.timestamp, nullptr, Eigen::Isometry3d::Identity()});
  }
  RememberFrame(frame.index, ok, frame.T_camera_world, consistency);
  return result;
}

void Tracker::RememberFrame(size_t index, bool tracked, const Eigen::Isometry3d& T_camera_world,
                            const ConsistencyInput* consistency) {
  if (consistency == nullptr) return;
  // Cloned: the caller may reuse its buffers for the next frame.
  history_.push_back(
      {index, consistency->gray.clone(), consistency->depth.clone(), T_camera_world, tracked});
  while (static_cast<int>(history_.size()) > options_.consistency.frame_gap) history_.pop_front();
}

bool Tracker::Initialize(Frame& frame) {
  int with_depth = 0;
  for (size_t i = 0; i < frame.size(); ++i) with_depth += frame.HasDepth(static_cast<int>(i));
  if (with_depth < options_.min_initial_depth_features) return false;
  frame.T_camera_world = Eigen::Isometry3d::Identity();  // the first camera defines the world
  KeyFrame* kf = map_->AddKeyFrame(frame);
  for (size_t i = 0; i < kf->frame.size(); ++i) {
    if (!kf->frame.HasDepth(static_cast<int>(i)) || !kf->frame.IsStatic(static_cast<int>(i)))
      continue;
    MapPoint* p = map_->AddMapPoint(kf->frame.UnprojectWorld(static_cast<int>(i)), kf);
    map_->AddObservation(p, kf, static_cast<int>(i));
    p->UpdateFromObservations();
  }
  reference_ = last_keyframe_ = kf;
  last_keyframe_frame_ = frame.index;
  return true;
}

void Tracker::MakeTemporaryPoints() {
  // ORB-SLAM2's "visual odometry" points: close features of the last frame that have no map
  // point get a temporary one from their depth, so the motion model has more to match.
  Frame& last = *last_frame_;
  std::vector<std::pair<float, int>> by_depth;
  for (size_t i = 0; i < last.size(); ++i) {
    if (last.HasDepth(static_cast<int>(i)) && last.IsStatic(static_cast<int>(i)))
      by_depth.emplace_back(last.depth[i], static_cast<int>(i));
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
  const PoseOptimizationResult r = WithoutMapLock([&] {
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
  const int matches = SearchByDescriptor(frame, *reference_);
  if (matches < 15) return false;
  return OptimizeAndCount(frame) >= 10;
}

bool Tracker::RelocalizeNearPrediction(Frame& frame) {
  if (frames_lost_ >= options_.relocalization_prior_frames) return false;
  // Every map point: the part of the room that comes back into view is often one that only
  // keyframes outside the reference's covisible set saw (synthetic loop: a person passing close
  // hid one side of the view, then the other), and the projection test keeps the search to
  // the points in view. A map that follows the place stays small.
  std::vector<MapPoint*> points;
  points.reserve(map_->points().size());
  for (const auto& [id, p] : map_->points()) {
    if (!p->bad && !p->observations.empty()) points.push_back(p.get());
  }
  // velocity_ still holds the motion between the last two tracked frames.
  Eigen::Isometry3d carried_on = last_frame_->T_camera_world;
  for (int k = 0; k <= frames_lost_; ++k) carried_on = velocity_ * carried_on;
  for (const Eigen::Isometry3d& prediction : {carried_on, last_frame_->T_camera_world}) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    frame.T_camera_world = prediction;
    // A stamp of its own per try (the search skips points stamped with the stamp it is given);
    // TrackLocalMap then searches at the found pose under a fresh one.
    const int matches = SearchLocalPoints(frame, points, ++frame_stamp_,
                                          options_.relocalization_radius_factor, false);
    if (matches >= 20 && OptimizeAndCount(frame) >= options_.min_inliers) {
      ++frame_stamp_;
      return true;
    }
  }
  ++frame_stamp_;
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  frame.T_camera_world = last_frame_->T_camera_world;
  return false;
}

bool Tracker::Relocalize(Frame& frame) {
  if (RelocalizeNearPrediction(frame)) return true;
  // Candidates: the reference keyframe and its best neighbours, then the keyframes made last.
  // The reference alone is not enough: when a person fills the view before tracking is lost,
  // the last keyframes see mostly that person (conventional mode maps it), and the room comes
  // back in view of older ones. Then place recognition: the keyframes anywhere in the map whose
  // bags of words look most like this frame's (a camera carried to another part of the room
  // while the view was blocked).
  std::vector<KeyFrame*> candidates;
  std::set<uint64_t> chosen;
  auto add = [&](KeyFrame* kf) {
    if (kf != nullptr && !kf->bad && chosen.insert(kf->id).second) candidates.push_back(kf);
  };
  add(reference_);
  if (reference_ != nullptr) {
    for (KeyFrame* n : reference_->Covisible(options_.relocalization_candidates)) add(n);
  }
  int recent = 0;
  for (auto it = map_->keyframes().rbegin();
       it != map_->keyframes().rend() && recent < options_.relocalization_candidates; ++it) {
    if (!it->second->bad) {
      add(it->second.get());
      ++recent;
    }
  }
  if (places_ != nullptr && places_->size() > 0 && options_.relocalization_place_candidates > 0) {
    const BowVector bow = places_->Describe(frame);
    for (const PlaceIndex::Candidate& c : places_->Query(
             *map_, bow, static_cast<size_t>(options_.relocalization_place_candidates))) {
      add(map_->keyframes().at(c.id).get());
    }
  }
  const PinholeIntrinsics& k = frame.geometry->intrinsics;
  const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  for (KeyFrame* kf : candidates) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    if (SearchByDescriptor(frame, *kf) < 15) continue;
    // The pose from the matches alone (the last pose may be far off): PnP in RANSAC on the
    // undistorted keypoints. OpenCV's RANSAC draws from a fixed seed: runs stay repeatable.
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    std::vector<int> feature;
    for (size_t i = 0; i < frame.size(); ++i) {
      const MapPoint* p = frame.map_points[i];
      if (p == nullptr || p->bad) continue;
      object.emplace_back(p->position.x(), p->position.y(), p->position.z());
      image.emplace_back(frame.undistorted[i].x, frame.undistorted[i].y);
      feature.push_back(static_cast<int>(i));
    }
    if (object.size() < 15) continue;
    cv::Mat rvec, tvec;
    std::vector<int> inliers;
    if (!cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 200, 4.0f, 0.99,
                            inliers, cv::SOLVEPNP_EPNP) ||
        inliers.size() < 15) {
      continue;
    }
    std::vector<uint8_t> keep(frame.size(), 0);
    for (int k_in : inliers) keep[static_cast<size_t>(feature[static_cast<size_t>(k_in)])] = 1;
    for (size_t i = 0; i < frame.size(); ++i) {
      if (!keep[i]) frame.map_points[i] = nullptr;
    }
    cv::Matx33d R;
    cv::Rodrigues(rvec, R);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) T.linear()(r, c) = R(r, c);
      T.translation()(r) = tvec.at<double>(r);
    }
    frame.T_camera_world = T;
    if (OptimizeAndCount(frame) >= 10) {
      reference_ = kf;
      return true;
    }
  }
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  frame.T_camera_world = last_frame_->T_camera_world;
  return false;
}

bool Tracker::TrackLocalMap(Frame& frame, TrackingResult* result) {
  // Local keyframes: those that see the matched points, plus their best neighbours.
  std::map<uint64_t, int> votes;
  for (MapPoint* p : frame.map_points) {
    if (p == nullptr || p->bad) continue;
    for (const auto& [kf_id, obs] : p->observations) ++votes[kf_id];
  }
  std::vector<KeyFrame*> local;
  std::set<uint64_t> in_local;
  KeyFrame* best = nullptr;
  int best_votes = 0;
  for (const auto& [kf_id, count] : votes) {
    KeyFrame* kf = map_->keyframes().at(kf_id).get();
    if (kf->bad) continue;
    local.push_back(kf);
    in_local.insert(kf_id);
    if (count > best_votes) {
      best_votes = count;
      best = kf;
    }
  }
  const size_t direct = local.size();
  for (size_t k = 0; k < direct && local.size() < 80; ++k) {
    for (KeyFrame* neighbour : local[k]->Covisible(10)) {
      if (!neighbour->bad && in_local.insert(neighbour->id).second) local.push_back(neighbour);
    }
    if (local[k]->parent != nullptr && !local[k]->parent->bad &&
        in_local.insert(local[k]->parent->id).second) {
      local.push_back(local[k]->parent);
    }
  }
  if (best != nullptr) reference_ = best;

  // Local points, not yet matched in this frame.
  for (size_t i = 0; i < frame.size(); ++i) {
    MapPoint* p = frame.map_points[i];
    if (p == nullptr || p->bad) continue;
    p->last_seen_frame = frame_stamp_;
    ++p->visible;
  }
  std::vector<MapPoint*> points;
  std::set<uint64_t> seen;
  for (KeyFrame* kf : local) {
    for (MapPoint* p : kf->frame.map_points) {
      if (p != nullptr && !p->bad && seen.insert(p->id).second) points.push_back(p);
    }
  }
  SearchLocalPoints(frame, points, frame_stamp_, 1.0);
  local_points_ = points;
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

bool Tracker::NeedKeyFrame(const Frame& frame, int inliers, bool mapping_idle) const {
  const size_t keyframes = map_->GoodKeyFrames();
  const int min_observations = keyframes == 1 ? 1 : keyframes == 2 ? 2 : 3;
  const int reference_matches = reference_->TrackedPoints(min_observations);
  int tracked_close = 0, untracked_close = 0;
  for (size_t i = 0; i < frame.size(); ++i) {
    if (!frame.HasDepth(static_cast<int>(i)) || !frame.IsStatic(static_cast<int>(i)) ||
        frame.depth[i] > frame.geometry->close_depth)
      continue;
    if (frame.map_points[i] != nullptr && !frame.outlier[i]) {
      ++tracked_close;
    } else {
      ++untracked_close;
    }
  }
  const bool need_close = tracked_close < options_.min_close_points &&
                          untracked_close > options_.close_points_to_create;
  const bool long_since =
      frame.index >=
      last_keyframe_frame_ + static_cast<size_t>(options_.max_frames_between_keyframes);
  const bool weak = inliers < 0.25 * reference_matches || need_close;
  const bool c2 =
      (inliers < options_.reference_ratio * reference_matches || need_close) && inliers > 15;
  return (long_since || mapping_idle || weak) && c2;
}

KeyFrame* Tracker::CreateKeyFrame(Frame& frame) {
  KeyFrame* kf = map_->AddKeyFrame(frame);
  // New close points from depth, nearest first; at least min_close_points of them.
  std::vector<std::pair<float, int>> by_depth;
  for (size_t i = 0; i < kf->frame.size(); ++i) {
    if (kf->frame.HasDepth(static_cast<int>(i)) && kf->frame.IsStatic(static_cast<int>(i)))
      by_depth.emplace_back(kf->frame.depth[i], static_cast<int>(i));
  }
  std::sort(by_depth.begin(), by_depth.end());
  int count = 0;
  for (const auto& [depth, i] : by_depth) {
    MapPoint* existing = kf->frame.map_points[static_cast<size_t>(i)];
    if (existing == nullptr || existing->bad) {
      MapPoint* p = map_->AddMapPoint(kf->frame.UnprojectWorld(i), kf);
      map_->AddObservation(p, kf, i);
      p->UpdateFromObservations();
    }
    if (++count > options_.min_close_points && depth > kf->frame.geometry->close_depth) break;
  }
  reference_ = last_keyframe_ = kf;
  last_keyframe_frame_ = frame.index;
  return kf;
}

std::vector<MapPoint*> Tracker::CheckSceneFlow(Frame& frame, const ConsistencyInput& input,
                                               TrackingResult* result) {
  const SceneFlowOptions& o = options_.consistency;
  // The earliest remembered frame that was tracked: frame k − frame_gap when all were.
  const PastFrame* past = nullptr;
  for (const PastFrame& p : history_) {
    if (p.tracked && p.index < frame.index) {
      past = &p;
      break;
    }
  }
  if (past == nullptr) return {};
  const Camera& camera = frame.geometry->camera;
  // Inliers of the frame's matches, and those of them that are established landmarks.
  auto count_inliers = [&](int* established) {
    int inliers = 0;
    *established = 0;
    for (size_t i = 0; i < frame.size(); ++i) {
      const MapPoint* p = frame.map_points[i];
      if (p == nullptr || p->bad || frame.outlier[i] || p->observations.empty()) continue;
      ++inliers;
      *established += static_cast<int>(p->observations.size()) >= o.established_observations;
    }
    return inliers;
  };
  // Tracking's pose and how many established landmarks it keeps as inliers.
  const Eigen::Isometry3d tracking_pose = frame.T_camera_world;
  int rough_established = 0;
  count_inliers(&rough_established);

  // Candidates: the features still taken as static. Those with depth get a correspondence in the
  // past frame by Lucas–Kanade, and both ends become landmarks from depth.
  // The search starts where a static point would be in the past frame, at the rough pose: static
  // points then need a step or two of Lucas–Kanade instead of a search from scratch.
  std::vector<int> candidates;
  std::vector<cv::Point2f> tracked_points, guesses;
  std::vector<size_t> tracked_slot;
  // Where a static point seen at `pixel` (undistorted: `undistorted`) at `depth` was in a past
  // frame (`earlier`) at the rough pose; `pixel` itself when that falls outside the image.
  // `T_earlier_camera`: this camera (rough pose) in the earlier frame's.
  auto where_static_was_in = [&](const Eigen::Isometry3d& T_earlier_camera,
                                 const cv::Point2f& pixel, const cv::Point2f& undistorted,
                                 double depth) {
    const Eigen::Vector3d in_past =
        T_earlier_camera * camera.Unproject({undistorted.x, undistorted.y}, depth);
    if (in_past.z() > 0) {
      const Eigen::Vector2d p = camera.Distort(camera.Project(in_past));
      if (p.x() >= 0 && p.y() >= 0 && p.x() < camera.width() && p.y() < camera.height())
        return cv::Point2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
    }
    return pixel;
  };
  const Eigen::Isometry3d T_past_camera = past->T_camera_world * frame.T_camera_world.inverse();
  auto where_static_was = [&](const cv::Point2f& pixel, const cv::Point2f& undistorted,
                              double depth) {
    return where_static_was_in(T_past_camera, pixel, undistorted, depth);
  };
  for (size_t i = 0; i < frame.size(); ++i) {
    if (!frame.IsStatic(static_cast<int>(i))) continue;
    if (frame.HasDepth(static_cast<int>(i))) {
      tracked_slot.push_back(candidates.size());
      tracked_points.push_back(frame.keypoints[i].pt);
      guesses.push_back(
          where_static_was(frame.keypoints[i].pt, frame.undistorted[i], frame.depth[i]));
    }
    candidates.push_back(static_cast<int>(i));
  }
  std::vector<cv::Point2f> past_points;
  std::vector<uint8_t> found;
  WithoutMapLock([&] {
    TrackPointsBack(o, input.gray, past->gray, tracked_points, &past_points, &found, &guesses);
  });

  const std::vector<cv::Point2f> past_undistorted = camera.UndistortPoints(past_points);
  const Eigen::Isometry3d T_world_past = past->T_camera_world.inverse();
  const size_t n = candidates.size();
  // Per measured feature, each end as a ray (world) and the depths it may have along it.
  struct Ends {
    Eigen::Vector3d past_origin, past_direction, current_direction;
    std::vector<float> past_depths, current_depths;
  };
  std::vector<uint8_t> measured(n, 0);
  std::vector<Ends> ends(n);
  const int r = o.depth_window_radius;
  // The two ends of a correspondence: `past_pixel` (undistorted: `past_undistorted_pixel`) in
  // `earlier`, `pixel` (`undistorted`) now. False when either window has no depth.
  auto make_ends = [&](const PastFrame& earlier, const cv::Point2f& past_pixel,
                       const cv::Point2f& past_undistorted_pixel, const cv::Point2f& pixel,
                       const cv::Point2f& undistorted, Ends* e) {
    e->past_depths = DepthCandidates(earlier.depth, past_pixel, r);
    e->current_depths = DepthCandidates(input.depth, pixel, r);
    if (e->past_depths.empty() || e->current_depths.empty()) return false;
    const Eigen::Isometry3d T_world_earlier = earlier.T_camera_world.inverse();
    e->past_origin = T_world_earlier.translation();
    e->past_direction = T_world_earlier.linear() *
                        camera.Unproject({past_undistorted_pixel.x, past_undistorted_pixel.y}, 1);
    e->current_direction = camera.Unproject({undistorted.x, undistorted.y}, 1);
    return true;
  };
  for (size_t t = 0; t < tracked_points.size(); ++t) {
    if (!found[t]) continue;
    const size_t slot = tracked_slot[t];
    const size_t i = static_cast<size_t>(candidates[slot]);
    measured[slot] = make_ends(*past, past_points[t], past_undistorted[t], frame.keypoints[i].pt,
                               frame.undistorted[i], &ends[slot]);
  }
  // Features Lucas–Kanade cannot follow back frame_gap frames: on movers most are (they turn,
  // deform and occlude the background over five frames), on the static scene one in five. Over
  // retry_gap frames it follows most of them, and a walking person still moves centimetres.
  const PastFrame* near_past = nullptr;
  for (const PastFrame& p : history_) {
    if (o.retry_gap > 0 && p.tracked && p.index + static_cast<size_t>(o.retry_gap) == frame.index &&
        &p != past)
      near_past = &p;
  }
  if (near_past != nullptr) {
    const Eigen::Isometry3d T_near_camera =
        near_past->T_camera_world * frame.T_camera_world.inverse();
    std::vector<size_t> retry;  // indices into tracked_points
    std::vector<cv::Point2f> retry_points, retry_guesses;
    for (size_t t = 0; t < tracked_points.size(); ++t) {
      if (found[t]) continue;
      const size_t i = static_cast<size_t>(candidates[tracked_slot[t]]);
      retry.push_back(t);
      retry_points.push_back(tracked_points[t]);
      retry_guesses.push_back(where_static_was_in(T_near_camera, frame.keypoints[i].pt,
                                                  frame.undistorted[i], frame.depth[i]));
    }
    std::vector<cv::Point2f> near_points;
    std::vector<uint8_t> near_found;
    WithoutMapLock([&] {
      TrackPointsBack(o, input.gray, near_past->gray, retry_points, &near_points, &near_found,
                      &retry_guesses);
    });
    const std::vector<cv::Point2f> near_undistorted = camera.UndistortPoints(near_points);
    for (size_t q = 0; q < retry.size(); ++q) {
      if (!near_found[q]) continue;
      const size_t slot = tracked_slot[retry[q]];
      const size_t i = static_cast<size_t>(candidates[slot]);
      measured[slot] = make_ends(*near_past, near_points[q], near_undistorted[q],
                                 frame.keypoints[i].pt, frame.undistorted[i], &ends[slot]);
    }
  }
  std::vector<cv::Point2f> candidate_points;
  for (int i : candidates) candidate_points.push_back(frame.keypoints[static_cast<size_t>(i)].pt);
  const std::vector<int> segment =
      SegmentsAt(input.segments, cv::Size(camera.width(), camera.height()), candidate_points);
  result->check_measured = static_cast<int>(std::count(measured.begin(), measured.end(), 1));

  // Start from the static world's motion, not the majority's (static_motion.h): a grid of
  // corner samples, one per textured cell, tracked back into the past frame like the features.
  // The samples also vote in the segment rule below (sample_votes): ORB features crowd on
  // strong texture and leave plainer objects with too few to judge, a cell's corner stands
  // for its area.
  std::vector<uint8_t> off_static_motion(n, 0);
  std::vector<Ends> sample_ends;
  std::vector<int> sample_segment;
  if (o.static_motion.enabled) {
    const StaticMotionOptions& so = o.static_motion;
    const std::vector<cv::Point2f> samples =
        WithoutMapLock([&] { return GridCorners(so, input.gray, input.depth); });
    const std::vector<cv::Point2f> samples_undistorted = camera.UndistortPoints(samples);
    std::vector<cv::Point2f> sample_guesses;
    for (size_t s = 0; s < samples.size(); ++s) {
      const cv::Point2f& p = samples[s];
      sample_guesses.push_back(
          where_static_was(p, samples_undistorted[s],
                           input.depth.at<float>(static_cast<int>(p.y), static_cast<int>(p.x))));
    }
    std::vector<cv::Point2f> sample_past;
    std::vector<uint8_t> sample_found;
    WithoutMapLock([&] {
      TrackPointsBack(o, input.gray, past->gray, samples, &sample_past, &sample_found,
                      &sample_guesses);
    });
    const std::vector<cv::Point2f> sample_past_undistorted = camera.UndistortPoints(sample_past);
    std::vector<MotionCorrespondence> correspondences;
    std::vector<cv::Point2f> sample_points;  // those that vote, in sample_ends' order
    for (size_t s = 0; s < samples.size(); ++s) {
      if (!sample_found[s]) continue;
      const int u = static_cast<int>(std::lround(sample_past[s].x));
      const int v = static_cast<int>(std::lround(sample_past[s].y));
      if (u < 0 || v < 0 || u >= past->depth.cols || v >= past->depth.rows) continue;
      const float past_depth = past->depth.at<float>(v, u);
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
        if (!make_ends(*past, sample_past[s], sample_past_undistorted[s], samples[s],
                       samples_undistorted[s], &e))
          continue;
        sample_ends.push_back(std::move(e));
        sample_points.push_back(samples[s]);
      }
    }
    sample_segment =
        SegmentsAt(input.segments, cv::Size(camera.width(), camera.height()), sample_points);
    const StaticMotionResult widest = WithoutMapLock([&] {
      return FindStaticMotion(so, frame.geometry->intrinsics, correspondences,
                              frame.T_camera_world);
    });
    result->check_rough_samples = widest.rough_inliers;
    result->check_static_samples = widest.inliers;
    if (widest.replaced) {
      frame.T_camera_world = widest.T_camera_world;
      result->check_replaced = true;
      // Features the static world's motion does not explain move, whatever the 3-D thresholds
      // say: near the camera those allow centimetres, as much as a carried box moves.
      const PinholeIntrinsics& k = frame.geometry->intrinsics;
      const double limit = 1.5 * so.inlier_px;
      for (size_t k_slot = 0; k_slot < n; ++k_slot) {
        if (!measured[k_slot]) continue;
        const Ends& e = ends[k_slot];
        const size_t i = static_cast<size_t>(candidates[k_slot]);
        bool explained = false;
        for (float dp : e.past_depths) {
          const Eigen::Vector3d p = frame.T_camera_world * (e.past_origin + dp * e.past_direction);
          if (p.z() <= 1e-6) continue;
          const Eigen::Vector2d uv(k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy);
          if ((uv - Eigen::Vector2d(frame.undistorted[i].x, frame.undistorted[i].y)).norm() <=
              limit) {
            explained = true;
            break;
          }
        }
        off_static_motion[k_slot] = !explained;
      }
    }
  }

  // Classify at the rough pose, re-estimate the pose without the dynamic features, and repeat
  // until the classification stops changing (a fixed point).
  const std::vector<MapPoint*> matched = frame.map_points;
  const std::vector<bool> rough_outlier = frame.outlier;
  const Eigen::Isometry3d rough_pose = frame.T_camera_world;
  std::vector<uint8_t> dynamic(n, 0), exceeds(n, 0), segment_dynamic;
  const std::vector<uint8_t> large_segments = LargeSegments(input.segments, o.max_segment_area);
  // Features first, then the voting samples: one list for the segment rule.
  std::vector<uint8_t> voter_measured = measured, voter_exceeds(n + sample_ends.size(), 0);
  voter_measured.resize(n + sample_ends.size(), 1);
  std::vector<int> voter_segment = segment;
  voter_segment.insert(voter_segment.end(), sample_segment.begin(), sample_segment.end());
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
      if (measured[k]) exceeds[k] = all_exceed(ends[k]) || off_static_motion[k];
    }
    for (size_t k = 0; k < n; ++k) voter_exceeds[k] = exceeds[k];
    for (size_t v = 0; v < sample_ends.size(); ++v)
      voter_exceeds[n + v] = all_exceed(sample_ends[v]);
    std::vector<uint8_t> segments_now;
    std::vector<uint8_t> next =
        ClassifyBySceneFlow(o, voter_measured, voter_exceeds, voter_segment, input.locked_segments,
                            large_segments, &segments_now);
    next.resize(n);  // the samples' own verdicts are not features'
    segment_dynamic.resize(std::max(segment_dynamic.size(), segments_now.size()), 0);
    for (size_t s = 0; s < segments_now.size(); ++s) segment_dynamic[s] |= segments_now[s];
    // A feature once judged dynamic stays so within the frame: the set only grows, so it
    // settles instead of flipping a borderline feature back and forth.
    for (size_t k = 0; k < n; ++k) next[k] |= dynamic[k];
    if (next == dynamic) {
      result->check_converged = true;
      break;
    }
    dynamic = std::move(next);
    for (size_t k = 0; k < n; ++k) {
      const size_t i = static_cast<size_t>(candidates[k]);
      frame.map_points[i] = dynamic[k] ? nullptr : matched[i];
      frame.outlier[i] = false;
    }
    OptimizeAndCount(frame);
  }

  int established = 0;
  const int inliers = count_inliers(&established);
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
  for (size_t k = 0; k < n; ++k) {
    if (!dynamic[k]) continue;
    const int i = candidates[k];
    MapPoint* p = matched[static_cast<size_t>(i)];
    if (p != nullptr && !p->bad && !p->observations.empty()) judged_dynamic.push_back(p);
    frame.MarkDynamic(i, kSceneFlowLabel);
    ++result->check_dynamic;
  }
  return judged_dynamic;
}

void Tracker::CheckLandmarks(const Frame& frame, const ConsistencyInput& input,
                             const std::vector<MapPoint*>& judged_dynamic, TrackingResult* result) {
  const SceneFlowOptions& o = options_.consistency;
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
  const int r = o.depth_window_radius;
  const int width = camera.width(), height = camera.height();
  for (MapPoint* p : local_points_) {
    if (p->bad || handled.count(p) != 0 || p->observations.empty()) continue;
    const Eigen::Vector3d X = frame.T_camera_world * p->position;
    if (X.z() < 0.1) continue;
    Eigen::Vector2d uv = camera.Project(X);
    if (camera.HasDistortion()) uv = camera.Distort(uv);
    const int u = static_cast<int>(std::lround(uv.x())), v = static_cast<int>(std::lround(uv.y()));
    if (u < r || v < r || u >= width - r || v >= height - r) continue;
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
    const bool seen_through = 2 * valid >= window && behind == valid;
    if (seen_through) strike(p);
  }
}

}  // namespace sdoslam
