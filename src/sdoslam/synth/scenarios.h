#pragma once

#include <optional>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/synth/scene.h"

namespace sdoslam::synth {

// Camera motions modelled on the TUM RGB-D dynamic sequences (and OMD's "unconstrained").
// kLongLoop: a handheld walk once around the room's centre, looking out at the walls and
// furniture, that ends by retracing its first stretch (see LongLoopPoseAtArc).
enum class CameraMotion { kStatic, kXyz, kRpy, kHalfsphere, kUnconstrained, kLoop, kLongLoop };
CameraMotion ParseCameraMotion(const std::string& name);  // throws Error listing the names
std::string ToString(CameraMotion motion);
std::vector<std::string> CameraMotionNames();

// Camera pose at time t of a sequence lasting `duration` seconds (the loop closes at t =
// duration, the long loop before it: see below). World frame: x right, y into the room, z up;
// camera: x right, y down, z forward.
Eigen::Isometry3d CameraPoseAt(CameraMotion motion, double t, double duration);

// The long loop (kLongLoop), exposed for its tests: an 8.5 m closed curve walked once, then on
// along its first metres again, so that the last seconds see again what the first saw.
//
// The frames at 30 Hz it is made for (about 0.45 m/s); fewer walk faster than a hand-held camera.
inline constexpr int kLongLoopFrames = 700;
double LongLoopLength();   // one lap, metres
double LongLoopRetrace();  // metres walked again after the lap
// Arc length walked by time t of a sequence of `duration` seconds; starts and ends at rest.
double LongLoopArcAt(double t, double duration);
// The camera at arc length s; periodic: the pose at s + LongLoopLength() is the pose at s.
Eigen::Isometry3d LongLoopPoseAtArc(double s);

struct Scenario {
  std::string name;
  std::string description;
  CameraMotion motion = CameraMotion::kStatic;
  Scene scene;
  // SensorOptions::depth_distortion for this scenario (the default sensor has none).
  double depth_distortion = 0.0;
};

// The named scenarios: static_room, walking_static, walking_xyz, walking_rpy,
// walking_halfsphere, boxes_translational, boxes_unconstrained, mixed, loop, box_alongside,
// parked_cart, long_loop, long_loop_people.
std::vector<std::string> ScenarioNames();

// Builds scenario `name` for a sequence of `duration` seconds; `motion` overrides its camera
// motion (e.g. static_room with halfsphere). Throws Error for an unknown name, listing the known.
Scenario MakeScenario(const std::string& name, double duration,
                      std::optional<CameraMotion> motion = std::nullopt);

// The pose with this position and rotation.
Eigen::Isometry3d Pose(const Eigen::Vector3d& position,
                       const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity());

// Building blocks of scenes, in a world frame with z up (also used by the real-background
// sequences, which place them in a frame levelled on the recording's first camera).
//
// A walking person shuttling between a and b (floor points) with period `period` seconds:
// legs and arms swing with the gait, the body turns at the ends of its path. Class "person".
SceneObject Person(uint16_t id, const std::string& name, const Eigen::Vector3d& a,
                   const Eigen::Vector3d& b, double period, double phase,
                   const Eigen::Vector3f& shirt, const Eigen::Vector3f& trousers,
                   double start_time = 0.0);
// When a SittingPerson does what (seconds of the sequence, in this order).
struct SittingSchedule {
  double arrive;  // walks in until then
  double seated;  // sits down until then
  double rise;    // sits still until then
  double stood;   // stands up until then
  double gone;    // walks off until then (and stands there after)
};
// A person who walks in along `walk` (a floor vector) to `feet` (where its feet are while it
// sits), turns to face `facing_yaw` (the body's forward, y, turned about z) and sits down on a
// seat 0.45 m high behind the feet, sits still, stands up and walks on along `walk` as far again.
// Thighs and shins are separate parts, so the knees bend. Class "person".
SceneObject SittingPerson(uint16_t id, const std::string& name, const Eigen::Vector3d& feet,
                          const Eigen::Vector3d& walk, double facing_yaw,
                          const SittingSchedule& schedule, const Eigen::Vector3f& shirt,
                          const Eigen::Vector3f& trousers);
// A box hanging from `pivot` on a rigid rod of `length`, swinging about a horizontal axis
// (OMD-style); no known class.
SceneObject Pendulum(uint16_t id, const std::string& name, const Eigen::Vector3d& pivot,
                     double length, double axis_yaw, double amplitude, double period, double phase,
                     const Eigen::Vector3d& size, const Eigen::Vector3f& colour,
                     double start_time = 0.0);
// A rigid textured box moving along `pose` (its centre and orientation at time t).
SceneObject RigidBox(uint16_t id, const std::string& name,
                     std::function<Eigen::Isometry3d(double)> pose,
                     const Eigen::Vector3d& half_size, const Eigen::Vector3f& colour,
                     uint32_t texture_seed);

// The synthetic camera: 640×480, the TUM freiburg3 intrinsics, no distortion, depth factor 5000.
CameraOptions SyntheticCamera();

}  // namespace sdoslam::synth
