#pragma once

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/io/output_folder.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/synth/scene.h"
#include "sdoslam/synth/sensor.h"

namespace sdoslam::synth {

// The kind in the marker of a synthetic sequence's folder (io/output_folder.h).
inline constexpr char kSyntheticSequenceKind[] = "synthetic sequence";

struct SequenceSummary {
  int frames = 0;
  double render_seconds = 0;  // rendering and sensor model, without PNG encoding
  double total_seconds = 0;
  double dynamic_fraction_mean = 0;  // share of pixels on moving objects
  double dynamic_fraction_max = 0;
};

// Writes a sequence with ground truth, frame by frame, in the layout `sdoslam run`, `eval` and
// `eval-masks` read (see WriteSequence). Everything goes to a sibling staging folder first and
// is switched into place by Finish() (io/output_folder.h), so a failed or killed run never
// leaves a half-written sequence; an existing non-empty `out` is an error unless `overwrite`,
// and even then is replaced only when it is an earlier synthetic sequence holding nothing else.
// `inputs` (a real recording the sequence is rendered over) may not be `out` or around it.
// Shared by the synthetic rooms and the real-background sequences so that both give the same
// ground truth.
class SequenceWriter {
 public:
  SequenceWriter(std::filesystem::path out, bool overwrite, const std::string& title,
                 std::vector<std::filesystem::path> inputs = {});
  ~SequenceWriter() = default;  // OutputFolder removes the staging folder without Finish()
  SequenceWriter(const SequenceWriter&) = delete;
  SequenceWriter& operator=(const SequenceWriter&) = delete;

  // One frame at `stamp` (seconds), scene time `t`, frame interval `dt`: the sensor images,
  // the rendered instance ids (0: static), and the scene, from which the dynamic mask (objects
  // moving between t − dt and t + dt), the known-class boxes and the object poses are derived.
  void AddFrame(double stamp, double t, double dt, const SensorFrame& frame,
                const cv::Mat& instance, const Eigen::Isometry3d& T_world_camera,
                const Scene& scene);

  // Writes the lists, ground truth, detections, objects.json, camera.yaml and sequence.yaml
  // (`info` is a finished YAML map), then moves the folder into place.
  SequenceSummary Finish(const CameraOptions& camera, const Scene& scene,
                         const YAML::Emitter& info);

 private:
  std::filesystem::path out_, staging_;
  std::unique_ptr<OutputFolder> folder_;
  SequenceSummary summary_;
  std::string rgb_list_, depth_list_, object_poses_;
  Trajectory ground_truth_;
  nlohmann::json detections_ = nlohmann::json::array();
};

}  // namespace sdoslam::synth
