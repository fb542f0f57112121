#include "sdoslam/matching/matcher.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "sdoslam/matching/best_two.h"

namespace sdoslam {
namespace {

constexpr int kHistogramBins = 30;

// Orientation consistency: the rotation between two frames is common to all correct matches,
// so only matches in the three most populated bins of angle change are kept.
class RotationHistogram {
 public:
  void Add(float angle_a, float angle_b, int index) {
    float d = angle_a - angle_b;
    if (d < 0) d += 360.0f;
    const int bin = std::min(kHistogramBins - 1, static_cast<int>(d * kHistogramBins / 360.0f));
    bins_[static_cast<size_t>(bin)].push_back(index);
  }
  // Indices outside the three largest bins.
  std::vector<int> Rejected() const {
    std::array<size_t, kHistogramBins> order;
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](size_t a, size_t b) { return bins_[a].size() > bins_[b].size(); });
    std::vector<int> rejected;
    const size_t largest = bins_[order[0]].size();
    for (size_t r = 0; r < order.size(); ++r) {
      // Keep a bin among the top three unless it is tiny compared with the top one.
      const bool keep = r < 3 && bins_[order[r]].size() * 10 >= largest;
      if (!keep) rejected.insert(rejected.end(), bins_[order[r]].begin(), bins_[order[r]].end());
    }
    return rejected;
  }

 private:
  std::array<std::vector<int>, kHistogramBins> bins_;
};

// Projects a world point into a camera at T_camera_world; false when behind it or outside the
// (undistorted) image. `p` receives the point in the camera frame.
bool ProjectIntoImage(const FrameGeometry& g, const Eigen::Isometry3d& T_camera_world,
                      const Eigen::Vector3d& X, Eigen::Vector3d* p, double* u, double* v) {
  *p = T_camera_world * X;
  if (p->z() <= 0) return false;
  *u = g.intrinsics.fx * p->x() / p->z() + g.intrinsics.cx;
  *v = g.intrinsics.fy * p->y() / p->z() + g.intrinsics.cy;
  return g.InImage(*u, *v);
}

}  // namespace

bool PredictInView(const FrameGeometry& g, const Eigen::Isometry3d& T_camera_world,
                   const Eigen::Vector3d& centre, const MapPoint& point, PredictedView* view) {
  if (!ProjectIntoImage(g, T_camera_world, point.position, &view->p, &view->u, &view->v))
    return false;
  const Eigen::Vector3d ray = point.position - centre;
  view->distance = ray.norm();
  if (view->distance < 0.8 * point.min_distance || view->distance > 1.2 * point.max_distance)
    return false;
  view->view_cos = ray.dot(point.normal) / view->distance;
  return view->view_cos >= 0.5;
}

int SearchByProjection(Frame& current, const Frame& last, double radius) {
  const FrameGeometry& g = *current.geometry;
  const Eigen::Isometry3d& T = current.T_camera_world;
  RotationHistogram histogram;
  int matches = 0;
  for (size_t i = 0; i < last.size(); ++i) {
    MapPoint* point = last.map_points[i];
    if (point == nullptr || point->bad || last.outlier[i]) continue;
    Eigen::Vector3d p;
    double u, v;
    if (!ProjectIntoImage(g, T, point->position, &p, &u, &v)) continue;
    const int level = last.keypoints[i].octave;
    const auto candidates = current.FeaturesInArea(
        u, v, radius * g.scale[static_cast<size_t>(level)], std::max(0, level - 1), level + 1);
    BestTwo nearest;
    for (int j : candidates) {
      const MapPoint* existing = current.map_points[static_cast<size_t>(j)];
      if (existing != nullptr && existing->found > 0 && !existing->bad) continue;
      if (current.right_u[static_cast<size_t>(j)] >= 0) {
        // The depth must agree too: compare the predicted and measured right coordinates.
        const double ur = u - g.intrinsics.bf / p.z();
        if (std::abs(ur - current.right_u[static_cast<size_t>(j)]) >
            radius * g.scale[static_cast<size_t>(level)])
          continue;
      }
      nearest.Add(
          DescriptorDistance(point->descriptor.ptr<uint8_t>(), current.descriptors.ptr<uint8_t>(j)),
          j);
    }
    if (nearest.found() && nearest.best <= kMatchLoose) {
      const int j = nearest.best_index;
      current.map_points[static_cast<size_t>(j)] = point;
      histogram.Add(last.keypoints[i].angle, current.keypoints[static_cast<size_t>(j)].angle, j);
      ++matches;
    }
  }
  for (int j : histogram.Rejected()) {
    current.map_points[static_cast<size_t>(j)] = nullptr;
    --matches;
  }
  return matches;
}

int SearchLocalPoints(Frame& current, const std::vector<MapPoint*>& points, uint64_t frame_stamp,
                      double radius_factor, bool count_visible) {
  const FrameGeometry& g = *current.geometry;
  const Eigen::Isometry3d& T = current.T_camera_world;
  const Eigen::Vector3d centre = current.CameraCentre();
  int matches = 0;
  for (MapPoint* point : points) {
    if (point->bad || point->last_seen_frame == frame_stamp) continue;  // already matched
    PredictedView view;
    if (!PredictInView(g, T, centre, *point, &view)) continue;
    const auto& [p, u, v, distance, view_cos] = view;
    if (count_visible) ++point->visible;
    const int level = point->PredictLevel(distance, g);
    const double radius =
        radius_factor * (view_cos > 0.998 ? 2.5 : 4.0) * g.scale[static_cast<size_t>(level)];
    const auto candidates = current.FeaturesInArea(u, v, radius, level - 1, level);
    BestTwo nearest;
    for (int j : candidates) {
      const MapPoint* existing = current.map_points[static_cast<size_t>(j)];
      if (existing != nullptr && !existing->bad && existing->observations.size() > 0) continue;
      if (current.right_u[static_cast<size_t>(j)] >= 0) {
        const double ur = u - g.intrinsics.bf / p.z();
        if (std::abs(ur - current.right_u[static_cast<size_t>(j)]) > radius) continue;
      }
      nearest.Add(
          DescriptorDistance(point->descriptor.ptr<uint8_t>(), current.descriptors.ptr<uint8_t>(j)),
          j);
    }
    if (!nearest.found() || nearest.best > kMatchLoose) continue;
    // Ambiguous only when the runner-up is on the same pyramid level (-1: there is none).
    const auto level_of = [&](int j) {
      return j < 0 ? -1 : current.keypoints[static_cast<size_t>(j)].octave;
    };
    if (level_of(nearest.best_index) == level_of(nearest.second_index) && nearest.Ambiguous(0.8))
      continue;
    current.map_points[static_cast<size_t>(nearest.best_index)] = point;
    point->last_seen_frame = frame_stamp;
    ++matches;
  }
  return matches;
}

int SearchByDescriptor(Frame& current, const KeyFrame& keyframe,
                       const FeatureVector* keyframe_words, const FeatureVector* current_words) {
  int matches = 0;
  RotationHistogram histogram;
  std::vector<int> best_for_feature(current.size(), 256);
  // Keyframe feature i against the frame's features `candidates` (nullptr: all of them).
  auto match = [&](size_t i, const std::vector<int>* candidates) {
    MapPoint* point = keyframe.frame.map_points[i];
    if (point == nullptr || point->bad) return;
    BestTwo nearest;
    const uint8_t* d_kf = keyframe.frame.descriptors.ptr<uint8_t>(static_cast<int>(i));
    auto consider = [&](int j) {
      if (!current.IsStatic(j)) return;
      nearest.Add(DescriptorDistance(d_kf, current.descriptors.ptr<uint8_t>(j)), j);
    };
    if (candidates == nullptr) {
      for (size_t j = 0; j < current.size(); ++j) consider(static_cast<int>(j));
    } else {
      for (int j : *candidates) consider(j);
    }
    if (!nearest.found() || nearest.best > kMatchStrict || nearest.Ambiguous(0.7)) return;
    const int best = nearest.best, best_index = nearest.best_index;
    if (best >= best_for_feature[static_cast<size_t>(best_index)]) return;
    if (current.map_points[static_cast<size_t>(best_index)] == nullptr) ++matches;
    best_for_feature[static_cast<size_t>(best_index)] = best;
    current.map_points[static_cast<size_t>(best_index)] = point;
    histogram.Add(keyframe.frame.keypoints[i].angle,
                  current.keypoints[static_cast<size_t>(best_index)].angle, best_index);
  };
  if (keyframe_words != nullptr && current_words != nullptr) {
    // Both maps are ordered by node: walk them side by side.
    auto a = keyframe_words->begin(), b = current_words->begin();
    while (a != keyframe_words->end() && b != current_words->end()) {
      if (a->first < b->first) {
        ++a;
      } else if (b->first < a->first) {
        ++b;
      } else {
        for (int i : a->second) {
          if (i >= 0 && static_cast<size_t>(i) < keyframe.frame.size())
            match(static_cast<size_t>(i), &b->second);
        }
        ++a;
        ++b;
      }
    }
  } else {
    for (size_t i = 0; i < keyframe.frame.size(); ++i) match(i, nullptr);
  }
  for (int j : histogram.Rejected()) {
    if (current.map_points[static_cast<size_t>(j)] != nullptr) --matches;
    current.map_points[static_cast<size_t>(j)] = nullptr;
  }
  return matches;
}
}  // namespace sdoslam
