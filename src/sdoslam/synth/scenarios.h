#pragma once

#include <optional>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/synth/scene.h"

namespace sdoslam::synth {

// Camera motions modelled on the TUM RGB-D dynamic sequences (and OMD's "unconstrained").
enum class CameraMotion { kStatic, kXyz, kRpy, kHalfsphere, kUnconstrained, kLoop };
CameraMotion ParseCameraMotion(const std::string& name);  // throws Error listing the names
std::string ToString(CameraMotion motion);
std::vector<std::string> CameraMotionNames();

// Camera pose at time t of a sequence lasting `duration` seconds (the loop closes at t =
// duration). World frame: x right, y into the room, z up; camera: x right, y down, z forward.
Eigen::Isometry3d CameraPoseAt(CameraMotion motion, double t, double duration);

struct Scenario {
  std::string name;
  std::string description;
  CameraMotion motion = CameraMotion::kStatic;
  Scene scene;
};

// The named scenarios: static_room, walking_static, walking_xyz, walking_rpy,
// walking_halfsphere, boxes_translational, boxes_unconstrained, mixed, loop, box_alongside,
// parked_cart.
std::vector<std::string> ScenarioNames();

// Builds scenario `name` for a sequence of `duration` seconds; `motion` overrides its camera
// motion (e.g. static_room with halfsphere). Throws Error for an unknown name, listing the known.
Scenario MakeScenario(const std::string& name, double duration,
                      std::optional<CameraMotion> motion = std::nullopt);

// The synthetic camera: 640×480, the TUM freiburg3 intrinsics, no distortion, depth factor 5000.
CameraOptions SyntheticCamera();

}  // namespace sdoslam::synth
