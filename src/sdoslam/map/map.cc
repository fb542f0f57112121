#include "sdoslam/map/map.h"

#include <algorithm>
#include <cmath>

namespace sdoslam {

MapPoint::MapPoint(uint64_t point_id, const Eigen::Vector3d& p, KeyFrame* ref)
    : id(point_id), position(p), reference(ref), first_keyframe_id(ref->id) {}

int MapPoint::PredictLevel(double distance, const FrameGeometry& g) const {
  const double ratio = max_distance / distance;
  const int level = static_cast<int>(std::ceil(std::log(ratio) / g.log_scale_factor));
  return std::clamp(level, 0, static_cast<int>(g.scale.size()) - 1);
}

void MapPoint::UpdateFromObservations() {
  UpdateDescriptor();
  UpdateNormalAndDepth();
}

void MapPoint::UpdateDescriptor() {
  if (bad || observations.empty()) return;
  // The choice is quadratic in the candidates, so a point seen by hundreds of keyframes (a map
  // that keeps every keyframe, as conventional tracking does with people in view) takes at
  // most kMaxDescriptorCandidates of them, spread evenly over its observations from the oldest
  // to the newest so that every stretch of viewpoints has a say. Below the cap every
  // observation is a candidate, as before.
  const size_t total = observations.size();
  const size_t take = std::min(total, kMaxDescriptorCandidates);
  std::vector<const uint8_t*> descriptors;
  descriptors.reserve(take);
  // Candidate k is observation floor(k * total / take): every observation when take == total.
  size_t index = 0, next = 0;
  for (const auto& [kf_id, obs] : observations) {
    if (index++ != next) continue;
    const auto& [kf, i] = obs;
    descriptors.push_back(kf->frame.descriptors.ptr<uint8_t>(i));
    next = descriptors.size() * total / take;
  }
  // Representative descriptor: least median distance to the others (the first on ties).
  const size_t n = descriptors.size();
  std::vector<int> distances(n * n, 0);
  for (size_t a = 0; a < n; ++a) {
    for (size_t b = a + 1; b < n; ++b) {
      distances[a * n + b] = distances[b * n + a] =
          DescriptorDistance(descriptors[a], descriptors[b]);
    }
  }
  size_t best = 0;
  int best_median = 1 << 30;
  const size_t middle = (n - 1) / 2;
  std::vector<int> row(n);
  for (size_t a = 0; a < n; ++a) {
    std::copy(distances.begin() + static_cast<long>(a * n),
              distances.begin() + static_cast<long>((a + 1) * n), row.begin());
    std::nth_element(row.begin(), row.begin() + static_cast<long>(middle), row.end());
    if (row[middle] < best_median) {
      best_median = row[middle];
      best = a;
    }
  }
  descriptor = cv::Mat(1, 32, CV_8U, const_cast<uint8_t*>(descriptors[best])).clone();
}

void MapPoint::UpdateNormalAndDepth() {
  if (bad || observations.empty()) return;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const auto& [kf_id, obs] : observations) {
    sum += (position - obs.first->CameraCentre()).normalized();
  }
  normal = sum.normalized();
  const auto ref = observations.find(reference->id);
  const auto& [kf, feature] =
      ref != observations.end() ? ref->second : observations.begin()->second;
  const FrameGeometry& g = *kf->frame.geometry;
  const double distance = (position - kf->CameraCentre()).norm();
  const int level = kf->frame.keypoints[static_cast<size_t>(feature)].octave;
  max_distance = distance * g.scale[static_cast<size_t>(level)];
  min_distance = max_distance / g.scale.back();
}

KeyFrame::KeyFrame(uint64_t keyframe_id, Frame f) : id(keyframe_id), frame(std::move(f)) {}

std::vector<KeyFrame*> KeyFrame::Covisible(size_t count) const {
  if (best_covisible.size() <= count) return best_covisible;
  return {best_covisible.begin(), best_covisible.begin() + static_cast<long>(count)};
}

int KeyFrame::TrackedPoints(int min_observations) const {
  int n = 0;
  for (const MapPoint* p : frame.map_points) {
    if (p != nullptr && !p->bad && static_cast<int>(p->observations.size()) >= min_observations)
      ++n;
  }
  return n;
}

std::vector<KeyFrame*> WithStrongestNeighbours(KeyFrame* kf, int count) {
  std::vector<KeyFrame*> out{kf};
  for (KeyFrame* n : kf->best_covisible) {  // by weight, then id
    if (static_cast<int>(out.size()) > count) break;
    if (!n->bad && n != kf) out.push_back(n);
  }
  return out;
}

Eigen::Isometry3d ComposeWithReference(const KeyFrame* reference,
                                       const Eigen::Isometry3d& T_camera_reference) {
  Eigen::Isometry3d T = T_camera_reference;
  while (reference->bad && reference->parent != nullptr) {
    T = T * reference->T_camera_parent;
    reference = reference->parent;
  }
  return T * reference->pose();
}

KeyFrame* Map::AddKeyFrame(Frame frame) {
  const uint64_t id = next_keyframe_id_++;
  auto [it, inserted] = keyframes_.emplace(id, std::make_unique<KeyFrame>(id, std::move(frame)));
  ++good_keyframes_;
  return it->second.get();
}

MapPoint* Map::AddMapPoint(const Eigen::Vector3d& position, KeyFrame* reference) {
  const uint64_t id = next_point_id_++;
  auto [it, inserted] = points_.emplace(id, std::make_unique<MapPoint>(id, position, reference));
  ++good_points_;
  return it->second.get();
}

void Map::Bury(MapPoint* point) {
  point->bad = true;
  --good_points_;
  graveyard_.push_back({point, finished_frames_, next_keyframe_id_});
}

size_t Map::CollectGarbage() {
  // Graves are in culling order, so both conditions hold for a prefix.
  size_t freed = 0;
  while (freed < graveyard_.size()) {
    const Grave& g = graveyard_[freed];
    if (finished_frames_ <= g.finished_frames || inserted_keyframes_ < g.keyframes_made) break;
    points_.erase(g.point->id);
    ++freed;
  }
  graveyard_.erase(graveyard_.begin(), graveyard_.begin() + static_cast<long>(freed));
  return freed;
}

void Map::AddObservation(MapPoint* point, KeyFrame* kf, int feature) {
  point->observations[kf->id] = {kf, feature};
  kf->frame.map_points[static_cast<size_t>(feature)] = point;
}

void Map::EraseObservation(MapPoint* point, KeyFrame* kf) {
  const auto it = point->observations.find(kf->id);
  if (it == point->observations.end()) return;
  kf->frame.map_points[static_cast<size_t>(it->second.second)] = nullptr;
  point->observations.erase(it);
  if (point->reference == kf && !point->observations.empty())
    point->reference = point->observations.begin()->second.first;
  // ORB-SLAM counts an RGB-D observation twice and drops points with <= 2: one keyframe left.
  if (point->observations.size() <= 1) SetBad(point);
}

void Map::SetBad(MapPoint* point) {
  if (point->bad) return;
  Bury(point);
  for (const auto& [kf_id, obs] : point->observations) {
    obs.first->frame.map_points[static_cast<size_t>(obs.second)] = nullptr;
  }
  point->observations.clear();
}

void Map::Replace(MapPoint* point, MapPoint* by) {
  if (point == by || point->bad) return;
  const auto observations = point->observations;
  point->observations.clear();
  Bury(point);
  for (const auto& [kf_id, obs] : observations) {
    auto [kf, feature] = obs;
    if (by->observations.count(kf_id)) {
      kf->frame.map_points[static_cast<size_t>(feature)] = nullptr;  // already seen there
    } else {
      AddObservation(by, kf, feature);
    }
  }
  by->visible += point->visible;
  by->found += point->found;
  by->UpdateFromObservations();
}

void Map::UpdateConnections(KeyFrame* kf) {
  std::map<uint64_t, int> counts;
  std::map<uint64_t, KeyFrame*> by_id;
  for (const MapPoint* p : kf->frame.map_points) {
    if (p == nullptr || p->bad) continue;
    for (const auto& [other_id, obs] : p->observations) {
      if (other_id == kf->id || obs.first->bad) continue;
      ++counts[other_id];
      by_id[other_id] = obs.first;
    }
  }
  // Old edges of this keyframe go away from the other side too (and from its best list, below,
  // where no new edge takes their place).
  std::vector<KeyFrame*> old_neighbours;
  for (const auto& [other_id, weight] : kf->covisibility) {
    const auto it = keyframes_.find(other_id);
    if (it == keyframes_.end()) continue;
    it->second->covisibility.erase(kf->id);
    old_neighbours.push_back(it->second.get());
  }
  kf->covisibility.clear();
  constexpr int kMinShared = 15;
  uint64_t best_id = 0;
  int best_count = -1;
  for (const auto& [other_id, count] : counts) {
    if (count > best_count) {
      best_count = count;
      best_id = other_id;
    }
    if (count >= kMinShared) kf->covisibility[other_id] = count;
  }
  if (kf->covisibility.empty() && best_count > 0) kf->covisibility[best_id] = best_count;
  auto sort_best = [&](KeyFrame* k) {
    k->best_covisible.clear();
    std::vector<std::pair<int, uint64_t>> order;
    for (const auto& [id, w] : k->covisibility) order.emplace_back(-w, id);
    std::sort(order.begin(), order.end());
    for (const auto& [w, id] : order) k->best_covisible.push_back(keyframes_.at(id).get());
  };
  for (const auto& [other_id, count] : kf->covisibility) {
    KeyFrame* other = by_id[other_id];
    other->covisibility[kf->id] = count;
    sort_best(other);
  }
  for (KeyFrame* other : old_neighbours) {
    if (kf->covisibility.count(other->id) == 0) sort_best(other);
  }
  sort_best(kf);
  if (kf->parent != nullptr || kf->id == 0) return;
  // The parent is the most covisible keyframe that does not descend from this one. A keyframe
  // still without a parent here is the first of a map started again (its first points were its
  // own): its children are the keyframes it shares most with, and taking one of them as its
  // parent would close a cycle that culling then turns into a keyframe that is its own parent
  // (ComposeWithReference never ended on such a run).
  KeyFrame* parent = nullptr;
  int parent_count = 0;
  for (const auto& [other_id, count] : counts) {
    if (count > parent_count && !DescendsFrom(by_id[other_id], kf)) {
      parent_count = count;
      parent = by_id[other_id];
    }
  }
  if (parent != nullptr) SetParent(kf, parent);
}

bool DescendsFrom(const KeyFrame* keyframe, const KeyFrame* ancestor) {
  for (const KeyFrame* k = keyframe; k != nullptr; k = k->parent) {
    if (k == ancestor) return true;
  }
  return false;
}

void Map::SetParent(KeyFrame* kf, KeyFrame* parent) {
  if (kf->parent != nullptr) kf->parent->children.erase(kf->id);
  kf->parent = parent;
  if (parent != nullptr) parent->children[kf->id] = kf;
}

bool Map::SetBad(KeyFrame* kf) {
  if (kf->id == 0 || kf->bad || kf->parent == nullptr) return false;
  // Invariant: parents are good, so the parent is the first good ancestor.
  KeyFrame* parent = kf->parent;
  kf->bad = true;
  --good_keyframes_;
  for (MapPoint* p : std::vector<MapPoint*>(kf->frame.map_points)) {
    if (p != nullptr && !p->bad) EraseObservation(p, kf);
  }
  for (const auto& [other_id, weight] : kf->covisibility) {
    KeyFrame* other = keyframes_.at(other_id).get();
    other->covisibility.erase(kf->id);
    other->best_covisible.erase(
        std::remove(other->best_covisible.begin(), other->best_covisible.end(), kf),
        other->best_covisible.end());
  }
  kf->covisibility.clear();
  kf->best_covisible.clear();
  // Frames tracked relative to this keyframe, or to a culled child of it, keep their pose
  // through T_camera_parent: this keyframe's own, and each culled child's composed with it
  // (the child skips this keyframe from now on).
  kf->T_camera_parent = kf->pose() * parent->pose().inverse();
  const std::map<uint64_t, KeyFrame*> children = std::move(kf->children);
  kf->children.clear();
  for (const auto& [id, child] : children) {
    if (child->bad) child->T_camera_parent = child->T_camera_parent * kf->T_camera_parent;
    child->parent = parent;
    parent->children[id] = child;
  }
  kf->frame.ReleaseFeatures();
  return true;
}

void Map::NoteCorrection(std::map<uint64_t, Eigen::Isometry3d> change_by_keyframe) {
  corrections_.push_back(std::move(change_by_keyframe));
  if (corrections_.size() > kMaxCorrections) corrections_.pop_front();
  ++correction_epoch_;
}

Eigen::Isometry3d Map::CorrectionSince(const KeyFrame* keyframe, uint64_t since) const {
  while (keyframe != nullptr && keyframe->bad) keyframe = keyframe->parent;
  Eigen::Isometry3d change = Eigen::Isometry3d::Identity();
  if (keyframe == nullptr) return change;
  // corrections_.back() is epoch correction_epoch_, the one before it epoch − 1, ...
  const uint64_t first_kept = correction_epoch_ - corrections_.size() + 1;
  for (uint64_t epoch = std::max(since + 1, first_kept); epoch <= correction_epoch_; ++epoch) {
    const auto& changes = corrections_[static_cast<size_t>(epoch - first_kept)];
    const auto it = changes.find(keyframe->id);
    if (it != changes.end()) change = change * it->second;
  }
  return change;
}

}  // namespace sdoslam
