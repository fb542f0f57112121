#pragma once

#include <cstdint>

#include "sdoslam/map/map.h"
#include "sdoslam/place/keyframe_places.h"
#include "sdoslam/tracking/tracking_types.h"

namespace sdoslam {

// Finds the pose of a frame that frame-to-frame tracking could not: first by a projection
// search of the whole map around where the camera should be, then by descriptor matching and
// PnP in RANSAC against candidate keyframes (the reference keyframe and its best neighbours,
// the keyframes made last, and those anywhere in the map whose bags of words look most like the
// frame). Holds no state of its own: the Tracker's comes with each call.
class Relocalizer {
 public:
  // `places` (optional): keyframes by their bags of words; then the keyframes anywhere in the
  // map that look like the lost frame are candidates too.
  Relocalizer(Map* map, const TrackerOptions& options, KeyFramePlaces* places = nullptr);

  // What the Tracker knows of where the camera was.
  struct Prior {
    const Frame& last_frame;            // the last tracked frame
    const Eigen::Isometry3d& velocity;  // the motion between the last two tracked frames
    int frames_lost;                    // frames since the last tracked one
  };

  // After tracking was lost: the pose from a search around the prediction
  // (RelocalizeNearPrediction), else from descriptor matches with candidate keyframes; the
  // keyframe that gave it then becomes `*reference`. On success the frame holds the pose and
  // its matches (the inliers of a pose optimisation by `refine_pose`); on failure no matches
  // and the last frame's pose. `frame_stamp`: the Tracker's stamp for local-map searches
  // (SearchLocalPoints), advanced past the stamps used here.
  bool Relocalize(Frame& frame, const Prior& prior, KeyFrame** reference, uint64_t* frame_stamp,
                  const RefinePose& refine_pose) const;

  // A projection search of the whole map around predicted poses (the last pose carried on at
  // the last velocity, then the last pose itself), in windows relocalization_radius_factor
  // times the local-map search's: Relocalize's first try, and a tracked camera's last before it
  // is called lost. Only for frames lost fewer than relocalization_prior_frames. Succeeds when
  // min_inliers remain after `refine_pose`.
  bool RelocalizeNearPrediction(Frame& frame, const Prior& prior, uint64_t* frame_stamp,
                                const RefinePose& refine_pose) const;

 private:
  Map* map_;
  KeyFramePlaces* places_;
  TrackerOptions options_;
};

}  // namespace sdoslam
