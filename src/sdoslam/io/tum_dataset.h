#pragma once

#include <filesystem>
#include <opencv2/core.hpp>
#include <vector>

#include "sdoslam/core/camera.h"

namespace sdoslam {

// One RGB-D frame, from reading (a dataset's Load, or a camera) to the pipeline's Prepare.
struct RgbdFrame {
  size_t index = 0;              // frames are numbered 0, 1, 2, ... in the order they are tracked
  double timestamp = 0.0;        // of the colour image: the frame's time
  double depth_timestamp = 0.0;  // of the associated depth image (a camera may leave it 0)
  cv::Mat bgr;                   // CV_8UC3
  cv::Mat depth;  // CV_32FC1, metres, registered to the colour image; 0 where there is none
  // The colour image's file: file-backed front ends find their per-frame data by its name.
  // Empty for a live camera.
  std::filesystem::path rgb_path;
};

// What the file lists say about one frame, before anything is decoded.
struct RgbdFrameEntry {
  double timestamp = 0.0;
  double depth_timestamp = 0.0;
  std::filesystem::path rgb_path;  // absolute or relative to the working directory
  std::filesystem::path depth_path;
};

struct TumDatasetOptions {
  // rgb/depth pairs further apart than this (seconds) are not associated (TUM tool default).
  double max_time_difference = 0.02;
  // Optional explicit association file (`t_rgb rgb/x.png t_depth depth/y.png` per line),
  // relative to the dataset folder unless absolute. Empty: associate rgb.txt with depth.txt.
  std::filesystem::path associations;

  void Check() const;
};

// A sequence in the TUM RGB-D layout (also Bonn RGB-D Dynamic and `sdoslam synth` output):
// rgb.txt, depth.txt, rgb/, depth/ with 16-bit depth. Opening reads and validates the file
// lists (every listed image must exist); images are decoded only when a frame is loaded, so a
// sequence of any length costs the memory of one frame.
class TumDataset {
 public:
  // Throws Error for a missing folder or list, a malformed line (file:line), timestamps that are
  // absurd (ParseTimestamp) or do not increase, a listed image that does not exist or is not a
  // regular file, or no associated frame at all.
  TumDataset(const std::filesystem::path& folder, const CameraOptions& camera,
             const TumDatasetOptions& options = {});

  size_t size() const { return entries_.size(); }
  const std::vector<RgbdFrameEntry>& entries() const { return entries_; }
  const std::filesystem::path& folder() const { return folder_; }

  // Decodes frame `index`. Throws Error naming the file when an image does not decode, has the
  // wrong size for the camera, a colour image is not 8-bit, or a depth image is not 16-bit
  // single-channel.
  RgbdFrame Load(size_t index) const;

 private:
  std::filesystem::path folder_;
  CameraOptions camera_;
  std::vector<RgbdFrameEntry> entries_;
};

}  // namespace sdoslam
