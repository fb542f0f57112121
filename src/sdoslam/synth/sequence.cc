#include "sdoslam/synth/sequence.h"

#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/synth/renderer.h"

namespace sdoslam::synth {
namespace {

std::string Stamp(double t) {
  char b[64];
  std::snprintf(b, sizeof(b), "%.6f", t);
  return b;
}

void WriteImage(const std::filesystem::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image)) throw Error("cannot write " + path.string());
}

// " tx ty tz qx qy qz qw" of a pose.
std::string PoseFields(const Eigen::Isometry3d& T) {
  const Eigen::Quaterniond q(T.rotation());
  const Eigen::Vector3d p = T.translation();
  char b[256];
  std::snprintf(b, sizeof(b), " %.9f %.9f %.9f %.9f %.9f %.9f %.9f", p.x(), p.y(), p.z(), q.x(),
                q.y(), q.z(), q.w());
  return b;
}

}  // namespace

void SynthOptions::Check() const {
  if (frames < 1 || frames > 100000) throw Error("frames must be in 1..100000");
  if (!std::isfinite(first_timestamp) || first_timestamp < 0)
    throw Error("first timestamp must be >= 0");
  sensor.Check();
  MakeScenario(scenario, 1.0, motion);  // throws for an unknown name
}

SequenceSummary WriteSequence(const SynthOptions& options, const std::filesystem::path& out,
                              bool overwrite) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  if (std::filesystem::exists(out) && !std::filesystem::is_empty(out) && !overwrite) {
    throw Error(out.string() + " exists and is not empty (use --overwrite to replace it)");
  }
  const CameraOptions camera_options = SyntheticCamera();
  const Camera camera(camera_options);
  const double dt = 1.0 / camera_options.fps;
  const double duration = (options.frames - 1) * dt;
  const Scenario scenario = MakeScenario(options.scenario, duration, options.motion);

  std::filesystem::path staging = out;
  staging += ".partial-" + std::to_string(::getpid());
  std::filesystem::remove_all(staging);
  for (const char* sub : {"rgb", "depth", "instance", "dynamic"}) {
    std::filesystem::create_directories(staging / sub);
  }

  SequenceSummary summary;
  summary.frames = options.frames;
  std::string rgb_list =
      "# color images\n# sdoslam synth " + scenario.name + "\n# timestamp filename\n";
  std::string depth_list =
      "# depth maps\n# sdoslam synth " + scenario.name + "\n# timestamp filename\n";
  Trajectory ground_truth;
  std::string object_poses = "# timestamp object_id tx ty tz qx qy qz qw (world frame)\n";
  nlohmann::json detections = nlohmann::json::array();
  double render_seconds = 0;

  for (int k = 0; k < options.frames; ++k) {
    const double t = k * dt;
    const double stamp_value = options.first_timestamp + t;
    const std::string stamp = Stamp(stamp_value);
    const Eigen::Isometry3d T_world_camera = CameraPoseAt(scenario.motion, t, duration);
    const auto render_start = std::chrono::steady_clock::now();

    RenderedView view = Render(scenario.scene, t, T_world_camera, camera);
    const SensorOptions& sensor = options.sensor;
    if (sensor.enabled && sensor.motion_blur_samples > 1) {
      cv::Mat sum = cv::Mat::zeros(view.colour.size(), CV_32FC3);
      for (int s = 0; s < sensor.motion_blur_samples; ++s) {
        const double ts =
            t + sensor.exposure_time * (s / double(sensor.motion_blur_samples - 1) - 0.5);
        sum +=
            Render(scenario.scene, ts, CameraPoseAt(scenario.motion, ts, duration), camera).colour;
      }
      view.colour = sum / sensor.motion_blur_samples;
    }
    double gain = 1.0;
    if (sensor.enabled && sensor.exposure_changes) {
      gain = 1.0 + sensor.exposure_amplitude * (0.6 * std::sin(0.7 * t + options.seed) +
                                                0.4 * std::sin(1.9 * t + 2.0 * options.seed));
    }
    const SensorFrame frame = Sense(view, camera_options, sensor, options.seed, k, gain);

    // Ground truth masks and detections.
    cv::Mat dynamic = cv::Mat::zeros(view.instance.size(), CV_8UC1);
    nlohmann::json frame_detections = nlohmann::json::array();
    for (const SceneObject& object : scenario.scene.objects) {
      const cv::Mat mask = view.instance == object.id;
      const bool moving = object.MovesBetween(t - dt, t) || object.MovesBetween(t, t + dt);
      if (moving) dynamic.setTo(255, mask);
      object_poses +=
          stamp + " " + std::to_string(object.id) + PoseFields(object.pose_at(t)) + "\n";
      const int pixels = cv::countNonZero(mask);
      if (!object.class_name.empty() && pixels >= 100) {
        const cv::Rect box = cv::boundingRect(mask);
        frame_detections.push_back({{"class", object.class_name},
                                    {"score", 1.0},
                                    {"box", {box.x, box.y, box.width, box.height}},
                                    {"instance", object.id}});
      }
    }
    const double fraction = cv::countNonZero(dynamic) / static_cast<double>(dynamic.total());
    summary.dynamic_fraction_mean += fraction / options.frames;
    summary.dynamic_fraction_max = std::max(summary.dynamic_fraction_max, fraction);
    render_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - render_start).count();

    WriteImage(staging / "rgb" / (stamp + ".png"), frame.bgr);
    WriteImage(staging / "depth" / (stamp + ".png"), frame.depth);
    WriteImage(staging / "instance" / (stamp + ".png"), view.instance);
    WriteImage(staging / "dynamic" / (stamp + ".png"), dynamic);
    rgb_list += stamp + " rgb/" + stamp + ".png\n";
    depth_list += stamp + " depth/" + stamp + ".png\n";
    ground_truth.push_back({stamp_value, T_world_camera});
    detections.push_back(
        {{"timestamp", stamp}, {"rgb", "rgb/" + stamp + ".png"}, {"detections", frame_detections}});
  }

  WriteFileAtomically(staging / "rgb.txt", [&](std::ostream& o) { o << rgb_list; });
  WriteFileAtomically(staging / "depth.txt", [&](std::ostream& o) { o << depth_list; });
  WriteTumTrajectory(staging / "groundtruth.txt", ground_truth);
  WriteFileAtomically(staging / "object_poses.txt", [&](std::ostream& o) { o << object_poses; });
  WriteFileAtomically(staging / "detections.json", [&](std::ostream& o) {
    o << nlohmann::json{{"format", "sdoslam detections v1"},
                        {"box_format", "x y width height, pixels"},
                        {"frames", detections}}
             .dump(1)
      << '\n';
  });
  nlohmann::json objects = nlohmann::json::array();
  for (const SceneObject& object : scenario.scene.objects) {
    objects.push_back({{"id", object.id},
                       {"name", object.name},
                       {"class", object.class_name.empty() ? nlohmann::json(nullptr)
                                                           : nlohmann::json(object.class_name)},
                       {"known", !object.class_name.empty()}});
  }
  WriteFileAtomically(staging / "objects.json", [&](std::ostream& o) {
    o << nlohmann::json{{"static_structure_id", 0}, {"objects", objects}}.dump(2) << '\n';
  });
  YAML::Emitter camera_yaml;
  camera_yaml << YAML::BeginMap;
  WriteCameraOptions(camera_options, &camera_yaml);
  camera_yaml << YAML::EndMap;
  WriteFileAtomically(staging / "camera.yaml",
                      [&](std::ostream& o) { o << camera_yaml.c_str() << '\n'; });
  YAML::Emitter info;
  info << YAML::BeginMap << YAML::Key << "scenario" << YAML::Value << scenario.name << YAML::Key
       << "description" << YAML::Value << scenario.description << YAML::Key << "camera_motion"
       << YAML::Value << ToString(scenario.motion) << YAML::Key << "frames" << YAML::Value
       << options.frames << YAML::Key << "seed" << YAML::Value << options.seed << YAML::Key
       << "sensor_noise" << YAML::Value << options.sensor.enabled << YAML::Key
       << "motion_blur_samples" << YAML::Value << options.sensor.motion_blur_samples << YAML::Key
       << "exposure_changes" << YAML::Value << options.sensor.exposure_changes << YAML::EndMap;
  WriteFileAtomically(staging / "sequence.yaml",
                      [&](std::ostream& o) { o << info.c_str() << '\n'; });

  if (std::filesystem::exists(out)) std::filesystem::remove_all(out);
  if (out.has_parent_path()) std::filesystem::create_directories(out.parent_path());
  std::filesystem::rename(staging, out);
  summary.render_seconds = render_seconds;
  summary.total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

cv::Mat ContactSheet(const std::vector<std::string>& scenarios, double duration, int columns,
                     int tile_width) {
  CameraOptions small = SyntheticCamera();
  const double scale = tile_width / static_cast<double>(small.width);
  small.width = tile_width;
  small.height = static_cast<int>(std::lround(small.height * scale));
  small.fx *= scale;
  small.fy *= scale;
  small.cx *= scale;
  small.cy *= scale;
  const Camera camera(small);
  const int label_height = 22;
  cv::Mat sheet(static_cast<int>(scenarios.size()) * (small.height + label_height),
                columns * small.width, CV_8UC3, cv::Scalar(255, 255, 255));
  for (size_t row = 0; row < scenarios.size(); ++row) {
    const Scenario scenario = MakeScenario(scenarios[row], duration);
    const int y0 = static_cast<int>(row) * (small.height + label_height);
    cv::putText(
        sheet,
        scenario.name + ": " + scenario.description + " (camera " + ToString(scenario.motion) + ")",
        cv::Point(6, y0 + 16), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    for (int col = 0; col < columns; ++col) {
      const double t = duration * col / std::max(1, columns - 1);
      const RenderedView view =
          Render(scenario.scene, t, CameraPoseAt(scenario.motion, t, duration), camera);
      cv::Mat tile;
      view.colour.convertTo(tile, CV_8UC3, 255.0);
      // Outline moving objects so the eye finds them.
      for (const SceneObject& object : scenario.scene.objects) {
        std::vector<std::vector<cv::Point>> contours;
        cv::findContours(view.instance == object.id, contours, cv::RETR_EXTERNAL,
                         cv::CHAIN_APPROX_SIMPLE);
        cv::drawContours(
            tile, contours, -1,
            object.class_name.empty() ? cv::Scalar(0, 200, 255) : cv::Scalar(0, 0, 255), 1);
      }
      tile.copyTo(sheet(cv::Rect(col * small.width, y0 + label_height, small.width, small.height)));
    }
  }
  return sheet;
}

}  // namespace sdoslam::synth
