#include "sdoslam/synth/real_background.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/io/tum_dataset.h"
#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"

namespace sdoslam::synth {
namespace {

using Eigen::Isometry3d;
using Eigen::Vector3d;
using Eigen::Vector3f;

// The object moved into the world by T_world_anchor (parts, texture frames and pose).
SceneObject InWorld(SceneObject object, const Isometry3d& T_world_anchor) {
  auto parts_at = object.parts_at;
  auto pose_at = object.pose_at;
  object.parts_at = [=](double t) {
    std::vector<Primitive> parts = parts_at(t);
    for (Primitive& p : parts) {
      p.T_world_primitive = T_world_anchor * p.T_world_primitive;
      p.T_world_texture = T_world_anchor * p.T_world_texture;
    }
    return parts;
  };
  object.pose_at = [=](double t) { return T_world_anchor * pose_at(t); };
  return object;
}

// A frame levelled on the first camera: origin at its centre, z up (against the image's y
// axis), y forward (its optical axis made horizontal), x right. People stand upright in it
// whatever the motion-capture frame's convention.
Isometry3d LevelledAnchor(const Isometry3d& T_world_camera) {
  const Vector3d up = -T_world_camera.linear().col(1);
  Vector3d forward = T_world_camera.linear().col(2);
  forward = (forward - forward.dot(up) * up).normalized();
  Eigen::Matrix3d R;
  R << forward.cross(up), forward, up;
  return Pose(T_world_camera.translation(), R);
}

// Median valid depth in the central third of the image: how far the recorded scene is.
double SceneDepth(const cv::Mat& depth, const std::filesystem::path& file) {
  const cv::Mat centre =
      depth(cv::Rect(depth.cols / 3, depth.rows / 3, depth.cols / 3, depth.rows / 3));
  std::vector<float> values;
  for (int v = 0; v < centre.rows; ++v) {
    for (int u = 0; u < centre.cols; ++u) {
      const float z = centre.at<float>(v, u);
      if (z > 0) values.push_back(z);
    }
  }
  if (values.size() < centre.total() / 10) {
    throw Error(file.string() +
                ": too little valid depth in the centre of the first frame to "
                "place objects in front of the scene");
  }
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

struct Placement {
  Isometry3d T_world_anchor;
  Vector3d focus;   // in the anchor frame: the scene point at the first image's centre
  double duration;  // seconds of the played sequence
  std::function<Isometry3d(double)> camera_at;  // T_world_camera at scene time t
};

SceneObject CarriedBox(const Placement& p) {
  auto camera_at = p.camera_at;
  auto pose = [camera_at](double t) {
    // Held in two hands, lower left of centre, 0.6 m ahead: it sways a little against the camera.
    const Isometry3d sway =
        Pose(Vector3d(0.025 * std::sin(1.7 * t), 0.02 * std::sin(1.1 * t + 1),
                      0.015 * std::sin(0.8 * t)),
             Eigen::AngleAxisd(0.06 * std::sin(0.9 * t), Vector3d::UnitY()).toRotationMatrix() *
                 Eigen::AngleAxisd(0.04 * std::sin(1.3 * t), Vector3d::UnitX()).toRotationMatrix());
    return camera_at(t) * Pose(Vector3d(-0.07, 0.05, 0.6)) * sway;
  };
  SceneObject box = RigidBox(21, "carried_box", pose, Vector3d(0.17, 0.13, 0.06),
                             Vector3f(0.8f, 0.6f, 0.35f), 4021u);
  // Finer texture than the procedural default: a printed carton with more corners than the
  // desk behind it, so that most ORB features of a frame can land on it.
  auto parts_at = box.parts_at;
  box.parts_at = [parts_at](double t) {
    auto parts = parts_at(t);
    for (Primitive& part : parts) part.texture_scale = 0.3;
    return parts;
  };
  return box;
}

// A point on the first view's optical axis at `fraction` of the scene's depth, shifted by
// `offset` (anchor frame: x right, y forward, z up).
Vector3d OnAxis(const Placement& p, double fraction, const Vector3d& offset) {
  return fraction * p.focus + offset;
}

std::vector<SceneObject> SwingingBoxes(const Placement& p) {
  // Swinging mostly across the view (axis_yaw near 90°), low enough to cross the image centre.
  const Vector3d box1 = OnAxis(p, 0.55, {-0.2, 0, 0});
  const Vector3d box2 = OnAxis(p, 0.7, {0.25, 0, 0.05});
  return {InWorld(Pendulum(11, "swinging_box_1", box1 + Vector3d(0, 0, 0.8), 0.8, 1.35, 0.45, 2.4,
                           0.0, {0.26, 0.26, 0.26}, {0.3f, 0.6f, 0.85f}),
                  p.T_world_anchor),
          InWorld(Pendulum(12, "swinging_box_2", box2 + Vector3d(0, 0, 1.0), 1.0, 1.75, 0.4, 2.9,
                           1.5, {0.32, 0.24, 0.28}, {0.85f, 0.45f, 0.2f}),
                  p.T_world_anchor)};
}

// People walking across the view once per `period`: they enter from one side, cross and leave.
std::vector<SceneObject> People(const Placement& p, int count) {
  const double period = std::clamp(2.0 * p.duration, 4.0, 9.0);
  const double forward = std::max(0.9, 0.75 * p.focus.y());
  // Feet 1.5 m below the camera: a camera held at about eye height.
  std::vector<SceneObject> people = {
      InWorld(Person(1, "person_1", {-1.0, forward, -1.5}, {0.9, forward, -1.5}, period, 0.0,
                     {0.75f, 0.2f, 0.2f}, {0.2f, 0.25f, 0.45f}),
              p.T_world_anchor)};
  if (count > 1) {
    const double far = std::max(forward + 0.5, 1.1 * p.focus.y());
    people.push_back(InWorld(Person(2, "person_2", {1.4, far, -1.5}, {-1.2, far, -1.5},
                                    period * 1.15, 0.6, {0.2f, 0.6f, 0.3f}, {0.3f, 0.3f, 0.3f}),
                             p.T_world_anchor));
  }
  return people;
}

// A person walks up to the camera from behind the scene, comes within 30 cm of the lens,
// filling the view for about half a second (0.6 of the way through the play), turns and walks
// away: a view with nothing static in it, then the scene back.
SceneObject PersonFillingTheView(const Placement& p) {
  constexpr double kPeriod = 5.0;  // there and back; the near end is reached at half of it
  const double near_time = 0.6 * p.duration;
  // Where the camera looks then, in the anchor frame (x right, y forward, z up): the person
  // stops on its optical axis, 30 cm out, and comes from 2 m further along it.
  const Isometry3d T_anchor_camera = p.T_world_anchor.inverse() * p.camera_at(near_time);
  const Vector3d centre = T_anchor_camera.translation();
  Vector3d forward = T_anchor_camera.linear().col(2);
  forward.z() = 0;
  forward.normalize();
  // Feet 1.35 m below the camera: a camera held at chest height, so that the torso covers the
  // view from up close.
  const Vector3d near_feet = centre + 0.3 * forward - Vector3d(0, 0, 1.35);
  const Vector3d far_feet = near_feet + std::max(2.0, 1.3 * p.focus.y()) * forward;
  return InWorld(Person(3, "person_close", far_feet, near_feet, kPeriod, 0.0, {0.3f, 0.35f, 0.7f},
                        {0.25f, 0.25f, 0.3f}, near_time - 0.5 * kPeriod),
                 p.T_world_anchor);
}

// `object` holding still from scene time `from` for `seconds`, then going on where it stopped.
SceneObject Paused(SceneObject object, double from, double seconds) {
  auto clock = [from, seconds](double t) {
    return t < from ? t : (t < from + seconds ? from : t - seconds);
  };
  auto parts_at = object.parts_at;
  auto pose_at = object.pose_at;
  object.parts_at = [=](double t) { return parts_at(clock(t)); };
  object.pose_at = [=](double t) { return pose_at(clock(t)); };
  return object;
}

// A person walks straight at the camera from 2.2 m to 0.75 m, stands there facing it for 1 s
// (about half the image covered, the head cut off by the top edge), then walks on, turns and
// goes back: a known class that stops moving at close range, where a full-body detector no
// longer sees it.
SceneObject PersonStoppingClose(const Placement& p) {
  constexpr double kFar = 2.2, kStop = 0.75, kNearest = 0.65;  // metres ahead of the camera
  const double stop_time = 0.37 * p.duration, stand = std::min(1.0, 0.3 * p.duration);
  // Where the camera looks while the person stands (anchor frame: x right, y forward, z up).
  const Isometry3d T_anchor_camera = p.T_world_anchor.inverse() * p.camera_at(stop_time);
  const Vector3d centre = T_anchor_camera.translation();
  Vector3d forward = T_anchor_camera.linear().col(2);
  forward.z() = 0;
  forward.normalize();
  // Feet 1.2 m below the camera (a robot's or a low hand-held camera): from 0.75 m the head is
  // above the view.
  const Vector3d feet = centre - Vector3d(0, 0, 1.2);
  // Person() walks a shuttle (1 − cos): it reaches kStop at a share `f` of its way from kFar to
  // kNearest, after acos(1 − 2f) / 2π of its period; the period puts that at stop_time.
  const double f = (kFar - kStop) / (kFar - kNearest);
  const double period = stop_time * 2 * M_PI / std::acos(1 - 2 * f);
  return Paused(
      InWorld(Person(4, "person_stopping", feet + kFar * forward, feet + kNearest * forward, period,
                     0.0, {0.55f, 0.3f, 0.25f}, {0.2f, 0.2f, 0.35f}),
              p.T_world_anchor),
      stop_time, stand);
}

// A box standing still 0.6 of the way to the scene, right of centre, whose depth the sensor
// reads 4 % too far (a material's bias): static, never dynamic.
SceneObject BiasedStillBox(const Placement& p) {
  const Isometry3d pose = p.T_world_anchor * Pose(OnAxis(p, 0.6, {0.15, 0, -0.05}));
  SceneObject box = RigidBox(
      31, "biased_box", [pose](double) { return pose; }, Vector3d(0.14, 0.1, 0.09),
      Vector3f(0.3f, 0.7f, 0.4f), 4031u);
  box.depth_bias = 0.04;
  return box;
}

// A crate about the size of a chair's seat standing still on the desk, 0.55 of the way to the
// scene and left of centre, for the first 0.35 of the play (long enough to be mapped), then
// pushed 0.3 m to the right over 0.8 s, turning 15 degrees, and left there: a thing of no known
// class that was static, moves, and is static again.
SceneObject PushedBox(const Placement& p) {
  const double start = 0.35 * p.duration, push = 0.8;
  const Isometry3d T_world_anchor = p.T_world_anchor;
  const Vector3d at = OnAxis(p, 0.55, {-0.2, 0, -0.1});
  auto pose = [=](double t) {
    // Smooth start and stop: (1 - cos) over the push.
    const double s = std::clamp((t - start) / push, 0.0, 1.0);
    const double done = 0.5 * (1 - std::cos(M_PI * s));
    return T_world_anchor *
           Pose(at + done * Vector3d(0.3, 0, 0),
                Eigen::AngleAxisd(done * 15 * M_PI / 180, Vector3d::UnitZ()).toRotationMatrix());
  };
  return RigidBox(32, "pushed_box", pose, Vector3d(0.18, 0.15, 0.12), Vector3f(0.6f, 0.45f, 0.7f),
                  4032u);
}

// A person walks in from the left behind the desk (the recorded scene), sits down on a stool
// facing the camera, sits still for a quarter of the play, stands up and walks off to the right:
// a known class that stops moving and changes shape (knees bent, 0.45 m lower) while it is
// still, half hidden by the desk. The stool (no class) stands still throughout.
std::vector<SceneObject> PersonSittingDown(const Placement& p) {
  const double d = p.duration;
  // The first view's centre is on the desk, 0.3 m short of the stool and 0.3 m to the left of it
  // (clear of the monitor); the floor is 0.45 m below that point, set by the rendered frames: the
  // seated person's head and shoulders then show above the desk, as across a real one.
  const Vector3d feet = p.focus + Vector3d(0.3, 0.3, -0.45);
  const double facing = M_PI;  // the body's forward (y) towards the camera
  SceneObject person = InWorld(SittingPerson(5, "person_sitting", feet, Vector3d(0.9, 0, 0), facing,
                                             {0.22 * d, 0.4 * d, 0.65 * d, 0.8 * d, 0.97 * d},
                                             {0.35f, 0.55f, 0.6f}, {0.3f, 0.25f, 0.2f}),
                               p.T_world_anchor);
  // Behind the feet, its top (0.4 m) just under the seated thighs.
  const Isometry3d stool =
      p.T_world_anchor *
      Pose(feet, Eigen::AngleAxisd(facing, Vector3d::UnitZ()).toRotationMatrix()) *
      Pose(Vector3d(0, -0.42, 0.2));
  return {person, RigidBox(
                      33, "stool", [stool](double) { return stool; }, Vector3d(0.2, 0.19, 0.2),
                      Vector3f(0.45f, 0.35f, 0.25f), 4033u)};
}

void CheckScenarioName(const std::string& name) {
  const auto names = BackgroundScenarioNames();
  if (std::find(names.begin(), names.end(), name) != names.end()) return;
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
  throw Error("unknown real-background scenario '" + name + "' (known: " + list + ")");
}

Scene MakeBackgroundScene(const std::string& name, const Placement& p) {
  Scene scene;
  scene.light_direction = p.T_world_anchor.linear() * Vector3d(0.3, -0.4, 1.0).normalized();
  if (name == "static") {
    // Nothing added: the recording as it is, for the static baseline of the same play.
  } else if (name == "carried_box") {
    scene.objects = {CarriedBox(p)};
  } else if (name == "swinging_boxes") {
    scene.objects = SwingingBoxes(p);
  } else if (name == "people") {
    scene.objects = People(p, 2);
  } else if (name == "mixed") {
    scene.objects = {People(p, 1)[0], SwingingBoxes(p)[0], CarriedBox(p)};
  } else if (name == "person_fills_view") {
    scene.objects = {PersonFillingTheView(p)};
  } else if (name == "person_stops_close") {
    scene.objects = {PersonStoppingClose(p)};
  } else if (name == "biased_box") {
    scene.objects = {BiasedStillBox(p)};
  } else if (name == "pushed_box") {
    scene.objects = {PushedBox(p)};
  } else if (name == "person_sits") {
    scene.objects = PersonSittingDown(p);
  } else {
    CheckScenarioName(name);  // throws, listing the known names
  }
  return scene;
}

}  // namespace

std::vector<std::string> BackgroundScenarioNames() {
  return {"static",     "carried_box",       "swinging_boxes",     "people",
          "mixed",      "person_fills_view", "person_stops_close", "biased_box",
          "pushed_box", "person_sits"};
}

void BackgroundSynthOptions::Check() const {
  CheckScenarioName(scenario);
  if (max_frames < 0) throw Error("max_frames must be >= 0");
  if (!(max_ground_truth_gap > 0)) throw Error("max_ground_truth_gap must be > 0");
  if (sensor.motion_blur_samples > 1) {
    throw Error("motion blur is not available over a real background (its frames are as recorded)");
  }
  if (sensor.supersampling > 1) {
    // The composited objects' edges would average with the renderer's empty black background.
    throw Error("supersampling is not available over a real background");
  }
  sensor.Check();
  camera.Check();
}

namespace {

// The recording's frames as they are played (forward, then back without repeating the turning
// frame, when asked), on a time that runs on, with their ground-truth poses.
struct Playback {
  size_t used = 0;            // recorded frames used
  std::vector<size_t> order;  // recorded frame of each played frame
  std::vector<double> times;  // seconds from the first played frame
  Trajectory played;          // the camera at each played frame
};
Playback PlayRecording(const TumDataset& recording, const Trajectory& ground_truth,
                       const BackgroundSynthOptions& options,
                       const std::filesystem::path& gt_file) {
  Playback playback;
  std::vector<size_t>& order = playback.order;
  std::vector<double>& times = playback.times;
  Trajectory& played = playback.played;
  const size_t available = recording.size();
  const size_t used = playback.used =
      options.max_frames > 0 ? std::min(available, static_cast<size_t>(options.max_frames))
                             : available;
  for (size_t k = 0; k < used; ++k) order.push_back(k);
  if (options.forward_backward) {
    for (size_t k = used - 1; k-- > 0;) order.push_back(k);
  }
  // Played time runs on: each step takes as long as it took in the recording.
  times.assign(order.size(), 0.0);
  for (size_t i = 0; i < order.size(); ++i) {
    const RgbdFrameEntry& entry = recording.entries()[order[i]];
    if (i > 0) {
      const double step = std::abs(entry.timestamp - recording.entries()[order[i - 1]].timestamp);
      times[i] = times[i - 1] + std::max(step, 1e-3);
    }
    const auto pose = InterpolatePose(ground_truth, entry.timestamp, options.max_ground_truth_gap);
    if (!pose) {
      throw Error(gt_file.string() + " has no pose within " +
                  std::to_string(options.max_ground_truth_gap) + " s of frame " +
                  entry.rgb_path.filename().string());
    }
    played.push_back({times[i], *pose});
  }
  return playback;
}

// The rendered objects over a recorded frame: `composite` is the scene as the sensor would see it
// (z-buffered against the recorded depth; where the sensor saw nothing, the object is in front),
// and the frame returned keeps the recorded pixels as recorded, except on the objects and the
// sensor's shadow next to their outlines.
SensorFrame Composite(const RgbdFrame& background, const RenderedView& objects, const Scene& scene,
                      const BackgroundSynthOptions& options, int index, RenderedView* out) {
  RenderedView& composite = *out;
  const cv::Mat object_mask =
      (objects.depth > 0) & ((background.depth <= 0) | (objects.depth < background.depth));
  background.bgr.convertTo(composite.colour, CV_32FC3, 1.0 / 255.0);
  objects.colour.copyTo(composite.colour, object_mask);
  composite.depth = background.depth.clone();
  objects.depth.copyTo(composite.depth, object_mask);
  composite.instance = cv::Mat::zeros(objects.instance.size(), CV_16UC1);
  objects.instance.copyTo(composite.instance, object_mask);
  SensorFrame sensed = Sense(composite, options.camera, options.sensor, options.seed, index);
  for (const SceneObject& object : scene.objects) {
    if (object.depth_bias == 0.0) continue;
    cv::Mat misread;
    sensed.depth.convertTo(misread, CV_16UC1, 1.0 + object.depth_bias);
    misread.copyTo(sensed.depth, object_mask & (composite.instance == object.id));
  }

  SensorFrame frame;
  frame.bgr = background.bgr.clone();
  sensed.bgr.copyTo(frame.bgr, object_mask);
  background.depth.convertTo(frame.depth, CV_16UC1, options.camera.depth_factor);
  cv::Mat near_objects;
  cv::dilate(object_mask, near_objects, cv::getStructuringElement(cv::MORPH_CROSS, {3, 3}));
  frame.depth.setTo(0, near_objects & (sensed.depth == 0));
  sensed.depth.copyTo(frame.depth, object_mask);
  return frame;
}

}  // namespace

SequenceSummary WriteBackgroundSequence(const BackgroundSynthOptions& options,
                                        const std::filesystem::path& out, bool overwrite) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  const TumDataset recording(options.background, options.camera);
  const std::filesystem::path gt_file = options.background / "groundtruth.txt";
  if (!std::filesystem::exists(gt_file)) {
    throw Error(gt_file.string() +
                " does not exist: a real background needs the recording's ground-truth "
                "trajectory (TUM format)");
  }
  const Trajectory ground_truth = ReadTumTrajectory(gt_file);

  const Playback playback = PlayRecording(recording, ground_truth, options, gt_file);
  const size_t used = playback.used;
  const std::vector<size_t>& order = playback.order;
  const std::vector<double>& times = playback.times;
  const Trajectory& played = playback.played;
  const double first_stamp = recording.entries()[0].timestamp;
  const double duration = times.back();
  const double dt = order.size() > 1 ? duration / (order.size() - 1) : 1.0 / options.camera.fps;

  const RgbdFrame first = recording.Load(0);
  Placement placement;
  placement.T_world_anchor = LevelledAnchor(played[0].T_world_camera);
  placement.focus = placement.T_world_anchor.inverse() *
                    (played[0].T_world_camera *
                     Vector3d(0, 0, SceneDepth(first.depth, recording.entries()[0].depth_path)));
  placement.duration = duration;
  placement.camera_at = [played, duration](double t) {
    return *InterpolatePose(played, std::clamp(t, 0.0, duration), 1e9);
  };
  const Scene scene = MakeBackgroundScene(options.scenario, placement);
  const Camera camera(options.camera);

  SequenceWriter writer(out, overwrite, options.scenario + " over " + options.background.string(),
                        {options.background});
  double render_seconds = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    const auto render_start = std::chrono::steady_clock::now();
    const RgbdFrame background = recording.Load(order[i]);
    const double t = times[i];
    const Isometry3d& T_world_camera = played[i].T_world_camera;
    const RenderedView objects = Render(scene, t, T_world_camera, camera);

    RenderedView composite;
    const SensorFrame frame =
        Composite(background, objects, scene, options, static_cast<int>(i), &composite);
    render_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - render_start).count();
    writer.AddFrame(first_stamp + t, t, dt, frame, composite.instance, T_world_camera, scene);
  }

  YAML::Emitter info;
  info << YAML::BeginMap << YAML::Key << "scenario" << YAML::Value << options.scenario << YAML::Key
       << "background" << YAML::Value << options.background.string() << YAML::Key
       << "background_frames" << YAML::Value << used << YAML::Key << "forward_backward"
       << YAML::Value << options.forward_backward << YAML::Key << "frames" << YAML::Value
       << order.size() << YAML::Key << "seed" << YAML::Value << options.seed << YAML::Key
       << "sensor_noise" << YAML::Value << options.sensor.enabled << YAML::EndMap;
  SequenceSummary summary = writer.Finish(options.camera, scene, info);
  summary.render_seconds = render_seconds;
  summary.total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace sdoslam::synth
