#include "sdoslam/tracking/relocalizer.h"

#include <algorithm>
#include <opencv2/calib3d.hpp>
#include <set>

#include "sdoslam/matching/matcher.h"

namespace sdoslam {

Relocalizer::Relocalizer(Map* map, const TrackerOptions& options, KeyFramePlaces* places)
    : map_(map), places_(places), options_(options) {}

bool Relocalizer::RelocalizeNearPrediction(Frame& frame, const Prior& prior, uint64_t* frame_stamp,
                                           const RefinePose& refine_pose) const {
  if (prior.frames_lost >= options_.relocalization_prior_frames) return false;
  // Every map point: the part of the room that comes back into view is often one that only
  // keyframes outside the reference's covisible set saw (synthetic loop: a person passing close
  // hid one side of the view, then the other), and the projection test keeps the search to
  // the points in view. A map that follows the place stays small.
  std::vector<MapPoint*> points;
  points.reserve(map_->points().size());
  for (const auto& [id, p] : map_->points()) {
    if (!p->bad && !p->observations.empty()) points.push_back(p.get());
  }
  // prior.velocity still holds the motion between the last two tracked frames.
  Eigen::Isometry3d carried_on = prior.last_frame.T_camera_world;
  for (int k = 0; k <= prior.frames_lost; ++k) carried_on = prior.velocity * carried_on;
  for (const Eigen::Isometry3d& prediction : {carried_on, prior.last_frame.T_camera_world}) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    frame.T_camera_world = prediction;
    // A stamp of its own per try (the search skips points stamped with the stamp it is given);
    // TrackLocalMap then searches at the found pose under a fresh one.
    const int matches = SearchLocalPoints(frame, points, ++*frame_stamp,
                                          options_.relocalization_radius_factor, false);
    if (matches >= 20 && refine_pose(frame) >= options_.min_inliers) {
      ++*frame_stamp;
      return true;
    }
  }
  ++*frame_stamp;
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  frame.T_camera_world = prior.last_frame.T_camera_world;
  return false;
}

namespace {

// The frame's pose from its matches alone (the last pose may be far off): PnP in RANSAC on the
// undistorted keypoints; the matches it leaves out are unmatched. OpenCV's RANSAC draws from a
// fixed seed: runs stay repeatable. False (the frame untouched but for its matches) when fewer
// than 15 matches or inliers.
bool PoseByPnp(Frame& frame) {
  const PinholeIntrinsics& k = frame.geometry->intrinsics;
  const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
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
  if (object.size() < 15) return false;
  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  if (!cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 200, 4.0f, 0.99,
                          inliers, cv::SOLVEPNP_EPNP) ||
      inliers.size() < 15) {
    return false;
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
  return true;
}

}  // namespace

bool Relocalizer::Relocalize(Frame& frame, const Prior& prior, KeyFrame** reference,
                             uint64_t* frame_stamp, const RefinePose& refine_pose) const {
  if (RelocalizeNearPrediction(frame, prior, frame_stamp, refine_pose)) return true;
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
  add(*reference);
  if (*reference != nullptr) {
    for (KeyFrame* n : (*reference)->Covisible(options_.relocalization_candidates)) add(n);
  }
  int recent = 0;
  for (auto it = map_->keyframes().rbegin();
       it != map_->keyframes().rend() && recent < options_.relocalization_candidates; ++it) {
    if (!it->second->bad) {
      add(it->second.get());
      ++recent;
    }
  }
  // The frame's words: for place recognition and vocabulary-guided matching.
  const bool have_places = places_ != nullptr && places_->size() > 0;
  FeatureVector frame_words;
  const BowVector bow = have_places ? places_->Describe(frame, &frame_words) : BowVector{};
  if (have_places && options_.relocalization_place_candidates > 0) {
    for (const PlaceIndex::Candidate& c : places_->Query(
             *map_, bow, static_cast<size_t>(options_.relocalization_place_candidates))) {
      add(map_->keyframes().at(c.id).get());
    }
  }
  for (KeyFrame* kf : candidates) {
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    // Vocabulary-guided where the keyframe is among the places (see the matcher).
    const FeatureVector* kf_words = have_places ? places_->Features(kf->id) : nullptr;
    if (SearchByDescriptor(frame, *kf, kf_words, kf_words != nullptr ? &frame_words : nullptr) < 15)
      continue;
    if (!PoseByPnp(frame)) continue;
    if (refine_pose(frame) >= 10) {
      *reference = kf;
      return true;
    }
  }
  std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
  frame.T_camera_world = prior.last_frame.T_camera_world;
  return false;
}

}  // namespace sdoslam
