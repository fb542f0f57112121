#pragma once

#include <memory>

#include "sdoslam/core/camera.h"
#include "sdoslam/core/config.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/mapping/local_mapper.h"
#include "sdoslam/tracking/tracker.h"

namespace YAML {
class Emitter;
}

namespace sdoslam {

struct SlamOptions {
  OrbOptions orb;
  TrackerOptions tracking;
  LocalMapperOptions mapping;
  double bf = 40.0;                     // virtual stereo baseline × fx (ORB-SLAM2's Kinect value)
  double close_depth_baselines = 40.0;  // "close" = depth < this × baseline (≈3.1 m for TUM)
  void Check() const;
};

// Reads the optional sections orb:, rgbd:, tracking:, mapping: of a run config (the camera:
// section is read by ReadCameraOptions); unknown keys are errors.
SlamOptions ReadSlamOptions(ConfigMap& root);
void WriteSlamOptions(const SlamOptions& options, YAML::Emitter* out);

// Timings of one frame, milliseconds.
struct FrameTiming {
  double features_ms = 0, tracking_ms = 0, mapping_ms = 0;
};

// The library's face: feed RGB-D frames in order, read trajectories. Local mapping runs inline
// after each new keyframe, so a run is reproducible bit for bit.
class System {
 public:
  System(const CameraOptions& camera, const SlamOptions& options);
  ~System();

  // bgr: CV_8UC3; depth: CV_32FC1 metres (0 = none), registered to the colour image.
  TrackingResult TrackRgbd(size_t index, double timestamp, const cv::Mat& bgr, const cv::Mat& depth,
                           FrameTiming* timing = nullptr);

  // Every tracked frame (lost ones left out), with its pose relative to its reference keyframe
  // composed with that keyframe's current (refined) pose. T_world_camera per pose.
  Trajectory CameraTrajectory() const;
  Trajectory KeyFrameTrajectory() const;
  const Map& map() const { return *map_; }

 private:
  SlamOptions options_;
  OrbExtractor extractor_;
  std::shared_ptr<const FrameGeometry> geometry_;
  std::unique_ptr<Map> map_;
  std::unique_ptr<Tracker> tracker_;
  std::unique_ptr<LocalMapper> mapper_;
};

}  // namespace sdoslam
