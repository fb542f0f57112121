#pragma once

// Frames of synth's static room for the map-level tests (matching, fusion, tracking's parts):
// one camera, extractor and geometry, and renderings with sensor noise at their true poses.
// Header-only: the tests that include it link sdoslam_synth.

#include <memory>

#include "sdoslam/map/frame.h"
#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sensor.h"

namespace sdoslam::testing {

class RoomFrames {
 public:
  RoomFrames()
      : camera_(synth::SyntheticCamera()),
        extractor_(std::make_unique<OrbExtractor>(OrbOptions{})),
        geometry_(std::make_shared<FrameGeometry>(camera_, *extractor_, 40.0, 3.0)),
        scenario_(synth::MakeScenario("static_room", 10.0, synth::CameraMotion::kHalfsphere)) {}

  // The room at time t (seconds of the 10-s halfsphere motion) with sensor noise `noise_seed`:
  // colour, depth in metres and the true pose.
  struct View {
    cv::Mat bgr, depth;
    Eigen::Isometry3d T_world_camera;
  };
  View Render(double t, int noise_seed) const {
    View v;
    v.T_world_camera = synth::CameraPoseAt(scenario_.motion, t, 10.0);
    const synth::RenderedView view = synth::Render(scenario_.scene, t, v.T_world_camera, camera_);
    const synth::SensorFrame sensed = synth::Sense(view, camera_.options(), {}, 1, noise_seed);
    v.bgr = sensed.bgr;
    sensed.depth.convertTo(v.depth, CV_32F, 1.0 / 5000.0);
    return v;
  }
  // Render's view as frame `index`, at its true pose.
  Frame MakeFrame(size_t index, double t, int noise_seed) const {
    const View v = Render(t, noise_seed);
    Frame frame(index, t, v.bgr, v.depth, geometry_, *extractor_);
    frame.T_camera_world = v.T_world_camera.inverse();
    return frame;
  }

  const OrbExtractor& extractor() const { return *extractor_; }
  const std::shared_ptr<FrameGeometry>& geometry() const { return geometry_; }

 private:
  Camera camera_;
  std::unique_ptr<OrbExtractor> extractor_;
  std::shared_ptr<FrameGeometry> geometry_;
  synth::Scenario scenario_;
};

// A map point for every feature of `keyframe` with depth, observed by it alone.
inline std::vector<MapPoint*> AddDepthPoints(Map& map, KeyFrame* keyframe) {
  std::vector<MapPoint*> points;
  for (size_t i = 0; i < keyframe->frame.size(); ++i) {
    if (!keyframe->frame.HasDepth(static_cast<int>(i))) continue;
    MapPoint* p = map.AddMapPoint(keyframe->frame.UnprojectWorld(static_cast<int>(i)), keyframe);
    map.AddObservation(p, keyframe, static_cast<int>(i));
    p->UpdateFromObservations();
    points.push_back(p);
  }
  return points;
}

}  // namespace sdoslam::testing
