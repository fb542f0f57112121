#include "sdoslam/synth/sequence.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/synth/renderer.h"

namespace sdoslam::synth {

void SynthOptions::Check() const {
  if (frames < 1 || frames > 100000) throw Error("frames must be in 1..100000");
  if (!std::isfinite(first_timestamp) || first_timestamp < 0)
    throw Error("first timestamp must be >= 0");
  // The farthest depth the synthetic camera reports must fit 16 bits.
  if (!(depth_factor >= 100 && depth_factor * SyntheticCamera().depth_max <= 65535))
    throw Error(
        fmt::format("depth factor must be in 100..{:.0f}", 65535 / SyntheticCamera().depth_max));
  sensor.Check();
  MakeScenario(scenario, 1.0, motion);  // throws for an unknown name
}

namespace {

// A rolling shutter's view: each band of rows rendered at its own time, row v at
// t + (v - h/2) / h * readout (v the band's middle row), with the camera and the objects where
// they are then.
RenderedView RenderRollingShutter(const Scenario& scenario, double t, double duration,
                                  const Camera& camera, double readout) {
  const int h = camera.height();
  RenderedView view = AllocateView(camera);
  for (int row = 0; row < h; row += kRollingShutterBandRows) {
    const int end = std::min(h, row + kRollingShutterBandRows);
    const double middle_row = 0.5 * (row + end - 1);
    const double t_row = t + (middle_row - 0.5 * h) / h * readout;
    RenderRows(scenario.scene, t_row, CameraPoseAt(scenario.motion, t_row, duration), camera, row,
               end, &view);
  }
  return view;
}

}  // namespace

SequenceSummary WriteSequence(const SynthOptions& options, const std::filesystem::path& out,
                              bool overwrite) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  CameraOptions camera_options = SyntheticCamera();
  camera_options.depth_factor = options.depth_factor;
  camera_options.readout_s = options.sensor.readout_time;  // checked against the frame rate
  const Camera camera(camera_options);
  const double dt = 1.0 / camera_options.fps;
  const double duration = (options.frames - 1) * dt;
  const Scenario scenario = MakeScenario(options.scenario, duration, options.motion);

  // The scenario may ask for a less perfect sensor than the default (the long loop's depth
  // distortion); the caller's choices (noise on or off, blur, exposure) still hold.
  SensorOptions sensor = options.sensor;
  sensor.depth_distortion = scenario.depth_distortion;

  SequenceWriter writer(out, overwrite, scenario.name);
  double render_seconds = 0;

  for (int k = 0; k < options.frames; ++k) {
    const double t = k * dt;
    const Eigen::Isometry3d T_world_camera = CameraPoseAt(scenario.motion, t, duration);
    const auto render_start = std::chrono::steady_clock::now();

    RenderedView view = sensor.readout_time > 0 ? RenderRollingShutter(scenario, t, duration,
                                                                       camera, sensor.readout_time)
                                                : Render(scenario.scene, t, T_world_camera, camera);
    // (SensorOptions::Check keeps blur and supersampling away from a rolling shutter.)
    if (sensor.enabled && sensor.motion_blur_samples > 1) {
      cv::Mat sum = cv::Mat::zeros(view.colour.size(), CV_32FC3);
      for (int s = 0; s < sensor.motion_blur_samples; ++s) {
        const double ts =
            t + sensor.exposure_time * (s / double(sensor.motion_blur_samples - 1) - 0.5);
        sum += RenderColour(scenario.scene, ts, CameraPoseAt(scenario.motion, ts, duration), camera,
                            sensor.supersampling);
      }
      view.colour = sum / sensor.motion_blur_samples;
    } else if (sensor.supersampling > 1) {
      view.colour = RenderColour(scenario.scene, t, T_world_camera, camera, sensor.supersampling);
    }
    double gain = 1.0;
    if (sensor.enabled && sensor.exposure_changes) {
      gain = 1.0 + sensor.exposure_amplitude * (0.6 * std::sin(0.7 * t + options.seed) +
                                                0.4 * std::sin(1.9 * t + 2.0 * options.seed));
    }
    const SensorFrame frame = Sense(view, camera_options, sensor, options.seed, k, gain);

    render_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - render_start).count();
    writer.AddFrame(options.first_timestamp + t, t, dt, frame, view.instance, T_world_camera,
                    scenario.scene);
  }

  YAML::Emitter info;
  info << YAML::BeginMap << YAML::Key << "scenario" << YAML::Value << scenario.name << YAML::Key
       << "description" << YAML::Value << scenario.description << YAML::Key << "camera_motion"
       << YAML::Value << ToString(scenario.motion) << YAML::Key << "frames" << YAML::Value
       << options.frames << YAML::Key << "seed" << YAML::Value << options.seed << YAML::Key
       << "sensor_noise" << YAML::Value << options.sensor.enabled << YAML::Key << "depth_distortion"
       << YAML::Value << fmt::format("{}", sensor.depth_distortion) << YAML::Key
       << "motion_blur_samples" << YAML::Value << options.sensor.motion_blur_samples << YAML::Key
       << "supersampling" << YAML::Value << options.sensor.supersampling << YAML::Key
       << "readout_time" << YAML::Value << options.sensor.readout_time << YAML::Key
       << "exposure_changes" << YAML::Value << options.sensor.exposure_changes << YAML::EndMap;
  SequenceSummary summary = writer.Finish(camera_options, scenario.scene, info);
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
