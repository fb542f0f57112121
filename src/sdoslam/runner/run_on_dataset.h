#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/eval/mask_metrics.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/dataset.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/objects/object_tracker.h"
#include "sdoslam/pipeline/pipeline.h"

// The offline runner: a whole dataset through the Pipeline, its result set written and
// evaluated. Above pipeline/, so that the library's entry point (Pipeline) needs no evaluation
// or result files.
namespace sdoslam {

// Where a run is, for a progress line.
struct RunProgress {
  size_t frames_done = 0, frames_requested = 0;
  double elapsed_s = 0;
  TrackingState state = TrackingState::kNotInitialized;
  size_t keyframes_alive = 0;
};

// "frame 120/859  29.8 fps  ok  14 keyframes": one line of a run's progress (no newline).
std::string FormatRunProgress(const RunProgress& progress);

struct RunOptions {
  std::filesystem::path dataset;
  std::filesystem::path associations;  // optional explicit rgb/depth associations
  DatasetLayout layout = DatasetLayout::kAuto;
  std::filesystem::path out;
  CameraOptions camera;
  SlamOptions slam;
  FrontEndOptions front_end;
  RunMode mode = RunMode::kConventional;
  size_t max_frames = 0;               // 0: all
  bool save_overlays = false;          // out/overlays/<rgb name>.png
  std::vector<size_t> overlay_frames;  // with save_overlays: only these frame indices (empty: all)
  bool save_masks = false;  // out/masks/<rgb name>.png (label image) and out/features.csv
  // out/map.ply: the static map as a coloured point cloud at the end of the run
  // (System::StaticMapCloud).
  bool save_map = false;
  // out/objects.csv and out/objects/<id>.txt: the moving objects of the label images with their
  // ids, classes, centroids and own motions (objects/object_tracker.h). Reads what tracking
  // produced and changes nothing in it.
  bool save_objects = false;
  ObjectTrackerOptions objects;
  // On a synthetic sequence (dynamic/ and instance/ folders beside the frames), score the
  // front end's masks against the ground truth (RunSummary::masks), not in conventional mode.
  // That reads two images a frame and compares them pixel by pixel, inside the frame loop: about
  // 2 ms of CPU a frame that the system itself does not need. bench turns it off (it reports no
  // mask scores) so that its timings are the system's alone.
  bool evaluate_masks = true;
  // Called after each frame is tracked, e.g. to look at the map as it grows (with a mapping
  // thread, the map may be changing: read it under your own care, or run sequentially).
  std::function<void(const TrackingResult& result, const System& slam)> after_frame;
  // Polled before each frame: when it returns true the run stops taking frames and commits
  // what it has, marked "interrupted" (sdoslam run wires SIGINT/SIGTERM to it).
  std::function<bool()> stop_requested;
  // Called after each frame (sdoslam run draws its progress line with it).
  std::function<void(const RunProgress&)> progress;
  // Frames are loaded and prepared (front end, feature extraction) in a thread of their own, at
  // most prepare_queue_capacity frames ahead of tracking. Unset: when mapping is threaded
  // (slam.sequential false). Either way the trajectory is the one the inline order gives, up to
  // the mapping thread's timing.
  std::optional<bool> prepare_ahead;
  size_t prepare_queue_capacity = 2;
  // Frames are read at the camera's rate (camera.fps) instead of as fast as the run takes
  // them, the way a live camera delivers them: the throughput then says whether the system
  // keeps up and the latency is the one a camera's frames see. None are dropped: a run slower
  // than its camera falls behind, its frames queue and their latency grows.
  bool camera_rate = false;
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
  size_t map_cloud_points = 0;             // points written to map.ply (save_map)
  double median_frame_ms = 0;              // features + tracking
  double median_front_end_ms = 0;          // the dynamic front end (0 in conventional mode)
  FrontEndTiming median_front_end_stages;  // each stage's own median
  double median_total_ms = 0;              // front end + features + tracking, per frame
  double median_mapping_ms = 0;            // per keyframe
  // Throughput: wall-clock seconds of the whole run (loading, every stage and the threads'
  // overlap included) per frame; and the median latency, from a frame's reading to its pose
  // (FrameOutput::latency_ms), and the median time a frame waited for tracking besides.
  double wall_ms_per_frame = 0;
  double median_latency_ms = 0;
  double median_queued_ms = 0;
  std::vector<MappingRecord> mapping;   // per keyframe, in processing order
  std::vector<LoopRecord> loops;        // loops closed, in order
  std::vector<size_t> relocalizations;  // frames tracked again after lost ones
  Trajectory trajectory;
  Trajectory keyframe_trajectory;                // the keyframes alive at the end
  std::optional<EstimateEvaluation> evaluation;  // when the dataset has ground truth
  std::optional<EstimateEvaluation> keyframe_evaluation;
  // The keyframes under the frames' alignment: the fair comparison of the two (see
  // ComputeAteUnderAlignment).
  std::optional<AteResult> keyframe_ate_in_frame_alignment;
  std::optional<MaskEvaluation>
      masks;  // when the dataset has ground-truth masks (not conventional)
};

// Runs SLAM over the sequence and writes CameraTrajectory.txt, KeyFrameTrajectory.txt,
// config.yaml (resolved: it reruns the run), frames.csv (per-frame log) and, when asked, masks/,
// features.csv, overlays/ and map.ply into `out` as one result set with its manifest.json (see
// io/result_set.h): an earlier set there is replaced as a whole or not at all. Throws Error for
// bad inputs and IoError for an unwritable `out` before the first frame, and Error when the first
// 30 frames cannot start the map (too little depth).
// The pipeline a run over `rgb_paths` needs (the frames file-based front-end backends read;
// may be empty without them); `prepare_ahead`: frames are prepared in a thread of their own, so
// feature extraction runs beside the front end.
PipelineOptions PipelineOptionsOf(const RunOptions& run,
                                  const std::vector<std::filesystem::path>& rgb_paths,
                                  bool prepare_ahead);

RunSummary RunOnDataset(const RunOptions& options);

std::string FormatRunSummary(const RunSummary& summary);

}  // namespace sdoslam
