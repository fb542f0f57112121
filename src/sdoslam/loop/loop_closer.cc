#include "sdoslam/loop/loop_closer.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "sdoslam/core/error.h"
#include "sdoslam/core/stopwatch.h"
#include "sdoslam/mapping/fuse.h"
#include "sdoslam/matching/matcher.h"
#include "sdoslam/optim/optimizer.h"

namespace sdoslam {

void LoopClosingOptions::Check(const std::string& path) const {
  if (min_keyframes_between < 1) throw Error(path + "min_keyframes_between must be >= 1");
  if (consistent_detections < 0) throw Error(path + "consistent_detections must be >= 0");
  if (min_matches < 3) throw Error(path + "min_matches must be >= 3");
  if (verify_neighbours < 0) throw Error(path + "verify_neighbours must be >= 0");
  if (!(min_correction_m >= 0)) throw Error(path + "min_correction_m must be >= 0");
  if (!(min_correction_deg >= 0)) throw Error(path + "min_correction_deg must be >= 0");
  if (min_inliers < 3) throw Error(path + "min_inliers must be >= 3");
  if (min_projected_inliers < min_inliers)
    throw Error(path + "min_projected_inliers must be >= " + path + "min_inliers");
  if (essential_min_weight < 1) throw Error(path + "essential_min_weight must be >= 1");
  if (essential_max_covisible < 0) throw Error(path + "essential_max_covisible must be >= 0");
  if (fuse_keyframes < 0) throw Error(path + "fuse_keyframes must be >= 0");
  ransac.Check(path + "ransac.");
  pose_graph.Check(path + "pose_graph.");
  global_ba.Check(path + "global_ba.");
  if (max_global_ba_observations < 1) throw Error(path + "max_global_ba_observations must be >= 1");
}

namespace {

// The map points of the place a loop closes on: the keyframe's and its `neighbours` most
// covisible keyframes', each once, in the order met.
std::vector<MapPoint*> LoopSidePoints(KeyFrame* loop, int neighbours) {
  std::vector<MapPoint*> points;
  std::set<uint64_t> seen;
  for (const KeyFrame* kf : WithStrongestNeighbours(loop, neighbours)) {
    for (MapPoint* p : kf->frame.map_points) {
      if (p != nullptr && !p->bad && seen.insert(p->id).second) points.push_back(p);
    }
  }
  return points;
}

// The ids of kf's strongest covisibility links that `accept` lets through, at most `count`,
// strongest first; links of fewer than `min_weight` shared points end the search. The essential
// graph and a loop's new links take each keyframe's few strongest: in a dense map, all of them
// grow with the map.
template <typename Accept>
std::vector<uint64_t> StrongestLinks(const KeyFrame& kf, int count, int min_weight, Accept accept) {
  std::vector<uint64_t> ids;
  for (const KeyFrame* n : kf.best_covisible) {
    if (static_cast<int>(ids.size()) >= count) break;
    const auto w = kf.covisibility.find(n->id);
    if (w == kf.covisibility.end() || w->second < min_weight) break;
    if (accept(*n)) ids.push_back(n->id);
  }
  return ids;
}

}  // namespace

LoopCloser::LoopCloser(Map* map, KeyFramePlaces* places, const LoopClosingOptions& options)
    : map_(map), places_(places), options_((options.Check(), options)) {}

LoopResult LoopCloser::Process(KeyFrame* keyframe, std::mutex* map_mutex,
                               std::condition_variable* frame_done,
                               const std::function<bool()>& between_frames) {
  LoopResult result;
  const auto start = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock;
  if (map_mutex != nullptr) lock = std::unique_lock<std::mutex>(*map_mutex);
  if (keyframe->bad) return result;  // culled by local mapping: its features are gone
  // Described and indexed even with loop closing off: relocalization looks places up too.
  FeatureVector words;  // for vocabulary-guided matching, here and in relocalization
  const BowVector bow = places_->Describe(keyframe->frame, &words);
  const std::vector<KeyFrame*> candidates =
      options_.enabled ? DetectCandidates(keyframe, bow) : std::vector<KeyFrame*>{};
  places_->Add(keyframe, bow, std::move(words));
  result.detect_ms = MsSince(start);
  if (candidates.empty()) return result;
  result.detected = true;
  // Verification searches the map by projection and correction moves it: neither may meet a
  // frame that tracking has half done.
  if (lock.owns_lock() && frame_done != nullptr && between_frames)
    frame_done->wait(lock, between_frames);
  if (keyframe->bad) return result;
  for (KeyFrame* candidate : candidates) {
    if (candidate->bad) continue;
    Verified verified;
    const auto verify_start = std::chrono::steady_clock::now();
    const bool verified_ok = Verify(keyframe, candidate, &verified);
    result.record.verify_ms += MsSince(verify_start);
    if (!verified_ok) continue;
    if (!CorrectsEnough(options_, keyframe->pose(), verified.T_camera_world)) {
      spdlog::debug("loop: keyframe {} agrees with {} already: not closed", keyframe->id,
                    candidate->id);
      continue;
    }
    Correct(keyframe, verified, &result.record);
    if (options_.global_bundle_adjustment)
      GlobalBundleAdjustment(&lock, frame_done, between_frames, &result.record);
    result.closed = true;
    groups_.clear();
    last_loop_keyframe_ = keyframe->id;
    closed_any_ = true;
    break;
  }
  result.record.ms = MsSince(start);
  return result;
}

std::vector<KeyFrame*> LoopCloser::DetectCandidates(KeyFrame* keyframe, const BowVector& bow) {
  if (map_->GoodKeyFrames() <= static_cast<size_t>(options_.min_keyframes_between) ||
      (closed_any_ && keyframe->id < last_loop_keyframe_ + options_.min_keyframes_between) ||
      bow.empty()) {
    groups_.clear();
    return {};
  }
  // The least similar of the keyframe's covisible neighbours sets the bar: a loop candidate
  // must look at least as much like this keyframe as the keyframes that share its view.
  double min_score = 1.0;
  bool any_neighbour = false;
  for (const KeyFrame* n : keyframe->best_covisible) {
    if (n->bad) continue;
    const BowVector* other = places_->Find(n->id);
    if (other == nullptr) continue;
    min_score = std::min(min_score, Vocabulary::Score(bow, *other));
    any_neighbour = true;
  }
  if (!any_neighbour) min_score = 0;
  std::set<uint64_t> connected{keyframe->id};
  for (const auto& [id, weight] : keyframe->covisibility) connected.insert(id);
  const auto found =
      places_->Query(*map_, bow, 64, [&](uint64_t id) { return connected.count(id) == 0; });
  std::map<uint64_t, double> score;
  for (const PlaceIndex::Candidate& c : found) {
    if (c.score >= min_score) score[c.id] = c.score;
  }
  spdlog::debug(
      "loop: keyframe {} (frame {}): min score {:.3f}, {} found, {} above, best {} {:.3f}",
      keyframe->id, keyframe->frame.index, min_score, found.size(), score.size(),
      found.empty() ? 0 : found[0].id, found.empty() ? 0.0 : found[0].score);
  if (score.empty()) {
    groups_.clear();
    return {};
  }
  return ConsistentCandidates(Representatives(score));
}

std::vector<KeyFrame*> LoopCloser::Representatives(const std::map<uint64_t, double>& score) const {
  // ORB-SLAM2's accumulated score: a place is seen by several keyframes; a candidate counts
  // with its covisible neighbours that were found too, and stands for its group by the best
  // single score in it.
  struct Scored {
    KeyFrame* best;
    double accumulated;
  };
  std::vector<Scored> scored;
  double best_accumulated = 0;
  for (const auto& [id, s] : score) {
    KeyFrame* candidate = map_->keyframes().at(id).get();
    double accumulated = s, best_score = s;
    KeyFrame* best = candidate;
    for (KeyFrame* n : candidate->Covisible(10)) {
      const auto it = score.find(n->id);
      if (it == score.end()) continue;
      accumulated += it->second;
      if (it->second > best_score) {
        best_score = it->second;
        best = n;
      }
    }
    scored.push_back({best, accumulated});
    best_accumulated = std::max(best_accumulated, accumulated);
  }
  std::vector<KeyFrame*> representatives;
  std::set<uint64_t> chosen;
  for (const Scored& s : scored) {
    if (s.accumulated >= 0.75 * best_accumulated && chosen.insert(s.best->id).second)
      representatives.push_back(s.best);
  }
  return representatives;
}

std::vector<KeyFrame*> LoopCloser::ConsistentCandidates(
    const std::vector<KeyFrame*>& representatives) {
  // Consistency over consecutive keyframes: a group (a representative and its covisible
  // keyframes) continues a group of the previous keyframe when they share a keyframe.
  std::vector<Group> groups;
  std::vector<bool> continued(groups_.size(), false);
  std::vector<KeyFrame*> accepted;
  for (KeyFrame* r : representatives) {
    Group group;
    group.keyframes.insert(r->id);
    for (const auto& [id, weight] : r->covisibility) group.keyframes.insert(id);
    bool enough = false, any = false;
    for (size_t g = 0; g < groups_.size(); ++g) {
      const bool shares = std::any_of(group.keyframes.begin(), group.keyframes.end(),
                                      [&](uint64_t id) { return groups_[g].keyframes.count(id); });
      if (!shares) continue;
      any = true;
      const int consistency = groups_[g].consistency + 1;
      if (!continued[g]) {
        groups.push_back({group.keyframes, consistency});
        continued[g] = true;
      }
      if (consistency >= options_.consistent_detections && !enough) {
        accepted.push_back(r);
        enough = true;
      }
    }
    if (!any) {
      groups.push_back({group.keyframes, 0});
      if (options_.consistent_detections == 0) accepted.push_back(r);
    }
  }
  groups_ = std::move(groups);
  spdlog::debug("loop: {} representatives, {} groups, {} accepted", representatives.size(),
                groups_.size(), accepted.size());
  return accepted;
}

int LoopCloser::MatchPlace(KeyFrame* keyframe, KeyFrame* candidate, Frame* probe) const {
  std::fill(probe->map_points.begin(), probe->map_points.end(), nullptr);
  std::set<uint64_t> matched_points;
  int matches = 0;
  Frame search = keyframe->frame;
  for (KeyFrame* kf : WithStrongestNeighbours(candidate, options_.verify_neighbours)) {
    const FeatureVector* words = places_->Features(kf->id);
    if (kf->bad || words == nullptr) continue;
    std::fill(search.map_points.begin(), search.map_points.end(), nullptr);
    // Vocabulary-guided (both keyframes are in the places).
    SearchByDescriptor(search, *kf, words, places_->Features(keyframe->id));
    for (size_t i = 0; i < search.size(); ++i) {
      MapPoint* p = search.map_points[i];
      if (p == nullptr || probe->map_points[i] != nullptr || !matched_points.insert(p->id).second)
        continue;
      probe->map_points[i] = p;
      ++matches;
    }
  }
  return matches;
}

bool LoopCloser::Verify(KeyFrame* keyframe, KeyFrame* candidate, Verified* verified) {
  Frame probe = keyframe->frame;
  verified->matches = MatchPlace(keyframe, candidate, &probe);
  spdlog::debug("loop: verify keyframe {} against {}: {} matches", keyframe->id, candidate->id,
                verified->matches);
  if (verified->matches < options_.min_matches) return false;
  // The keyframe's own measurement of each matched point, in its camera frame, against the
  // point where the loop side put it: the rigid motion between them is the keyframe's pose in
  // the loop side's map.
  std::vector<Eigen::Vector3d> world, camera;
  std::vector<int> feature;
  std::vector<MapPoint*> matched_point;
  const Eigen::Isometry3d& T_old = keyframe->pose();
  for (size_t i = 0; i < probe.size(); ++i) {
    MapPoint* p = probe.map_points[i];
    if (p == nullptr || p->bad || !probe.HasDepth(static_cast<int>(i))) continue;
    matched_point.push_back(p);
    world.push_back(p->position);
    camera.push_back(T_old * probe.UnprojectWorld(static_cast<int>(i)));
    feature.push_back(static_cast<int>(i));
  }
  const RigidRansacResult ransac = EstimateRigidTransformRansac(world, camera, options_.ransac);
  spdlog::debug("loop: ransac {} inliers of {}", ransac.num_inliers, world.size());
  if (!ransac.found || ransac.num_inliers < options_.min_inliers) return false;

  // Refined on the reprojection error of the inliers, then widened to every point of the loop
  // side in view.
  std::fill(probe.map_points.begin(), probe.map_points.end(), nullptr);
  for (size_t k = 0; k < feature.size(); ++k) {
    if (ransac.inlier[k]) probe.map_points[static_cast<size_t>(feature[k])] = matched_point[k];
  }
  auto optimize = [&](Frame& f) {
    std::vector<int> index;
    std::vector<Eigen::Vector3d> points;
    std::vector<PointObservation> observations;
    for (size_t i = 0; i < f.size(); ++i) {
      const MapPoint* p = f.map_points[i];
      if (p == nullptr || p->bad) continue;
      index.push_back(static_cast<int>(i));
      points.push_back(p->position);
      observations.push_back(f.Observation(static_cast<int>(i)));
    }
    if (index.size() < 10) return 0;
    const PoseOptimizationResult r =
        OptimizePose(f.geometry->intrinsics, f.T_camera_world, points, observations);
    f.T_camera_world = r.T_camera_world;
    for (size_t k = 0; k < index.size(); ++k) {
      if (!r.inlier[k]) f.map_points[static_cast<size_t>(index[k])] = nullptr;
    }
    return r.num_inliers;
  };
  probe.T_camera_world = ransac.T_b_a;
  verified->inliers = optimize(probe);
  if (verified->inliers < options_.min_inliers) return false;

  // Every covisible keyframe's: one projection search, cheap next to fusing.
  const std::vector<MapPoint*> loop_points =
      LoopSidePoints(candidate, std::numeric_limits<int>::max());
  // A stamp space of its own (top bit set), apart from tracking's frame stamps.
  const uint64_t stamp = (uint64_t{1} << 63) | ++search_stamp_;
  for (MapPoint* p : probe.map_points) {
    if (p != nullptr) p->last_seen_frame = stamp;
  }
  SearchLocalPoints(probe, loop_points, stamp, 2.0, false);
  verified->projected_inliers = optimize(probe);
  spdlog::debug("loop: {} inliers after the pose, {} after the projection search",
                verified->inliers, verified->projected_inliers);
  if (verified->projected_inliers < options_.min_projected_inliers) return false;
  verified->loop = candidate;
  verified->T_camera_world = probe.T_camera_world;
  verified->matched = probe.map_points;
  return true;
}

bool CorrectsEnough(const LoopClosingOptions& options, const Eigen::Isometry3d& T_camera_world,
                    const Eigen::Isometry3d& corrected_T_camera_world) {
  const double metres =
      (T_camera_world.inverse().translation() - corrected_T_camera_world.inverse().translation())
          .norm();
  const Eigen::AngleAxisd turn(corrected_T_camera_world.linear() *
                               T_camera_world.linear().transpose());
  return metres >= options.min_correction_m ||
         turn.angle() * 180.0 / M_PI >= options.min_correction_deg;
}

void LoopCloser::Correct(KeyFrame* keyframe, const Verified& verified, LoopRecord* record) {
  KeyFrame* loop = verified.loop;
  record->frame_index = keyframe->frame.index;
  record->loop_frame_index = loop->frame.index;
  record->keyframe_id = keyframe->id;
  record->loop_keyframe_id = loop->id;
  record->matches = verified.matches;
  record->inliers = verified.inliers;
  record->projected_inliers = verified.projected_inliers;
  record->correction_m =
      (keyframe->CameraCentre() - verified.T_camera_world.inverse().translation()).norm();

  auto stage_start = std::chrono::steady_clock::now();
  std::map<uint64_t, Eigen::Isometry3d> before;  // every good keyframe's pose before the loop
  for (const auto& [id, kf] : map_->keyframes()) {
    if (!kf->bad) before[id] = kf->pose();
  }
  std::set<uint64_t> connected_ids;
  const std::map<uint64_t, uint64_t> corrected_by =
      MoveToLoop(keyframe, verified.T_camera_world, &connected_ids);
  record->fused_points = FuseAcrossLoop(keyframe, verified, connected_ids);
  record->fuse_ms = MsSince(stage_start);
  stage_start = std::chrono::steady_clock::now();

  CorrectedGraph corrected = SpreadCorrection(loop, before, record);
  record->pose_graph_ms = MsSince(stage_start);
  stage_start = std::chrono::steady_clock::now();

  MovePoints(keyframe, before, corrected_by, &corrected);
  record->points_ms = MsSince(stage_start);
}

std::map<uint64_t, uint64_t> LoopCloser::MoveToLoop(KeyFrame* keyframe,
                                                    const Eigen::Isometry3d& T_camera_world,
                                                    std::set<uint64_t>* connected_ids) {
  // 1. The keyframe and its neighbours move rigidly to the loop, and their points with them.
  const std::vector<KeyFrame*> connected =
      WithStrongestNeighbours(keyframe, std::numeric_limits<int>::max());
  for (const KeyFrame* kf : connected) connected_ids->insert(kf->id);
  const Eigen::Isometry3d change = keyframe->pose().inverse() * T_camera_world;
  std::map<uint64_t, uint64_t> corrected_by;  // point id -> keyframe whose move it followed
  std::vector<MapPoint*> moved;
  for (KeyFrame* kf : connected) {
    const Eigen::Isometry3d T_new = kf->pose() * change;
    const Eigen::Isometry3d to_new = T_new.inverse() * kf->pose();  // old world -> new world
    for (MapPoint* p : kf->frame.map_points) {
      if (p == nullptr || p->bad || !corrected_by.emplace(p->id, kf->id).second) continue;
      p->position = to_new * p->position;
      moved.push_back(p);
    }
    kf->frame.T_camera_world = T_new;
  }
  for (MapPoint* p : moved) p->UpdateNormalAndDepth();
  return corrected_by;
}

int LoopCloser::FuseAcrossLoop(KeyFrame* keyframe, const Verified& verified,
                               const std::set<uint64_t>& connected_ids) {
  KeyFrame* loop = verified.loop;
  // 2. The matched points become the loop side's, and the loop side's points are fused into
  // the neighbours: the map holds each place once.
  int fused = 0;
  for (size_t i = 0; i < verified.matched.size(); ++i) {
    MapPoint* q = verified.matched[i];
    if (q == nullptr || q->bad) continue;
    MapPoint* p = keyframe->frame.map_points[i];
    if (p != nullptr && !p->bad) {
      if (p != q) {
        map_->Replace(p, q);
        ++fused;
      }
    } else if (!q->observations.count(keyframe->id)) {
      map_->AddObservation(q, keyframe, static_cast<int>(i));
      q->UpdateFromObservations();
      ++fused;
    }
  }
  const std::vector<MapPoint*> loop_points = LoopSidePoints(loop, options_.fuse_keyframes);
  // The keyframe and its fuse_keyframes strongest neighbours take the loop side's points.
  const std::vector<KeyFrame*> fused_into =
      WithStrongestNeighbours(keyframe, options_.fuse_keyframes);
  std::map<uint64_t, std::set<uint64_t>> linked_before;
  for (KeyFrame* kf : fused_into) {
    for (const auto& [id, weight] : kf->covisibility) linked_before[kf->id].insert(id);
    fused += Fuse(*map_, kf, loop_points);
  }
  // 3. New covisibility links across the loop are its edges in the essential graph.
  // The strongest links of each keyframe, as in the essential graph: in a dense map each loop
  // would otherwise add its connected keyframes times the loop side's. Only the keyframes fused
  // into are reconnected (ORB-SLAM2: every connected one): each reconnection re-sorts every
  // neighbour's links, and over hundreds of connected keyframes that took 51 s of a closure.
  for (KeyFrame* kf : fused_into) {
    if (kf->bad) continue;
    map_->UpdateConnections(kf);
    const std::set<uint64_t>& old_links = linked_before[kf->id];
    for (const uint64_t id :
         StrongestLinks(*kf, options_.essential_max_covisible, 0, [&](const KeyFrame& n) {
           return !connected_ids.count(n.id) && !old_links.count(n.id);
         })) {
      loop_edges_.insert(std::minmax(kf->id, id));
    }
  }
  loop_edges_.insert(std::minmax(keyframe->id, loop->id));
  return fused;
}

LoopCloser::CorrectedGraph LoopCloser::SpreadCorrection(
    KeyFrame* loop, const std::map<uint64_t, Eigen::Isometry3d>& before, LoopRecord* record) {
  CorrectedGraph corrected;
  PoseGraphProblem& graph = corrected.graph;
  std::vector<KeyFrame*>& keyframes = corrected.keyframes;
  std::vector<KeyFrame*>& pending = corrected.pending;
  // 4. The pose graph spreads the correction: the loop keyframe holds the gauge, spanning-tree
  // and strong covisibility edges keep the odometry measured before the loop, loop edges what
  // the loop measured.
  std::map<uint64_t, int> node;
  for (const auto& [id, kf] : map_->keyframes()) {
    if (kf->bad) continue;
    if (kf->parent == nullptr && kf->covisibility.empty() && id != 0) {
      pending.push_back(kf.get());
      continue;
    }
    node[id] = static_cast<int>(graph.poses.size());
    graph.poses.push_back(kf->pose());
    graph.fixed.push_back(kf.get() == loop);
    keyframes.push_back(kf.get());
  }
  corrected.pre_graph = graph.poses;
  auto measured = [&](uint64_t i, uint64_t j) {
    const auto bi = before.find(i), bj = before.find(j);
    if (bi != before.end() && bj != before.end())
      return Eigen::Isometry3d(bi->second * bj->second.inverse());
    return Eigen::Isometry3d(graph.poses[static_cast<size_t>(node.at(i))] *
                             graph.poses[static_cast<size_t>(node.at(j))].inverse());
  };
  std::set<std::pair<uint64_t, uint64_t>> added;
  auto add_edge = [&](uint64_t i, uint64_t j, const Eigen::Isometry3d& T_i_j) {
    if (!node.count(i) || !node.count(j) || i == j || !added.insert(std::minmax(i, j)).second)
      return;
    graph.edges.push_back({node.at(i), node.at(j), T_i_j, 1.0});
  };
  for (const auto& [a, b] : loop_edges_) {
    if (!node.count(a) || !node.count(b)) continue;
    add_edge(a, b,
             graph.poses[static_cast<size_t>(node.at(a))] *
                 graph.poses[static_cast<size_t>(node.at(b))].inverse());
  }
  for (KeyFrame* kf : keyframes) {
    if (kf->parent != nullptr) add_edge(kf->id, kf->parent->id, measured(kf->id, kf->parent->id));
    // The strongest links to older keyframes, in the covisibility's id order.
    const std::vector<uint64_t> links =
        StrongestLinks(*kf, options_.essential_max_covisible, options_.essential_min_weight,
                       [&](const KeyFrame& n) { return n.id < kf->id; });
    const std::set<uint64_t> strongest(links.begin(), links.end());
    for (const auto& [id, weight] : kf->covisibility) {
      if (strongest.count(id)) add_edge(kf->id, id, measured(kf->id, id));
    }
  }
  record->graph_keyframes = static_cast<int>(graph.poses.size());
  record->graph_edges = static_cast<int>(graph.edges.size());
  OptimizePoseGraph(&graph, options_.pose_graph);
  return corrected;
}

void LoopCloser::MovePoints(KeyFrame* keyframe, const std::map<uint64_t, Eigen::Isometry3d>& before,
                            const std::map<uint64_t, uint64_t>& corrected_by,
                            CorrectedGraph* corrected) {
  const PoseGraphProblem& graph = corrected->graph;
  const std::vector<Eigen::Isometry3d>& pre_graph = corrected->pre_graph;
  std::vector<KeyFrame*>& keyframes = corrected->keyframes;
  // 5. Every point follows the keyframe it was corrected with, or its reference keyframe.
  std::map<uint64_t, Eigen::Isometry3d> to_new;  // keyframe id -> pre-graph world -> new world
  for (size_t k = 0; k < keyframes.size(); ++k) {
    to_new[keyframes[k]->id] = graph.poses[k].inverse() * pre_graph[k];
    keyframes[k]->frame.T_camera_world = graph.poses[k];
  }
  // A keyframe still queued for local mapping has no edges yet; it was made a moment ago, next
  // to the keyframe that closed the loop, and moves with it.
  const Eigen::Isometry3d keyframe_change = before.at(keyframe->id).inverse() * keyframe->pose();
  for (KeyFrame* kf : corrected->pending) {
    const Eigen::Isometry3d T_new = kf->pose() * keyframe_change;
    to_new[kf->id] = T_new.inverse() * kf->pose();
    kf->frame.T_camera_world = T_new;
    keyframes.push_back(kf);
  }
  for (const auto& [id, p] : map_->points()) {
    if (p->bad) continue;
    const auto by = corrected_by.find(id);
    const KeyFrame* ref = nullptr;
    if (by != corrected_by.end() && !map_->keyframes().at(by->second)->bad) {
      ref = map_->keyframes().at(by->second).get();
    } else {
      ref = p->reference;
      while (ref != nullptr && ref->bad) ref = ref->parent;
    }
    if (ref == nullptr) continue;
    const auto it = to_new.find(ref->id);
    if (it == to_new.end()) continue;
    p->position = it->second * p->position;
    p->UpdateNormalAndDepth();
  }
  std::map<uint64_t, Eigen::Isometry3d> change_by_keyframe;
  for (KeyFrame* kf : keyframes) {
    const auto b = before.find(kf->id);
    if (b != before.end()) change_by_keyframe[kf->id] = b->second.inverse() * kf->pose();
  }
  map_->NoteCorrection(std::move(change_by_keyframe));
}

void LoopCloser::GlobalBundleAdjustment(std::unique_lock<std::mutex>* lock,
                                        std::condition_variable* frame_done,
                                        const std::function<bool()>& between_frames,
                                        LoopRecord* record) {
  const auto start = std::chrono::steady_clock::now();
  BundleAdjustmentProblem ba;
  std::vector<KeyFrame*> keyframes;
  std::map<uint64_t, int> pose_index;
  for (const auto& [id, kf] : map_->keyframes()) {
    // Keyframes local mapping has not inserted yet have no observations to fit.
    if (kf->bad || (kf->parent == nullptr && id != 0)) continue;
    pose_index[id] = static_cast<int>(ba.poses.size());
    ba.poses.push_back(kf->pose());
    ba.pose_fixed.push_back(keyframes.empty());  // the first keyframe holds the gauge
    keyframes.push_back(kf.get());
  }
  // Points by id: threaded, local mapping may cull and free a point while the BA is solved
  // without the lock (keyframes are never freed). Counted before anything is copied, so that
  // a BA over the budget costs only the count.
  std::vector<MapPoint*> adjustable;
  int observation_count = 0;
  for (const auto& [id, p] : map_->points()) {
    if (p->bad) continue;
    int observed = 0;
    for (const auto& [kf_id, obs] : p->observations) observed += pose_index.count(kf_id) > 0;
    if (observed < 2) continue;
    adjustable.push_back(p.get());
    observation_count += observed;
  }
  if (keyframes.size() < 2 || adjustable.empty()) return;
  record->global_ba_observations = observation_count;
  if (observation_count > options_.max_global_ba_observations) {
    record->global_ba_skipped = true;
    spdlog::warn(
        "loop closing: global BA over {} keyframes and {} observations skipped (more than "
        "loop_closing.max_global_ba_observations, {}); the pose graph's correction stands",
        keyframes.size(), observation_count, options_.max_global_ba_observations);
    return;
  }
  std::vector<uint64_t> points;
  ba.observations.reserve(static_cast<size_t>(observation_count));
  for (const MapPoint* p : adjustable) {
    const int index = static_cast<int>(points.size());
    points.push_back(p->id);
    ba.points.push_back(p->position);
    for (const auto& [kf_id, obs] : p->observations) {
      const auto it = pose_index.find(kf_id);
      if (it == pose_index.end()) continue;
      ba.observations.push_back({it->second, index, obs.first->frame.Observation(obs.second)});
    }
  }
  const PinholeIntrinsics intrinsics = keyframes.front()->frame.geometry->intrinsics;
  const uint64_t epoch = map_->correction_epoch();
  const bool unlocked = lock->owns_lock();
  if (unlocked) lock->unlock();
  BundleAdjust(intrinsics, &ba, options_.global_ba);
  if (unlocked) {
    lock->lock();
    if (frame_done != nullptr && between_frames) frame_done->wait(*lock, between_frames);
  }
  record->global_ba_ms = MsSince(start);
  if (map_->correction_epoch() != epoch) {
    record->global_ba_discarded = true;
    return;
  }
  WriteBackGlobalBa(keyframes, points, ba);
}

void LoopCloser::WriteBackGlobalBa(const std::vector<KeyFrame*>& keyframes,
                                   const std::vector<uint64_t>& points,
                                   const BundleAdjustmentProblem& ba) {
  // Points made meanwhile (threaded) follow their reference keyframe's move.
  std::map<uint64_t, Eigen::Isometry3d> change_by_keyframe, to_new;
  for (size_t k = 0; k < keyframes.size(); ++k) {
    KeyFrame* kf = keyframes[k];
    if (kf->bad) continue;
    change_by_keyframe[kf->id] = kf->pose().inverse() * ba.poses[k];
    to_new[kf->id] = ba.poses[k].inverse() * kf->pose();
    kf->frame.T_camera_world = ba.poses[k];
  }
  std::set<uint64_t> adjusted;
  for (size_t i = 0; i < points.size(); ++i) {
    const auto it = map_->points().find(points[i]);
    if (it == map_->points().end() || it->second->bad) continue;
    it->second->position = ba.points[i];
    adjusted.insert(points[i]);
  }
  for (const auto& [id, p] : map_->points()) {
    if (p->bad) continue;
    if (!adjusted.count(id)) {
      const KeyFrame* ref = p->reference;
      while (ref != nullptr && ref->bad) ref = ref->parent;
      const auto it = ref != nullptr ? to_new.find(ref->id) : to_new.end();
      if (it != to_new.end()) p->position = it->second * p->position;
    }
    p->UpdateNormalAndDepth();
  }
  map_->NoteCorrection(std::move(change_by_keyframe));
}

}  // namespace sdoslam
