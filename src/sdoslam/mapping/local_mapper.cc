#include "sdoslam/mapping/local_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <set>

#include "sdoslam/core/error.h"
#include "sdoslam/core/geometry.h"
#include "sdoslam/core/stopwatch.h"
#include "sdoslam/mapping/fuse.h"
#include "sdoslam/matching/best_two.h"
#include "sdoslam/matching/matcher.h"

namespace sdoslam {

void LocalMapperOptions::Check(const std::string& path) const {
  if (fuse_neighbours < 0) throw Error(path + "fuse_neighbours must be >= 0");
  if (!(min_found_ratio >= 0 && min_found_ratio < 1))
    throw Error(path + "min_found_ratio must be in [0, 1)");
  if (!(redundant_ratio > 0 && redundant_ratio <= 1))
    throw Error(path + "redundant_ratio must be in (0, 1]");
  if (transient_observations < 0) throw Error(path + "transient_observations must be >= 0");
  if (!(crowded_distance >= 0)) throw Error(path + "crowded_distance must be >= 0");
  if (!(crowded_angle_deg > 0 && crowded_angle_deg <= 180))
    throw Error(path + "crowded_angle_deg must be in (0, 180]");
  if (crowded_keyframes < 2) throw Error(path + "crowded_keyframes must be >= 2");
  if (local_keyframes < 1) throw Error(path + "local_keyframes must be >= 1");
  if (fixed_keyframes < 0) throw Error(path + "fixed_keyframes must be >= 0");
  if (max_ba_observations < 1) throw Error(path + "max_ba_observations must be >= 1");
  if (triangulation_neighbours < 1) throw Error(path + "triangulation_neighbours must be >= 1");
  if (max_queued_keyframes < 1) throw Error(path + "max_queued_keyframes must be >= 1");
  if (max_tracking_lead < 0) throw Error(path + "max_tracking_lead must be >= 0");
  if (min_frames_between_local_ba < 0)
    throw Error(path + "min_frames_between_local_ba must be >= 0");
  bundle_adjustment.Check(path + "bundle_adjustment.");
}

LocalMapper::LocalMapper(Map* map, const LocalMapperOptions& options)
    : map_(map), options_(options) {
  options_.Check();
}

namespace {

// Keyframes over which a new point must prove itself (ORB-SLAM2: found often enough, seen by
// more than its own keyframe).
constexpr uint64_t kProbationKeyFrames = 3;

// A lock that is only taken when there is a mutex (threaded runs); the wait is added to
// `*wait_ms`.
std::unique_lock<std::mutex> LockIf(std::mutex* mutex, double* wait_ms) {
  if (mutex == nullptr) return std::unique_lock<std::mutex>();
  const auto start = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(*mutex);
  *wait_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return lock;
}

}  // namespace

MappingResult LocalMapper::Process(KeyFrame* kf, std::mutex* map_mutex,
                                   const std::atomic<bool>* new_keyframe_waiting) {
  const std::atomic<bool>* stop =
      options_.stop_ba_for_new_keyframe ? new_keyframe_waiting : nullptr;
  MappingResult result;
  bool adjust = false;
  {
    auto lock = LockIf(map_mutex, &result.lock_wait_ms);
    auto start = std::chrono::steady_clock::now();
    // No pointer to a culled point is held here: recent points are pruned first.
    std::erase_if(recent_points_, [](const MapPoint* p) { return p->bad; });
    result.freed_points = static_cast<int>(map_->CollectGarbage());
    InsertKeyFrame(kf);
    result.culled_points = CullRecentPoints(kf);
    result.insert_ms = MsSince(start);
    start = std::chrono::steady_clock::now();
    result.triangulated_points = TriangulateNewPoints(kf);
    result.triangulate_ms = MsSince(start);
    start = std::chrono::steady_clock::now();
    result.fused_points = FuseWithNeighbours(kf);
    result.fuse_ms = MsSince(start);
    adjust = map_->GoodKeyFrames() > 2;
  }
  auto start = std::chrono::steady_clock::now();
  const bool too_soon =
      last_adjusted_frame_.has_value() &&
      kf->frame.index <
          *last_adjusted_frame_ + static_cast<size_t>(options_.min_frames_between_local_ba);
  if (adjust && too_soon) {
    result.ba_spaced = true;
  } else if (adjust && stop != nullptr && stop->load()) {
    result.ba_skipped = true;
  } else if (adjust) {
    LocalBundleAdjustment(kf, &result, map_mutex, stop);
    last_adjusted_frame_ = kf->frame.index;
  }
  result.ba_ms = MsSince(start);
  auto lock = LockIf(map_mutex, &result.lock_wait_ms);
  start = std::chrono::steady_clock::now();
  result.culled_keyframes = CullKeyFrames(kf) + CullCrowdedKeyFrames(kf);
  result.cull_ms = MsSince(start);
  return result;
}

void LocalMapper::InsertKeyFrame(KeyFrame* kf) {
  for (size_t i = 0; i < kf->frame.size(); ++i) {
    MapPoint* p = kf->frame.map_points[i];
    if (p == nullptr) continue;
    if (p->bad) {
      kf->frame.map_points[i] = nullptr;
      continue;
    }
    const auto it = p->observations.find(kf->id);
    if (it == p->observations.end()) {
      map_->AddObservation(p, kf, static_cast<int>(i));
      p->UpdateFromObservations();
    } else if (it->second.second == static_cast<int>(i)) {
      recent_points_.push_back(p);  // created from this keyframe's depth
    } else {
      kf->frame.map_points[i] = nullptr;  // a second feature matched to the same point
    }
  }
  map_->UpdateConnections(kf);
  map_->KeyFrameInserted(kf);
}

int LocalMapper::CullRecentPoints(KeyFrame* kf) {
  int culled = 0;
  std::vector<MapPoint*> keep;
  for (MapPoint* p : recent_points_) {
    if (p->bad) continue;
    const uint64_t age = kf->id - p->first_keyframe_id;
    if (p->FoundRatio() < options_.min_found_ratio || (age >= 2 && p->observations.size() < 2)) {
      map_->SetBad(p);
      ++culled;
    } else if (age < kProbationKeyFrames) {
      keep.push_back(p);  // still on probation
    }
  }
  recent_points_ = std::move(keep);
  return culled;
}

namespace {

// Whether X, triangulated, fails the χ² test of its reprojection onto keyframe feature i; it
// does behind the camera.
bool FailsChi2(const KeyFrame& kf, int i, const Eigen::Vector3d& X) {
  const Eigen::Vector3d p = kf.pose() * X;
  if (p.z() <= 0) return true;
  const PointObservation m = kf.frame.Observation(i);
  return ReprojectionChi2(kf.frame.geometry->intrinsics, p, m) >
         ReprojectionChi2Threshold(m.stereo());
}

// The linear (DLT) triangulation of the normalised rays `r1` from the camera at `T1_camera_world`
// and `r2` from `T2_camera_world`; none when the solution lies at infinity.
std::optional<Eigen::Vector3d> TriangulateRays(const Eigen::Vector3d& r1,
                                               const Eigen::Isometry3d& T1_camera_world,
                                               const Eigen::Vector3d& r2,
                                               const Eigen::Isometry3d& T2_camera_world) {
  const Eigen::Matrix<double, 3, 4> P1 = T1_camera_world.matrix().topRows<3>();
  const Eigen::Matrix<double, 3, 4> P2 = T2_camera_world.matrix().topRows<3>();
  Eigen::Matrix4d A;
  A.row(0) = r1.x() * P1.row(2) - P1.row(0);
  A.row(1) = r1.y() * P1.row(2) - P1.row(1);
  A.row(2) = r2.x() * P2.row(2) - P2.row(0);
  A.row(3) = r2.y() * P2.row(2) - P2.row(1);
  const Eigen::Vector4d h =
      Eigen::JacobiSVD<Eigen::Matrix4d>(A, Eigen::ComputeFullV).matrixV().col(3);
  if (std::abs(h.w()) < 1e-12) return std::nullopt;
  return Eigen::Vector3d(h.head<3>() / h.w());
}

// The two nearest descriptors to `descriptor` among the `candidates` of `other` (not yet
// `used`) that lie on the epipolar `line` (chi-square 3.84 at their scale).
BestTwo NearestOnEpipolarLine(const uint8_t* descriptor, const Eigen::Vector3d& line,
                              const Frame& other, const std::vector<int>& candidates,
                              const std::vector<bool>& used) {
  const std::vector<double>& scale = other.geometry->scale;
  const double line_norm2 = line.x() * line.x() + line.y() * line.y();
  BestTwo nearest;
  for (int j : candidates) {
    if (used[static_cast<size_t>(j)]) continue;
    const size_t jj = static_cast<size_t>(j);
    const Eigen::Vector3d x2(other.undistorted[jj].x, other.undistorted[jj].y, 1.0);
    const double d = line.dot(x2);
    const int level = other.keypoints[jj].octave;
    if (d * d / line_norm2 >
        3.84 * scale[static_cast<size_t>(level)] * scale[static_cast<size_t>(level)]) {
      continue;  // off the epipolar line
    }
    nearest.Add(DescriptorDistance(descriptor, other.descriptors.ptr<uint8_t>(j)), j);
  }
  return nearest;
}

}  // namespace

int LocalMapper::TriangulateNewPoints(KeyFrame* kf) {
  const FrameGeometry& g = *kf->frame.geometry;
  const PinholeIntrinsics& k = g.intrinsics;
  const Eigen::Matrix3d K = (Eigen::Matrix3d() << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1).finished();
  const Eigen::Matrix3d K_inv = K.inverse();
  const double baseline = k.bf / k.fx;
  const double ratio_factor = 1.5 * (g.scale.size() > 1 ? g.scale[1] : 1.2);
  int created = 0;
  for (KeyFrame* other : kf->Covisible(static_cast<size_t>(options_.triangulation_neighbours))) {
    if (other->bad) continue;
    // Below the virtual stereo baseline, the depth sensor knows better than triangulation.
    if ((other->CameraCentre() - kf->CameraCentre()).norm() < baseline) continue;
    // Fundamental matrix from kf to other: x_other^T F x_kf = 0.
    const Eigen::Isometry3d T_other_kf = other->pose() * kf->pose().inverse();
    const Eigen::Matrix3d F =
        K_inv.transpose() * Hat(T_other_kf.translation()) * T_other_kf.linear() * K_inv;
    std::vector<int> free_other;
    for (size_t j = 0; j < other->frame.size(); ++j) {
      const MapPoint* p = other->frame.map_points[j];
      const int feature = static_cast<int>(j);
      if ((p == nullptr || p->bad) && other->frame.MakesPoints(feature))
        free_other.push_back(feature);
    }
    std::vector<bool> used(other->frame.size(), false);
    for (size_t i = 0; i < kf->frame.size(); ++i) {
      const MapPoint* existing = kf->frame.map_points[i];
      const int feature = static_cast<int>(i);
      if ((existing != nullptr && !existing->bad) || !kf->frame.MakesPoints(feature)) continue;
      const Eigen::Vector3d x1(kf->frame.undistorted[i].x, kf->frame.undistorted[i].y, 1.0);
      const BestTwo nearest =
          NearestOnEpipolarLine(kf->frame.descriptors.ptr<uint8_t>(static_cast<int>(i)), F * x1,
                                other->frame, free_other, used);
      // Repetitive texture puts look-alikes on the same epipolar line: demand a clear winner.
      if (!nearest.found() || nearest.best > kMatchStrict || nearest.Ambiguous(0.8)) continue;
      const int best_j = nearest.best_index;
      const size_t j = static_cast<size_t>(best_j);
      const std::optional<Eigen::Vector3d> triangulated =
          TriangulateRays(K_inv * x1, kf->pose(),
                          K_inv * Eigen::Vector3d(other->frame.undistorted[j].x,
                                                  other->frame.undistorted[j].y, 1.0),
                          other->pose());
      if (!triangulated) continue;
      const Eigen::Vector3d X = *triangulated;
      // Enough parallax, in front of both, consistent in both images and in scale.
      const Eigen::Vector3d ray1 = X - kf->CameraCentre(), ray2 = X - other->CameraCentre();
      if (ray1.normalized().dot(ray2.normalized()) > 0.9998) continue;
      if (FailsChi2(*kf, static_cast<int>(i), X) || FailsChi2(*other, best_j, X)) continue;
      // Where a view measured depth, the triangulation must agree with it.
      const double z1 = (kf->pose() * X).z(), z2 = (other->pose() * X).z();
      if (kf->frame.depth[i] > 0 && std::abs(z1 - kf->frame.depth[i]) > 0.05 * kf->frame.depth[i])
        continue;
      if (other->frame.depth[j] > 0 &&
          std::abs(z2 - other->frame.depth[j]) > 0.05 * other->frame.depth[j])
        continue;
      const double distance_ratio = ray1.norm() / ray2.norm();
      const double scale_ratio = g.scale[static_cast<size_t>(kf->frame.keypoints[i].octave)] /
                                 g.scale[static_cast<size_t>(other->frame.keypoints[j].octave)];
      if (distance_ratio * ratio_factor < scale_ratio ||
          distance_ratio > scale_ratio * ratio_factor)
        continue;
      MapPoint* p = map_->AddMapPoint(X, kf);
      map_->AddObservation(p, kf, static_cast<int>(i));
      map_->AddObservation(p, other, best_j);
      p->UpdateFromObservations();
      recent_points_.push_back(p);
      used[j] = true;
      ++created;
    }
  }
  return created;
}

int LocalMapper::FuseWithNeighbours(KeyFrame* kf) {
  std::vector<KeyFrame*> targets;
  std::set<uint64_t> chosen{kf->id};
  for (KeyFrame* n : kf->Covisible(static_cast<size_t>(options_.fuse_neighbours))) {
    if (n->bad || !chosen.insert(n->id).second) continue;
    targets.push_back(n);
    for (KeyFrame* m : n->Covisible(5)) {
      if (!m->bad && chosen.insert(m->id).second) targets.push_back(m);
    }
  }
  int fused = 0;
  for (KeyFrame* target : targets) fused += Fuse(*map_, target, kf->frame.map_points);
  std::vector<MapPoint*> candidates;
  std::set<uint64_t> seen;
  for (KeyFrame* target : targets) {
    for (MapPoint* p : target->frame.map_points) {
      if (p != nullptr && !p->bad && seen.insert(p->id).second) candidates.push_back(p);
    }
  }
  fused += Fuse(*map_, kf, candidates);
  for (MapPoint* p : kf->frame.map_points) {
    if (p != nullptr && !p->bad) p->UpdateFromObservations();
  }
  map_->UpdateConnections(kf);
  return fused;
}

std::vector<KeyFrame*> LocalMapper::LocalWindow(KeyFrame* kf) const {
  return WithStrongestNeighbours(kf, options_.local_keyframes);
}

LocalMapper::BaWindow LocalMapper::SelectBaWindow(KeyFrame* kf) const {
  // Every map point a local keyframe holds is in the problem, so a local keyframe brings one
  // observation per point it holds. The new keyframe always takes part. The neighbours take at
  // most three quarters of the budget, so that the keyframes beyond them are held fixed instead
  // of left out: a budget spent on neighbours alone cost static_room's keyframes 2.7 -> 4.3 mm.
  BaWindow w;
  const int local_budget = options_.max_ba_observations * 3 / 4;
  int observations = 0;
  for (KeyFrame* k : LocalWindow(kf)) {
    const int held =
        static_cast<int>(std::count_if(k->frame.map_points.begin(), k->frame.map_points.end(),
                                       [](const MapPoint* p) { return p != nullptr && !p->bad; }));
    if (!w.local.empty() && observations + held > local_budget) break;
    w.local.push_back(k);
    observations += held;
  }
  std::set<uint64_t> local_ids;
  for (const KeyFrame* k : w.local) local_ids.insert(k->id);
  std::set<uint64_t> point_ids;
  for (KeyFrame* k : w.local) {
    for (MapPoint* p : k->frame.map_points) {
      if (p != nullptr && !p->bad && point_ids.insert(p->id).second) w.points.push_back(p);
    }
  }
  // Fixed: the other observers of the window's points, those that see most of them first.
  std::map<uint64_t, std::pair<int, KeyFrame*>> observers;
  for (MapPoint* p : w.points) {
    for (const auto& [kf_id, obs] : p->observations) {
      if (local_ids.count(kf_id) || obs.first->bad) continue;
      auto& [count, keyframe] = observers[kf_id];
      ++count;
      keyframe = obs.first;
    }
  }
  std::vector<std::pair<int, KeyFrame*>> ranked;
  for (const auto& [id, entry] : observers) ranked.push_back(entry);
  std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second->id < b.second->id;
  });
  for (const auto& [count, keyframe] : ranked) {
    if (static_cast<int>(w.fixed.size()) >= options_.fixed_keyframes ||
        observations + count > options_.max_ba_observations)
      break;
    w.fixed.push_back(keyframe);
    observations += count;
  }
  std::sort(w.fixed.begin(), w.fixed.end(),
            [](const KeyFrame* a, const KeyFrame* b) { return a->id < b->id; });
  return w;
}

BundleAdjustmentProblem LocalMapper::MakeBaProblem(const BaWindow& window,
                                                   std::vector<BaLink>* links) {
  BundleAdjustmentProblem ba;
  std::map<uint64_t, int> pose_index;
  for (KeyFrame* k : window.local) {
    pose_index[k->id] = static_cast<int>(ba.poses.size());
    ba.poses.push_back(k->pose());
    ba.pose_fixed.push_back(k->id == 0);  // the first keyframe holds the gauge
  }
  for (KeyFrame* k : window.fixed) {
    pose_index[k->id] = static_cast<int>(ba.poses.size());
    ba.poses.push_back(k->pose());
    ba.pose_fixed.push_back(true);
  }
  const std::vector<MapPoint*>& points = window.points;
  for (size_t pi = 0; pi < points.size(); ++pi) {
    ba.points.push_back(points[pi]->position);
    for (const auto& [kf_id, obs] : points[pi]->observations) {
      const auto it = pose_index.find(kf_id);
      if (it == pose_index.end()) continue;
      ba.observations.push_back(
          {it->second, static_cast<int>(pi), obs.first->frame.Observation(obs.second)});
      links->push_back({points[pi], obs.first});
    }
  }
  return ba;
}

void LocalMapper::LocalBundleAdjustment(KeyFrame* kf, MappingResult* result, std::mutex* map_mutex,
                                        const std::atomic<bool>* stop) {
  // Built under the lock, solved without it, written back under it to what still exists:
  // tracking goes on while Ceres runs. Only this thread frees points or culls keyframes, so the
  // pointers stay valid; a point or keyframe culled meanwhile by tracking is skipped.
  auto lock = LockIf(map_mutex, &result->lock_wait_ms);
  const BaWindow window = SelectBaWindow(kf);
  std::vector<BaLink> links;
  BundleAdjustmentProblem ba = MakeBaProblem(window, &links);
  const PinholeIntrinsics intrinsics = kf->frame.geometry->intrinsics;
  const uint64_t epoch = map_->correction_epoch();
  if (lock.owns_lock()) lock.unlock();
  const auto solve_start = std::chrono::steady_clock::now();
  const std::vector<bool> inlier =
      BundleAdjust(intrinsics, &ba, options_.bundle_adjustment, &result->ba, stop);
  result->ba_solve_ms = MsSince(solve_start);
  if (map_mutex != nullptr) {
    const auto wait_start = std::chrono::steady_clock::now();
    lock.lock();
    result->lock_wait_ms += MsSince(wait_start);
  }
  result->local_keyframes = static_cast<int>(window.local.size());
  result->fixed_keyframes = static_cast<int>(window.fixed.size());
  result->local_points = static_cast<int>(window.points.size());
  if (map_->correction_epoch() != epoch) {
    // Loop closing moved the map meanwhile: this solution belongs to the old one.
    result->ba_discarded = true;
    return;
  }
  WriteBackBa(window, ba, inlier, links, result);
}

void LocalMapper::WriteBackBa(const BaWindow& window, const BundleAdjustmentProblem& ba,
                              const std::vector<bool>& inlier, const std::vector<BaLink>& links,
                              MappingResult* result) {
  const std::vector<KeyFrame*>& local = window.local;
  const std::vector<MapPoint*>& points = window.points;
  for (size_t k = 0; k < local.size(); ++k) {
    if (!local[k]->bad) local[k]->frame.T_camera_world = ba.poses[k];
  }
  for (size_t pi = 0; pi < points.size(); ++pi) {
    if (!points[pi]->bad) points[pi]->position = ba.points[pi];
  }
  for (size_t o = 0; o < links.size(); ++o) {
    if (inlier[o] || links[o].point->bad || links[o].keyframe->bad) continue;
    map_->EraseObservation(links[o].point, links[o].keyframe);
    ++result->removed_observations;
  }
  // Positions moved; descriptors change only where an outlier observation went.
  std::set<uint64_t> lost_observation;
  for (size_t o = 0; o < links.size(); ++o) {
    if (!inlier[o]) lost_observation.insert(links[o].point->id);
  }
  for (MapPoint* p : points) {
    if (p->bad) continue;
    if (lost_observation.count(p->id)) p->UpdateDescriptor();
    p->UpdateNormalAndDepth();
  }
}

// Points that count for the redundancy of `candidate` when `kf` is processed, and how many of
// them three other keyframes see.
LocalMapper::Redundancy LocalMapper::RedundantPoints(const KeyFrame* candidate,
                                                     const KeyFrame* kf) const {
  Redundancy r;
  for (size_t i = 0; i < candidate->frame.size(); ++i) {
    const MapPoint* p = candidate->frame.map_points[i];
    if (p == nullptr || p->bad) continue;
    if (static_cast<int>(p->observations.size()) <= options_.transient_observations &&
        p->first_keyframe_id + kProbationKeyFrames <= kf->id)
      continue;  // transient: neither kept nor made redundant
    ++r.points;
    if (p->observations.size() <= 3) continue;
    const int level = candidate->frame.keypoints[i].octave;
    int others = 0;
    for (const auto& [other_id, obs] : p->observations) {
      if (other_id == candidate->id) continue;
      if (obs.first->frame.keypoints[static_cast<size_t>(obs.second)].octave <= level + 1 &&
          ++others >= 3)
        break;
    }
    r.redundant += others >= 3;
  }
  return r;
}

// ORB-SLAM2's rule with two changes. It counts only the points whose depth is "close" (below
// 40 baselines, about 3 m): in a room seen from its middle most points are farther, the ratio
// then rests on a few dozen points, and a camera that never leaves the room kept adding
// keyframes without bound (walking_xyz: 124 alive after 1,500 frames, mapping cost 4x).
// Counting every map point keeps 20 alive there at the same ATE. And a keyframe left without
// any map point (all culled) is culled too: it can no longer help tracking, and the ratio would
// never cull it.
int LocalMapper::CullKeyFrames(KeyFrame* kf) {
  int culled = 0;
  for (KeyFrame* candidate : LocalWindow(kf)) {
    if (candidate->id == 0 || candidate->bad || candidate == kf) continue;
    const Redundancy r = RedundantPoints(candidate, kf);
    if ((r.points == 0 || r.redundant > options_.redundant_ratio * r.points) &&
        map_->SetBad(candidate))
      ++culled;
  }
  return culled;
}

// The crowd is found by a pass over the keyframes' poses, not the map's points: one flag check
// per keyframe ever made (culled ones stay in the map) and a distance check per live one, a few
// thousand at most over a 3,000-frame run, microseconds. Shares are only counted when the crowd
// is over its quota.
int LocalMapper::CullCrowdedKeyFrames(KeyFrame* kf) {
  if (options_.crowded_distance <= 0 || kf->bad) return 0;
  const Eigen::Vector3d centre = kf->CameraCentre();
  const Eigen::Vector3d axis = kf->pose().rotation().row(2).transpose();
  const double min_cos = std::cos(options_.crowded_angle_deg * std::numbers::pi / 180);
  std::vector<KeyFrame*> crowded;
  for (const auto& [id, other] : map_->keyframes()) {
    if (id == 0 || id >= kf->id || other->bad) continue;
    if ((other->CameraCentre() - centre).norm() > options_.crowded_distance) continue;
    if (other->pose().rotation().row(2).dot(axis.transpose()) < min_cos) continue;
    crowded.push_back(other.get());
  }
  if (static_cast<int>(crowded.size()) < options_.crowded_keyframes) return 0;
  // The crowd keeps its most useful members: those with the smallest share of redundant points.
  std::vector<std::pair<double, KeyFrame*>> by_share;
  for (KeyFrame* other : crowded) {
    const Redundancy r = RedundantPoints(other, kf);
    by_share.emplace_back(r.points == 0 ? 1.0 : static_cast<double>(r.redundant) / r.points, other);
  }
  std::sort(by_share.begin(), by_share.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second->id < b.second->id;
  });
  int culled = 0;
  for (const auto& [share, other] : by_share) {
    if (static_cast<int>(crowded.size()) - culled < options_.crowded_keyframes) break;
    culled += map_->SetBad(other);
  }
  return culled;
}

}  // namespace sdoslam
