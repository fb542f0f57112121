#pragma once

#include <filesystem>
#include <string>

#include "sdoslam/core/camera.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/slam/system.h"

namespace sdoslam {

struct RunSummary {
  size_t frames = 0, tracked = 0, lost = 0, not_initialized = 0;
  size_t keyframes = 0, map_points = 0;
  double median_frame_ms = 0;    // features + tracking
  double median_mapping_ms = 0;  // per keyframe
  Trajectory trajectory;
  std::optional<EstimateEvaluation> evaluation;  // when the dataset has groundtruth.txt
};

// Runs SLAM over the sequence in `dataset` and writes CameraTrajectory.txt,
// KeyFrameTrajectory.txt, config.yaml (resolved) and frames.csv (per-frame log) into `out`.
// Throws Error for bad inputs before the first frame, and when the first 30 frames cannot start
// the map (too little depth).
RunSummary RunOnDataset(const std::filesystem::path& dataset,
                        const std::filesystem::path& associations, const CameraOptions& camera,
                        const SlamOptions& options, size_t max_frames,
                        const std::filesystem::path& out);

std::string FormatRunSummary(const RunSummary& summary);

}  // namespace sdoslam
