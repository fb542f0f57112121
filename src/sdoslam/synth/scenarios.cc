#include "sdoslam/synth/scenarios.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>

#include "sdoslam/core/error.h"

namespace sdoslam::synth {
namespace {

using Eigen::AngleAxisd;
using Eigen::Isometry3d;
using Eigen::Vector3d;
using Eigen::Vector3f;

constexpr double kPi = 3.14159265358979323846;

Eigen::Matrix3d Rz(double a) { return AngleAxisd(a, Vector3d::UnitZ()).toRotationMatrix(); }
Eigen::Matrix3d Rx(double a) { return AngleAxisd(a, Vector3d::UnitX()).toRotationMatrix(); }
Eigen::Matrix3d Ry(double a) { return AngleAxisd(a, Vector3d::UnitY()).toRotationMatrix(); }

// Camera looking from `eye` at `target`, no roll (world z up).
Isometry3d LookAt(const Vector3d& eye, const Vector3d& target) {
  const Vector3d z = (target - eye).normalized();
  const Vector3d x = z.cross(Vector3d::UnitZ()).normalized();
  const Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R << x, y, z;
  return Pose(eye, R);
}

const Vector3d kEye(0.0, -2.3, 1.3);
const Vector3d kTarget(0.0, 2.0, 0.9);

Primitive Box(const Vector3d& centre, const Vector3d& size, const Vector3f& colour, uint32_t seed,
              double yaw = 0.0) {
  Primitive p;
  p.shape = Primitive::Shape::kBox;
  p.T_world_primitive = Pose(centre, Rz(yaw));
  p.half_size = 0.5 * size;
  p.base_colour = colour;
  p.texture_seed = seed;
  p.T_world_texture = p.T_world_primitive;
  return p;
}

// Room 6 × 7 × 2.8 m (walls as thick boxes outside the volume) with furniture.
std::vector<Primitive> Room() {
  std::vector<Primitive> parts;
  const double hx = 3.0, hy = 3.5, h = 2.8, t = 0.2;
  parts.push_back(
      Box({0, 0, -t / 2}, {2 * hx + 2 * t, 2 * hy + 2 * t, t}, {0.55f, 0.45f, 0.35f}, 1));  // floor
  parts.push_back(Box({0, 0, h + t / 2}, {2 * hx + 2 * t, 2 * hy + 2 * t, t}, {0.85f, 0.85f, 0.8f},
                      2));                                                               // ceiling
  parts.push_back(Box({0, hy + t / 2, h / 2}, {2 * hx, t, h}, {0.7f, 0.75f, 0.8f}, 3));  // far wall
  parts.push_back(
      Box({0, -hy - t / 2, h / 2}, {2 * hx, t, h}, {0.75f, 0.7f, 0.65f}, 4));  // back wall
  parts.push_back(Box({-hx - t / 2, 0, h / 2}, {t, 2 * hy, h}, {0.8f, 0.7f, 0.6f}, 5));  // left
  parts.push_back(Box({hx + t / 2, 0, h / 2}, {t, 2 * hy, h}, {0.6f, 0.7f, 0.8f}, 6));   // right
  // Furniture: desks, cabinets, shelves, boxes and monitors, some turned.
  parts.push_back(Box({-0.8, 1.9, 0.37}, {1.6, 0.8, 0.74}, {0.6f, 0.45f, 0.3f}, 10));
  parts.push_back(Box({1.2, 2.2, 0.37}, {1.4, 0.7, 0.74}, {0.5f, 0.5f, 0.55f}, 11, 0.2));
  parts.push_back(Box({-0.9, 1.95, 0.97}, {0.55, 0.08, 0.42}, {0.2f, 0.2f, 0.25f}, 12));
  parts.push_back(Box({1.1, 2.3, 0.95}, {0.5, 0.3, 0.4}, {0.7f, 0.3f, 0.3f}, 13, 0.4));
  parts.push_back(Box({-2.4, 3.0, 0.9}, {1.0, 0.8, 1.8}, {0.45f, 0.55f, 0.4f}, 14));
  parts.push_back(Box({2.5, 3.1, 1.1}, {0.9, 0.6, 2.2}, {0.55f, 0.4f, 0.5f}, 15));
  parts.push_back(Box({-2.75, 0.5, 1.2}, {0.5, 2.0, 0.06}, {0.6f, 0.5f, 0.4f}, 16));
  parts.push_back(Box({-2.75, 0.5, 0.7}, {0.5, 2.0, 0.06}, {0.6f, 0.5f, 0.4f}, 17));
  parts.push_back(Box({-2.6, 0.4, 1.35}, {0.3, 0.3, 0.25}, {0.3f, 0.5f, 0.7f}, 18, 0.3));
  parts.push_back(Box({2.6, 0.2, 0.45}, {0.6, 1.2, 0.9}, {0.4f, 0.45f, 0.6f}, 19));
  parts.push_back(Box({0.1, 3.3, 1.6}, {1.6, 0.2, 1.0}, {0.8f, 0.75f, 0.5f}, 20));  // board
  parts.push_back(Box({0.3, 1.5, 0.15}, {0.5, 0.4, 0.3}, {0.5f, 0.6f, 0.35f}, 21, -0.5));
  return parts;
}

// Smooth back-and-forth between a and b: position fraction and its rate.
struct Shuttle {
  double fraction, rate;  // rate in fraction per second
};
Shuttle BackAndForth(double t, double period, double phase) {
  const double w = 2 * kPi / period;
  return {0.5 * (1 - std::cos(w * t + phase)), 0.5 * w * std::sin(w * t + phase)};
}

// A box sliding back and forth on the floor while spinning about its vertical axis.
SceneObject SlidingBox(uint16_t id, const std::string& name, const Vector3d& a, const Vector3d& b,
                       double period, double spin, const Vector3d& size, const Vector3f& colour,
                       double start_time = 0.0) {
  auto pose = [=](double t) {
    const double tau = std::max(0.0, t - start_time);
    const Shuttle s = BackAndForth(tau, period, 0.0);
    return Pose(a + s.fraction * (b - a) + Vector3d(0, 0, 0.5 * size.z()), Rz(spin * tau));
  };
  return RigidBox(id, name, pose, 0.5 * size, colour, 3000u + id);
}

// A box carried in front of the camera: nearly still in the image, the hardest case for RANSAC.
SceneObject CarriedBox(uint16_t id, CameraMotion motion, double duration) {
  auto pose = [=](double t) {
    const Isometry3d wobble =
        Pose(Vector3d(0.02 * std::sin(1.3 * t), 0.015 * std::sin(0.9 * t), 0.0),
             Ry(0.05 * std::sin(0.7 * t)));
    // Camera frame: right, down, forward. Lower left, 1.1 m ahead.
    return CameraPoseAt(motion, t, duration) * Pose(Vector3d(-0.35, 0.22, 1.1)) * wobble;
  };
  return RigidBox(id, "carried_box", pose, Vector3d(0.16, 0.12, 0.14), Vector3f(0.75f, 0.6f, 0.3f),
                  4000u + id);
}

// A box carried alongside the camera at distance `near` in front of a background `far` away,
// following the camera's displacement scaled by 1 − near/far: its image motion then matches
// the background's, so its outline leaves no optical-flow gradient, yet it moves in the world.
SceneObject AlongsideBox(uint16_t id, CameraMotion motion, double duration, const Vector3d& start,
                         double near, double far) {
  const double follow = 1.0 - near / far;
  auto pose = [=](double t) {
    const Vector3d shift = CameraPoseAt(motion, t, duration).translation() -
                           CameraPoseAt(motion, 0, duration).translation();
    return Pose(start + follow * shift, Rz(0.3));
  };
  return RigidBox(id, "alongside_box", pose, Vector3d(0.17, 0.14, 0.15),
                  Vector3f(0.35f, 0.55f, 0.75f), 4100u + id);
}

// The long loop: an ellipse around the middle of the room, 1–2 m from the walls and furniture
// all the way round, walked anticlockwise from the middle of its far side (facing the desks).
constexpr double kLongLoopCentreX = 0.0, kLongLoopCentreY = -0.6;
constexpr double kLongLoopRadiusX = 1.5, kLongLoopRadiusY = 1.2;
constexpr double kLongLoopRetrace = 0.8;  // metres walked again after the lap: about 2.8 s
constexpr double kLongLoopRamp = 1.5;     // seconds to start walking and to stop
constexpr int kLongLoopSamples = 4096;
// The long loop's depth is up to 4 % too far towards the image corners (exact at the centre), as
// an uncalibrated Kinect's is at 2–3 m. With exact depth and only the default sensor's noise, how
// far a lap drifts is left to chance (ATE 3.4 cm conventional, 5.6 sdo with the default seed;
// 3.1–8.1 cm over three seeds on a walk 0.2 m longer). The distortion is systematic, so every
// lap drifts: 3.7–14.5 cm over seeds 1–3 in both modes.
constexpr double kLongLoopDepthDistortion = 0.04;

Eigen::Vector2d LongLoopPoint(double u) {
  return {kLongLoopCentreX + kLongLoopRadiusX * std::cos(u),
          kLongLoopCentreY + kLongLoopRadiusY * std::sin(u)};
}

// Cumulative arc length at u = π/2 + 2π k / kLongLoopSamples (the ellipse has no closed-form
// arc length), so that the camera walks at the speed the timing asks for, not the angle's.
const std::array<double, kLongLoopSamples + 1>& LongLoopArcTable() {
  static const auto table = [] {
    std::array<double, kLongLoopSamples + 1> arc{};
    for (int k = 1; k <= kLongLoopSamples; ++k) {
      const double u0 = kPi / 2 + 2 * kPi * (k - 1) / kLongLoopSamples;
      const double u1 = kPi / 2 + 2 * kPi * k / kLongLoopSamples;
      arc[k] = arc[k - 1] + (LongLoopPoint(u1) - LongLoopPoint(u0)).norm();
    }
    return arc;
  }();
  return table;
}

std::vector<SceneObject> TwoWalkers() {
  return {Person(1, "person_1", {-1.3, -0.9, 0}, {1.1, -0.7, 0}, 7.0, 0.0, {0.7f, 0.2f, 0.2f},
                 {0.2f, 0.25f, 0.4f}),
          Person(2, "person_2", {1.0, 0.4, 0}, {-1.0, 0.0, 0}, 8.0, 2.0, {0.2f, 0.55f, 0.3f},
                 {0.3f, 0.3f, 0.3f})};
}

// People walking between the long loop and the walls, 1.2–1.6 m from the camera when it looks
// their way; the desks the walk starts and ends at stay clear.
std::vector<SceneObject> LongLoopWalkers() {
  return {Person(1, "person_1", {-1.3, -3.05, 0}, {1.3, -3.05, 0}, 11.0, 0.0, {0.7f, 0.2f, 0.2f},
                 {0.2f, 0.25f, 0.4f}),
          Person(2, "person_2", {2.6, -1.0, 0}, {1.9, -2.5, 0}, 8.0, 1.0, {0.2f, 0.55f, 0.3f},
                 {0.3f, 0.3f, 0.3f}),
          Person(3, "person_3", {-2.6, -1.1, 0}, {-1.9, -2.5, 0}, 9.0, 2.5, {0.3f, 0.35f, 0.7f},
                 {0.25f, 0.2f, 0.2f})};
}

std::vector<SceneObject> SwingingBoxes() {
  return {Pendulum(11, "pendulum_1", {-0.7, 0.3, 2.8}, 1.4, 0.0, 0.5, 2.6, 0.0, {0.6, 0.6, 0.6},
                   {0.3f, 0.6f, 0.8f}),
          Pendulum(12, "pendulum_2", {0.6, 0.9, 2.8}, 1.6, 1.2, 0.45, 3.1, 1.0, {0.65, 0.45, 0.55},
                   {0.8f, 0.5f, 0.2f}),
          Pendulum(13, "pendulum_3", {0.1, -0.4, 2.8}, 1.2, 0.6, 0.35, 2.2, 2.0, {0.45, 0.45, 0.45},
                   {0.6f, 0.3f, 0.7f}),
          SlidingBox(14, "sliding_box", {-1.2, 1.0, 0}, {0.8, 1.2, 0}, 6.0, 0.6, {0.6, 0.6, 0.6},
                     {0.5f, 0.7f, 0.4f})};
}

}  // namespace

Isometry3d Pose(const Vector3d& position, const Eigen::Matrix3d& rotation) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = rotation;
  T.translation() = position;
  return T;
}

// A walking person: legs and arms swing with the gait, the body turns at the ends of its path.
SceneObject Person(uint16_t id, const std::string& name, const Vector3d& a, const Vector3d& b,
                   double period, double phase, const Vector3f& shirt, const Vector3f& trousers,
                   double start_time) {
  const double length = (b - a).norm();
  const double heading = std::atan2(b.y() - a.y(), b.x() - a.x());
  auto state = [=](double t) {
    const double tau = std::max(0.0, t - start_time);
    const Shuttle s = BackAndForth(tau, period, phase);
    const double max_rate = kPi / period;
    // Turn around smoothly where the direction of travel reverses.
    const double turn = 0.5 * (1 - std::clamp(s.rate / (0.25 * max_rate), -1.0, 1.0));
    const double yaw = heading - kPi / 2 + kPi * turn;
    const Vector3d position = a + s.fraction * (b - a);
    const double speed = std::abs(s.rate) * length;
    // Gait phase grows with the distance walked (about 1.4 m per stride).
    const double gait = 2 * kPi * (s.fraction * length) / 1.4 * (s.rate >= 0 ? 1 : -1);
    return std::tuple{Pose(position, Rz(yaw)), std::min(1.0, speed / 0.6), gait};
  };
  SceneObject person;
  person.id = id;
  person.name = name;
  person.class_name = "person";
  person.pose_at = [=](double t) { return std::get<0>(state(t)); };
  person.parts_at = [=](double t) {
    const auto [body, swing_scale, gait] = state(t);
    const double swing = 0.45 * swing_scale * std::sin(gait);
    std::vector<Primitive> parts;
    auto part = [&](Primitive::Shape shape, const Isometry3d& local, const Vector3d& half,
                    const Vector3f& colour, uint32_t seed) {
      Primitive p;
      p.shape = shape;
      p.T_world_primitive = body * local;
      p.half_size = half;
      p.base_colour = colour;
      p.texture_seed = 1000u + id * 16u + seed;
      p.T_world_texture = body;
      parts.push_back(p);
    };
    // Body frame: origin between the feet on the floor, y forward, z up.
    const Vector3f skin(0.85f, 0.65f, 0.5f);
    for (int side : {-1, 1}) {
      const Vector3d hip(0.1 * side, 0, 0.9);
      const Eigen::Matrix3d leg = Rx(side * swing);
      part(Primitive::Shape::kBox, Pose(hip + leg * Vector3d(0, 0, -0.44), leg),
           {0.075, 0.09, 0.44}, trousers, side > 0 ? 1 : 2);
      const Vector3d shoulder(0.28 * side, 0, 1.45);
      const Eigen::Matrix3d arm = Rx(-side * swing * 0.8);
      part(Primitive::Shape::kBox, Pose(shoulder + arm * Vector3d(0, 0, -0.3), arm),
           {0.055, 0.06, 0.3}, shirt, side > 0 ? 3 : 4);
    }
    part(Primitive::Shape::kBox, Pose({0, 0, 1.2}), {0.21, 0.12, 0.31}, shirt, 5);
    part(Primitive::Shape::kEllipsoid, Pose({0, 0, 1.66}), {0.09, 0.1, 0.12}, skin, 6);
    return parts;
  };
  return person;
}

SceneObject SittingPerson(uint16_t id, const std::string& name, const Vector3d& feet,
                          const Vector3d& walk, double facing_yaw, const SittingSchedule& when,
                          const Vector3f& shirt, const Vector3f& trousers) {
  if (!(0 < when.arrive && when.arrive < when.seated && when.seated <= when.rise &&
        when.rise < when.stood && when.stood < when.gone)) {
    throw Error("SittingPerson '" + name + "': its schedule's times are out of order");
  }
  const double walking_yaw = std::atan2(walk.y(), walk.x()) - kPi / 2;
  // The turn from walking to facing, the short way round.
  const double turn = std::remainder(facing_yaw - walking_yaw, 2 * kPi);
  // 0 → 1 over [t0, t1], smooth at both ends (1 − cos).
  auto ease = [](double t, double t0, double t1) {
    const double s = std::clamp((t - t0) / (t1 - t0), 0.0, 1.0);
    return 0.5 * (1 - std::cos(kPi * s));
  };
  struct State {
    Isometry3d body;  // feet on the floor, y forward, z up
    double sit;       // 0 standing, 1 seated
    double swing;     // the legs' swing angle
  };
  auto state = [=](double t) {
    double along, sit, facing;
    if (t < when.seated) {
      along = ease(t, 0, when.arrive) - 1;  // −1 → 0: walking in
      sit = ease(t, when.arrive, when.seated);
      facing = sit;
    } else {
      along = ease(t, when.stood, when.gone);  // 0 → 1: walking off
      sit = 1 - ease(t, when.rise, when.stood);
      facing = sit;
    }
    // Legs swing while walking, about one stride per 1.4 m, as Person's do.
    const bool walking_in = t<when.arrive, walking_off = t> when.stood && t < when.gone;
    const double gait = 2 * kPi * (along * walk.norm()) / 1.4;
    const double swing = walking_in || walking_off ? 0.45 * std::sin(gait) : 0.0;
    return State{Pose(feet + along * walk, Rz(walking_yaw + facing * turn)), sit, swing};
  };
  SceneObject person;
  person.id = id;
  person.name = name;
  person.class_name = "person";
  person.pose_at = [=](double t) { return state(t).body; };
  person.parts_at = [=](double t) {
    const State s = state(t);
    std::vector<Primitive> parts;
    auto part = [&](Primitive::Shape shape, const Isometry3d& local, const Vector3d& half,
                    const Vector3f& colour, uint32_t seed) {
      Primitive p;
      p.shape = shape;
      p.T_world_primitive = s.body * local;
      p.half_size = half;
      p.base_colour = colour;
      p.texture_seed = 1000u + id * 16u + seed;
      p.T_world_texture = s.body;
      parts.push_back(p);
    };
    constexpr double kShin = 0.47, kThigh = 0.44;
    // Sitting turns the thighs forward about the knees, which stay over the feet: the hips go
    // down and back onto the seat.
    const double bend = s.sit * kPi / 2;
    const Vector3d hips(0, -kThigh * std::sin(bend), kShin + kThigh * std::cos(bend));
    const Vector3f skin(0.85f, 0.65f, 0.5f);
    for (int side : {-1, 1}) {
      const Vector3d hip = hips + Vector3d(0.1 * side, 0, 0);
      const Eigen::Matrix3d thigh = Rx(bend + side * s.swing), shin = Rx(side * s.swing);
      const Vector3d knee = hip + thigh * Vector3d(0, 0, -kThigh);
      part(Primitive::Shape::kBox, Pose(hip + thigh * Vector3d(0, 0, -kThigh / 2), thigh),
           {0.075, 0.09, kThigh / 2}, trousers, side > 0 ? 1 : 2);
      part(Primitive::Shape::kBox, Pose(knee + shin * Vector3d(0, 0, -kShin / 2), shin),
           {0.065, 0.08, kShin / 2}, trousers, side > 0 ? 7 : 8);
      const Vector3d shoulder = hips + Vector3d(0.28 * side, 0, 0.55);
      const Eigen::Matrix3d arm = Rx(-side * s.swing * 0.8);
      part(Primitive::Shape::kBox, Pose(shoulder + arm * Vector3d(0, 0, -0.3), arm),
           {0.055, 0.06, 0.3}, shirt, side > 0 ? 3 : 4);
    }
    part(Primitive::Shape::kBox, Pose(hips + Vector3d(0, 0, 0.3)), {0.21, 0.12, 0.31}, shirt, 5);
    part(Primitive::Shape::kEllipsoid, Pose(hips + Vector3d(0, 0, 0.76)), {0.09, 0.1, 0.12}, skin,
         6);
    return parts;
  };
  return person;
}

// A box hanging from `pivot` on a rigid rod, swinging about a horizontal axis (OMD-style).
SceneObject Pendulum(uint16_t id, const std::string& name, const Vector3d& pivot, double length,
                     double axis_yaw, double amplitude, double period, double phase,
                     const Vector3d& size, const Vector3f& colour, double start_time) {
  auto pose = [=](double t) {
    const double tau = std::max(0.0, t - start_time);
    const double angle = amplitude * std::sin(2 * kPi * tau / period + phase) -
                         (start_time > 0 ? amplitude * std::sin(phase) : 0.0);
    const Eigen::Matrix3d R = Rz(axis_yaw) * Rx(angle) * Rz(-axis_yaw);
    return Pose(pivot + R * Vector3d(0, 0, -length), R * Rz(axis_yaw));
  };
  SceneObject object;
  object.id = id;
  object.name = name;
  object.pose_at = pose;
  object.parts_at = [=](double t) {
    const Isometry3d body = pose(t);
    Primitive box;
    box.T_world_primitive = body;
    box.half_size = 0.5 * size;
    box.base_colour = colour;
    box.texture_seed = 2000u + id;
    box.T_world_texture = body;
    Primitive rod = box;
    rod.T_world_primitive = body * Pose({0, 0, 0.5 * length});
    rod.half_size = Vector3d(0.008, 0.008, 0.5 * length - 0.5 * size.z());
    rod.base_colour = Vector3f(0.25f, 0.25f, 0.25f);
    return std::vector<Primitive>{box, rod};
  };
  return object;
}

// A rigid textured box moving along `pose` (its centre and orientation at time t).
SceneObject RigidBox(uint16_t id, const std::string& name, std::function<Isometry3d(double)> pose,
                     const Vector3d& half_size, const Vector3f& colour, uint32_t texture_seed) {
  SceneObject object;
  object.id = id;
  object.name = name;
  object.pose_at = pose;
  object.parts_at = [=](double t) {
    Primitive box;
    box.T_world_primitive = pose(t);
    box.half_size = half_size;
    box.base_colour = colour;
    box.texture_seed = texture_seed;
    box.T_world_texture = box.T_world_primitive;
    return std::vector<Primitive>{box};
  };
  return object;
}

double LongLoopLength() { return LongLoopArcTable().back(); }

double LongLoopRetrace() { return kLongLoopRetrace; }

double LongLoopArcAt(double t, double duration) {
  // Eases in over `ramp` seconds (speed v/2 · (1 − cos)), walks at v, eases out the same way;
  // v is what covers the lap and the retrace in `duration`.
  const double total = LongLoopLength() + kLongLoopRetrace;
  const double ramp = std::min(kLongLoopRamp, 0.25 * duration);
  const double v = total / std::max(duration - ramp, 1e-6);
  auto easing = [&](double tau) {
    tau = std::clamp(tau, 0.0, ramp);
    return ramp > 0 ? v * (0.5 * tau - ramp / (2 * kPi) * std::sin(kPi * tau / ramp)) : 0.0;
  };
  if (t <= ramp) return easing(t);
  if (t >= duration - ramp) return total - easing(duration - t);
  return 0.5 * v * ramp + v * (t - ramp);
}

Isometry3d LongLoopPoseAtArc(double s) {
  const auto& arc = LongLoopArcTable();
  const double length = arc.back();
  s = std::fmod(s, length);
  if (s < 0) s += length;
  const auto it = std::upper_bound(arc.begin(), arc.end(), s);
  const int k = std::clamp(static_cast<int>(it - arc.begin()) - 1, 0, kLongLoopSamples - 1);
  const double fraction = (s - arc[k]) / std::max(arc[k + 1] - arc[k], 1e-12);
  const double u = kPi / 2 + 2 * kPi * (k + fraction) / kLongLoopSamples;
  const Eigen::Vector2d p = LongLoopPoint(u);
  // Looking out of the loop, along the ellipse's normal, at the walls and furniture.
  const double normal_yaw =
      std::atan2(kLongLoopRadiusX * std::sin(u), kLongLoopRadiusY * std::cos(u));
  // A hand-held walk: the view sways left and right, up and down, and the camera bobs with the
  // steps (about 0.75 m each). Every term repeats a whole number of times per lap, so the lap
  // closes exactly and the retraced stretch has the very poses of the first.
  const double phase = 2 * kPi * s / length;
  const double steps = std::round(length / 0.75);
  // The sway turns against the ellipse at the start, so the retraced stretch ends looking
  // nearly where the walk began.
  const double yaw = normal_yaw - 0.15 * std::sin(3 * phase);
  const double pitch = 0.14 + 0.04 * std::sin(2 * phase + 1.0);  // down
  const double roll = 0.03 * std::sin(5 * phase + 2.0);
  const double height = 1.35 + 0.015 * std::sin(steps * phase);
  const Vector3d eye(p.x(), p.y(), height);
  const Vector3d forward(std::cos(yaw) * std::cos(pitch), std::sin(yaw) * std::cos(pitch),
                         -std::sin(pitch));
  return Pose(eye, LookAt(eye, eye + forward).linear() * Rz(roll));
}

CameraMotion ParseCameraMotion(const std::string& name) {
  for (CameraMotion m :
       {CameraMotion::kStatic, CameraMotion::kXyz, CameraMotion::kRpy, CameraMotion::kHalfsphere,
        CameraMotion::kUnconstrained, CameraMotion::kLoop, CameraMotion::kLongLoop}) {
    if (ToString(m) == name) return m;
  }
  std::string names;
  for (const auto& n : CameraMotionNames()) names += (names.empty() ? "" : ", ") + n;
  throw Error("unknown camera motion '" + name + "' (known: " + names + ")");
}

std::string ToString(CameraMotion motion) {
  switch (motion) {
    case CameraMotion::kStatic:
      return "static";
    case CameraMotion::kXyz:
      return "xyz";
    case CameraMotion::kRpy:
      return "rpy";
    case CameraMotion::kHalfsphere:
      return "halfsphere";
    case CameraMotion::kUnconstrained:
      return "unconstrained";
    case CameraMotion::kLoop:
      return "loop";
    case CameraMotion::kLongLoop:
      return "long_loop";
  }
  return "?";
}

std::vector<std::string> CameraMotionNames() {
  return {"static", "xyz", "rpy", "halfsphere", "unconstrained", "loop", "long_loop"};
}

Isometry3d CameraPoseAt(CameraMotion motion, double t, double duration) {
  const Isometry3d base = LookAt(kEye, kTarget);
  switch (motion) {
    case CameraMotion::kStatic: {
      // A camera on a tripod that is touched now and then: millimetres and a tenth of a degree.
      const Vector3d d(0.003 * std::sin(1.1 * t), 0.002 * std::sin(0.7 * t + 1),
                       0.003 * std::sin(0.9 * t + 2));
      return Pose(kEye + d) * Pose(Vector3d::Zero(), base.linear() * Rx(0.002 * std::sin(0.8 * t)));
    }
    case CameraMotion::kXyz: {
      const Vector3d d(0.35 * std::sin(2 * kPi * t / 6.0), 0.25 * std::sin(2 * kPi * t / 4.3),
                       0.2 * std::sin(2 * kPi * t / 5.1));
      return Pose(kEye + d, base.linear());
    }
    case CameraMotion::kRpy: {
      const double roll = 0.26 * std::sin(2 * kPi * t / 5.0),
                   pitch = 0.2 * std::sin(2 * kPi * t / 3.7),
                   yaw = 0.35 * std::sin(2 * kPi * t / 6.3);
      // Rotations about the camera's own axes (z forward: roll, x: pitch, y: yaw).
      const Eigen::Matrix3d R = base.linear() * Ry(yaw) * Rx(pitch) * Rz(roll);
      return Pose(kEye + Vector3d(0.01 * std::sin(t), 0.01 * std::sin(0.5 * t), 0.0), R);
    }
    case CameraMotion::kHalfsphere: {
      // On a sphere of radius 0.6 m around a point 1.2 m ahead, always looking at a point beyond.
      const Vector3d centre = kEye + 1.2 * (kTarget - kEye).normalized();
      const double azimuth = 0.75 * std::sin(2 * kPi * t / 7.0);
      const double elevation = 0.4 * std::sin(2 * kPi * t / 4.6);
      const Vector3d offset(std::sin(azimuth) * std::cos(elevation),
                            -std::cos(azimuth) * std::cos(elevation), std::sin(elevation));
      return LookAt(centre + 0.6 * offset, centre + 1.3 * (kTarget - kEye).normalized());
    }
    case CameraMotion::kUnconstrained: {
      const Vector3d d(0.25 * std::sin(2 * kPi * t / 5.5), 0.2 * std::sin(2 * kPi * t / 4.1),
                       0.15 * std::sin(2 * kPi * t / 3.3));
      const Eigen::Matrix3d R = base.linear() * Ry(0.25 * std::sin(2 * kPi * t / 6.1)) *
                                Rx(0.15 * std::sin(2 * kPi * t / 4.4)) *
                                Rz(0.15 * std::sin(2 * kPi * t / 5.2));
      return Pose(kEye + d, R);
    }
    case CameraMotion::kLoop: {
      // A closed walk: a circle of radius 0.7 m, looking ahead with a gentle sway; the last
      // frame (t = duration) is back at the start.
      const double s = 2 * kPi * t / std::max(duration, 1e-6);
      const Vector3d d(0.7 * std::sin(s), 0.7 * (1 - std::cos(s)), 0.05 * std::sin(2 * s));
      return Pose(kEye + d, base.linear() * Ry(0.3 * std::sin(s)));
    }
    case CameraMotion::kLongLoop:
      return LongLoopPoseAtArc(LongLoopArcAt(t, duration));
  }
  return base;
}

std::vector<std::string> ScenarioNames() {
  return {"static_room",
          "walking_static",
          "walking_xyz",
          "walking_rpy",
          "walking_halfsphere",
          "boxes_translational",
          "boxes_unconstrained",
          "mixed",
          "loop",
          "box_alongside",
          "parked_cart",
          "long_loop",
          "long_loop_people"};
}

Scenario MakeScenario(const std::string& name, double duration,
                      std::optional<CameraMotion> motion) {
  Scenario s;
  s.name = name;
  s.scene.static_parts = Room();
  s.scene.light_direction = Vector3d(0.3, -0.4, 1.0).normalized();
  if (name == "static_room") {
    s.description = "the room alone; nothing moves but the camera";
    s.motion = CameraMotion::kXyz;
  } else if (name.rfind("walking_", 0) == 0 &&
             (name == "walking_static" || name == "walking_xyz" || name == "walking_rpy" ||
              name == "walking_halfsphere")) {
    s.description = "two people walking across the room (TUM fr3 walking_*)";
    s.motion = ParseCameraMotion(name.substr(8));
    s.scene.objects = TwoWalkers();
  } else if (name == "boxes_translational" || name == "boxes_unconstrained") {
    s.description = "swinging and sliding boxes of no known class (OMD)";
    s.motion = name == "boxes_translational" ? CameraMotion::kXyz : CameraMotion::kUnconstrained;
    s.scene.objects = SwingingBoxes();
  } else if (name == "mixed") {
    s.description = "a person, swinging boxes and a box carried with the camera";
    s.motion = CameraMotion::kXyz;
  } else if (name == "loop") {
    s.description = "a closed camera loop past a walking person";
    s.motion = CameraMotion::kLoop;
    s.scene.objects = {TwoWalkers()[0]};
  } else if (name == "box_alongside") {
    s.description =
        "a box carried alongside the camera, its image motion matching the background's: no "
        "flow boundary, only scene flow shows it";
    s.motion = CameraMotion::kXyz;
  } else if (name == "parked_cart") {
    s.description = "a cart parked for two seconds, then pushed away across the floor";
    s.motion = CameraMotion::kXyz;
    s.scene.objects = {SlidingBox(31, "cart", {-0.5, 0.6, 0}, {1.1, 0.6, 0}, 6.0, 0.0,
                                  {0.7, 0.5, 0.6}, {0.75f, 0.45f, 0.3f}, 2.0)};
  } else if (name == "long_loop") {
    s.description = "a long closed walk round the room, looking out; ends back at its start";
    s.motion = CameraMotion::kLongLoop;
    s.depth_distortion = kLongLoopDepthDistortion;
  } else if (name == "long_loop_people") {
    s.description = "the long closed walk with people walking through the room";
    s.motion = CameraMotion::kLongLoop;
    s.depth_distortion = kLongLoopDepthDistortion;
    s.scene.objects = LongLoopWalkers();
  } else {
    std::string names;
    for (const auto& n : ScenarioNames()) names += (names.empty() ? "" : ", ") + n;
    throw Error("unknown scenario '" + name + "' (known: " + names + ")");
  }
  if (motion) s.motion = *motion;
  if (name == "box_alongside") {
    // 1.7 m ahead of the camera, above the desks, with the board and far wall about 5.7 m away.
    s.scene.objects = {AlongsideBox(41, s.motion, duration, {-0.25, -0.6, 1.45}, 1.7, 5.7)};
  }
  if (name == "mixed") {
    auto boxes = SwingingBoxes();
    s.scene.objects = {TwoWalkers()[0], boxes[0], boxes[1], CarriedBox(21, s.motion, duration)};
  }
  return s;
}

CameraOptions SyntheticCamera() {
  CameraOptions o;
  o.name = "sdoslam synthetic (TUM freiburg3 intrinsics)";
  o.width = 640;
  o.height = 480;
  o.fx = 535.4;
  o.fy = 539.2;
  o.cx = 320.1;
  o.cy = 247.6;
  o.fps = 30.0;
  o.depth_factor = 5000.0;
  o.depth_min = 0.1;
  o.depth_max = 8.0;
  return o;
}

}  // namespace sdoslam::synth
