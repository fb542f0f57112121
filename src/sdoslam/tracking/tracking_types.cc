#include "sdoslam/tracking/tracking_types.h"

#include "sdoslam/core/error.h"

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

void TrackerOptions::Check(const std::string& path) const {
  if (min_initial_depth_features < 10)
    throw Error(path + "min_initial_depth_features must be >= 10");
  if (min_inliers < 6) throw Error(path + "min_inliers must be >= 6");
  if (max_frames_between_keyframes < 1)
    throw Error(path + "max_frames_between_keyframes must be >= 1");
  if (min_frames_between_keyframes < 0 ||
      min_frames_between_keyframes > max_frames_between_keyframes)
    throw Error(path + "min_frames_between_keyframes must lie in [0, " + path +
                "max_frames_between_keyframes]");
  if (!(reference_ratio > 0 && reference_ratio < 1))
    throw Error(path + "reference_ratio must be in (0, 1)");
  if (!(projection_radius > 0)) throw Error(path + "projection_radius must be positive");
  if (!(local_map_radius > 0)) throw Error(path + "local_map_radius must be positive");
  if (relocalization_candidates < 0) throw Error(path + "relocalization_candidates must be >= 0");
  if (relocalization_place_candidates < 0)
    throw Error(path + "relocalization_place_candidates must be >= 0");
  if (relocalization_prior_frames < 0)
    throw Error(path + "relocalization_prior_frames must be >= 0");
  if (restart_below_keyframes < 0) throw Error(path + "restart_below_keyframes must be >= 0");
  if (!(relocalization_radius_factor >= 1))
    throw Error(path + "relocalization_radius_factor must be >= 1");
  if (keyframes_min_static_samples < 0)
    throw Error(path + "keyframes_min_static_samples must be >= 0");
  if (keyframes_min_static_features < 0)
    throw Error(path + "keyframes_min_static_features must be >= 0");
  consistency.Check(path + "consistency.");
}

}  // namespace sdoslam
