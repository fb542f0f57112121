#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/synth/sensor.h"
#include "sdoslam/synth/sequence_writer.h"

namespace sdoslam::synth {

// Moving objects rendered into a real static RGB-D recording: a benchmark with full ground
// truth (dynamic and instance masks, detections, object poses) made from any TUM-layout folder
// that has a groundtruth.txt. The objects follow the recording's real trajectory, are z-buffered
// against its real depth (they occlude and are occluded), and their own depth gets the sensor
// model's noise and silhouette shadows; the real pixels are left as recorded.
struct BackgroundSynthOptions {
  std::filesystem::path background;  // TUM layout: rgb.txt, depth.txt, groundtruth.txt, images
  CameraOptions camera;              // of the recording (distortion included)
  std::string scenario = "mixed";    // see BackgroundScenarioNames()
  // Play the recording forward, then backward (without repeating the turning frame): twice the
  // length, a real trajectory that returns to its start.
  bool forward_backward = false;
  int max_frames = 0;  // recording frames used, from the first (0: all)
  uint32_t seed = 1;   // sensor noise on the objects
  SensorOptions sensor;
  // Largest distance (seconds) from a frame to the ground-truth samples it is interpolated from.
  double max_ground_truth_gap = 0.05;
  void Check() const;
};

// static: nothing added (the static baseline of the same play); carried_box: a large textured box
// carried in front of the camera (about a quarter of the
//   image), moving with it; swinging_boxes: two boxes swinging across the view (unknown class);
// people: two people walking across the view (class person); mixed: the carried box, a swinging
// box and a walking person; person_fills_view: a person walks up to the camera, fills the whole
// view for about half a second (0.6 of the way through), turns and walks away;
// person_stops_close: a person walks up from 2.2 m, stands 0.75 m ahead for a second (about half
// the image, head cut off), then walks back; biased_box: a box standing still in front of the
// scene whose depth the sensor reads 4 % too far (a material's bias), static throughout.
std::vector<std::string> BackgroundScenarioNames();

// Writes the sequence to `out` in the layout of WriteSequence, with the recording's camera in
// camera.yaml. Throws Error naming the file for a recording that cannot be read, a frame without
// ground truth, or an unknown scenario.
SequenceSummary WriteBackgroundSequence(const BackgroundSynthOptions& options,
                                        const std::filesystem::path& out, bool overwrite = false);

}  // namespace sdoslam::synth
