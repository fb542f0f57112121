#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sensor.h"
#include "sdoslam/synth/sequence_writer.h"

namespace sdoslam::synth {

struct SynthOptions {
  std::string scenario = "walking_xyz";
  std::optional<CameraMotion> motion;  // overrides the scenario's camera motion
  int frames = 300;                    // at the camera's 30 Hz
  uint32_t seed = 1;                   // sensor noise; same seed ⇒ byte-identical files
  double first_timestamp = 1000.0;     // seconds
  // Raw depth units per metre in the 16-bit depth PNGs (TUM: 5000; OMD and Bonn's RealSense and
  // Kinect v2: 1000, millimetres).
  double depth_factor = 5000.0;
  SensorOptions sensor;
  void Check() const;
};

// Renders the sequence and writes, into `out`:
//   rgb/, depth/ (16-bit, options.depth_factor), rgb.txt, depth.txt, groundtruth.txt, camera.yaml
//   (TUM) instance/ (16-bit object ids; 0 = static structure), dynamic/ (8-bit, 255 = moving now),
//   detections.json (known-class boxes per frame), objects.json, object_poses.txt,
//   sequence.yaml (how it was made).
// Everything is written to a sibling folder first and moved into place at the end, so a failed
// run never leaves a half-written sequence; an existing non-empty `out` is an error unless
// `overwrite`.
SequenceSummary WriteSequence(const SynthOptions& options, const std::filesystem::path& out,
                              bool overwrite = false);

// A grid of renderings: one row per scenario, `columns` frames spread over `duration` seconds,
// each tile `tile_width` wide, labelled. For looking at the scenarios, not for SLAM.
cv::Mat ContactSheet(const std::vector<std::string>& scenarios, double duration, int columns = 4,
                     int tile_width = 320);

}  // namespace sdoslam::synth
