#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/dynamic/front_end.h"
#include "sdoslam/io/dataset.h"
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

// What the pipeline is made of: the camera, SLAM, and how moving things are found.
struct PipelineOptions {
  CameraOptions camera;
  SlamOptions slam;
  FrontEndOptions front_end;
  RunMode mode = RunMode::kConventional;
  // kSdo with file backends: the folder their relative paths resolve against, and every frame's
  // rgb path (the detections and masks files are checked against them when the pipeline is made).
  std::filesystem::path dataset_folder;
  std::vector<std::filesystem::path> rgb_paths;
  // kSdo: extract the ORB features in a task beside the front end instead of after it (they need
  // only the grey image; the front end's labels join them afterwards). Same result either way;
  // threaded runs set it so that a frame's preparation can use both cores. Not with
  // slam.orb.budget_on_static, where the extraction needs the labels.
  bool extract_beside_front_end = false;
};

// A frame after the stages that need no map: the dynamic front end's verdict and the ORB
// features. Made by Pipeline::Prepare, consumed by Pipeline::Finish.
struct StagedFrame {
  RgbdFrame input;
  std::optional<SdoResult> sdo;  // kSdo
  cv::Mat labels;                // the per-pixel DynamicLabel image tracking uses; empty: none
  std::vector<uint8_t> locked_segments;
  FrontEndTiming front_end_timing;
  std::optional<PreparedFrame> slam;
  std::chrono::steady_clock::time_point
      started;  // the frame's latency counts from here (Prepare or the load)
  std::chrono::steady_clock::time_point prepared;  // the end of Prepare
};

// One frame's outcome.
struct FrameOutput {
  RgbdFrame input;
  TrackingResult tracking;
  // The final per-pixel verdict: the front end's labels, with the segments the consistency check
  // judged moving marked kSceneFlow (empty in conventional mode without a caller's mask).
  cv::Mat labels;
  std::optional<SdoResult> sdo;
  FrameTiming timing;
  FrontEndTiming front_end_timing;
  // The frame's own time from StagedFrame::started to the end of Finish: its preparation and
  // its tracking, without queued_ms, the time it waited between them for tracking to finish the
  // frames before it. An offline run that reads ahead keeps that queue full and its frames wait
  // there; a camera's frames, when the system keeps up with the camera, do not.
  double latency_ms = 0;
  double queued_ms = 0;
};

// The whole system for one camera: the dynamic front end (per `mode`) and SLAM, one frame at a
// time. Use Track for a live camera (everything inline). A pipelined caller runs Prepare for
// frame k + 1 in one thread while Finish tracks frame k in another (RunOnDataset does this
// unless the run is sequential): Prepare needs no map, and the front end never looks at
// tracking's results, so the two orders give the same trajectory.
class Pipeline {
 public:
  // Throws Error for bad options, unknown backends and missing or mismatched front-end files.
  explicit Pipeline(const PipelineOptions& options);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  // Prepare then Finish. `dynamic_mask`: optional CV_8U image of the frame's size from the
  // caller's own model (non-zero = a moving thing): features there are never tracked nor mapped,
  // in every mode, on top of what the front end finds.
  FrameOutput Track(RgbdFrame input, const cv::Mat& dynamic_mask = cv::Mat());

  // The stages that need no map. One thread at a time, frames in order. Throws Error for inputs
  // of the wrong size or type, naming the frame.
  StagedFrame Prepare(RgbdFrame input, const cv::Mat& dynamic_mask = cv::Mat());
  // Tracking (and, sequential, local mapping). Frames in the order they were prepared.
  FrameOutput Finish(StagedFrame&& staged);

  System& slam() { return *slam_; }
  const System& slam() const { return *slam_; }
  const PipelineOptions& options() const { return options_; }

 private:
  PipelineOptions options_;
  std::unique_ptr<FrontEnd> front_end_;
  std::unique_ptr<System> slam_;
};

}  // namespace sdoslam
