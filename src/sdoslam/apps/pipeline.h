#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "sdoslam/core/camera.h"
#include "sdoslam/dynamic/front_end.h"
#include "sdoslam/eval/mask_metrics.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/dataset.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/slam/system.h"

namespace sdoslam {

// How features on moving things are treated.
enum class RunMode {
  kConventional,  // no front end: every feature is used (ORB-SLAM2 behaviour)
  kSdo,           // the paper's front end decides (segments + detections + motion boundaries)
  kOracle,        // ground-truth dynamic masks of a synthetic sequence: the ceiling for kSdo
};
const char* ToString(RunMode mode);
RunMode ParseRunMode(const std::string& name);  // throws Error naming the known modes

struct RunOptions {
  std::filesystem::path dataset;
  std::filesystem::path associations;  // optional explicit rgb/depth associations
  DatasetLayout layout = DatasetLayout::kAuto;
  std::filesystem::path out;
  CameraOptions camera;
  SlamOptions slam;
  FrontEndOptions front_end;
  RunMode mode = RunMode::kConventional;
  size_t max_frames = 0;       // 0: all
  bool save_overlays = false;  // out/overlays/<rgb name>.png
  bool save_masks = false;     // out/masks/<rgb name>.png (label image) and out/features.csv
  // Called after each frame is tracked, e.g. to look at the map as it grows (with a mapping
  // thread, the map may be changing: read it under your own care, or run sequentially).
  std::function<void(const TrackingResult& result, const System& slam)> after_frame;
  // Polled before each frame: when it returns true the run stops taking frames and commits
  // what it has, marked "interrupted" (sdoslam run wires SIGINT/SIGTERM to it).
  std::function<bool()> stop_requested;
};

// Reads a run's config file: `mode:` and the camera:, SLAM and dynamic: sections into the
// matching RunOptions fields (the rest stay default), and the `run:` section a run's own
// config.yaml has (dataset, layout, associations, max_frames, sequential, save_*), so that a
// config.yaml reruns its run. `versions:` is informative and not compared. Unknown keys are
// errors naming the file and line.
RunOptions LoadRunConfig(const std::filesystem::path& config);

struct RunSummary {
  size_t frames = 0;     // frames processed (fewer than asked for when interrupted)
  size_t requested = 0;  // frames the run was asked to process
  bool interrupted = false;
  size_t tracked = 0, lost = 0, not_initialized = 0;
  size_t keyframes = 0, map_points = 0;
  double median_frame_ms = 0;              // features + tracking
  double median_front_end_ms = 0;          // the dynamic front end (0 in conventional mode)
  FrontEndTiming median_front_end_stages;  // each stage's own median
  double median_total_ms = 0;              // front end + features + tracking, per frame
  double median_mapping_ms = 0;            // per keyframe
  std::vector<MappingRecord> mapping;      // per keyframe, in processing order
  Trajectory trajectory;
  Trajectory keyframe_trajectory;                // the keyframes alive at the end
  std::optional<EstimateEvaluation> evaluation;  // when the dataset has ground truth
  std::optional<EstimateEvaluation> keyframe_evaluation;
  std::optional<MaskEvaluation>
      masks;  // when the dataset has ground-truth masks (not conventional)
};

// Runs SLAM over the sequence and writes CameraTrajectory.txt, KeyFrameTrajectory.txt,
// config.yaml (resolved: it reruns the run), frames.csv (per-frame log) and, when asked, masks/,
// features.csv and overlays/ into `out` as one result set with its manifest.json (see
// io/result_set.h): an earlier set there is replaced as a whole or not at all. Throws Error for
// bad inputs and IoError for an unwritable `out` before the first frame, and Error when the first
// 30 frames cannot start the map (too little depth).
RunSummary RunOnDataset(const RunOptions& options);

std::string FormatRunSummary(const RunSummary& summary);

}  // namespace sdoslam
