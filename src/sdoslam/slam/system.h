#pragma once

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <thread>

#include "sdoslam/core/bounded_queue.h"
#include "sdoslam/core/camera.h"
#include "sdoslam/core/config.h"
#include "sdoslam/io/point_cloud.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/loop/loop_closer.h"
#include "sdoslam/mapping/local_mapper.h"
#include "sdoslam/tracking/tracker.h"

namespace YAML {
class Emitter;
}

namespace sdoslam {

// Depth as a virtual stereo pair (ORB-SLAM2's RGB-D frames), config section rgbd:.
struct RgbdOptions {
  double bf = 40.0;                     // virtual stereo baseline × fx (ORB-SLAM2's Kinect value)
  double close_depth_baselines = 40.0;  // "close" = depth < this × baseline (≈3.1 m for TUM)
  void Check(const std::string& path = "rgbd.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("bf", o.bf);
    visit("close_depth_baselines", o.close_depth_baselines);
  }
};

// The SLAM's settings. In a config file they sit at the top level beside camera: and run:, each
// at the path its VisitFields gives (orb.num_features, mapping.bundle_adjustment.iterations).
struct SlamOptions {
  OrbOptions orb;
  RgbdOptions rgbd;
  TrackerOptions tracking;
  LocalMapperOptions mapping;
  LoopClosingOptions loop_closing;
  // Bag-of-words vocabulary for place recognition (sdoslam vocab build), for relocalization and
  // loop closing alike; empty: the one built into the library.
  std::string vocabulary;
  // true: local mapping and loop closing run inline after each keyframe, and runs are
  // bit-identical. false (a threaded run): with mapping.concurrent they run in threads of their
  // own beside tracking; without it, inline as with true.
  // Not among the settings below: how a run is driven is the run's (run.sequential in a run
  // config, or --sequential), and library callers set it here.
  bool sequential = true;
  void Check() const;

  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("orb", o.orb);
    visit("rgbd", o.rgbd);
    visit("tracking", o.tracking);
    visit("mapping", o.mapping);
    visit("loop_closing", o.loop_closing);
    visit("vocabulary", o.vocabulary);
  }
};

// Reads the SLAM's settings (orb:, rgbd:, tracking:, mapping:, loop_closing:, vocabulary) from
// the top level of a run config (the camera: section is read by ReadCameraOptions); unknown
// keys below these sections are errors, and the options are checked.
SlamOptions ReadSlamOptions(ConfigMap& root);
// Writes them, each setting at its key, into an open YAML mapping (ReadSlamOptions reads it
// back to the same options).
void WriteSlamOptions(const SlamOptions& options, YAML::Emitter* out);

// Timings of one frame, milliseconds.
struct FrameTiming {
  double features_ms = 0, tracking_ms = 0, mapping_ms = 0;
  double lock_wait_ms = 0;  // of tracking_ms: waiting for the map while local mapping held it
  // Concurrent mapping: how many frames before this one the oldest keyframe was made that local
  // mapping had not finished when this frame was tracked (0: none; at most
  // mapping.max_tracking_lead when that bounds it).
  size_t mapping_lag_frames = 0;
};

// Local mapping of one keyframe.
struct MappingRecord {
  size_t frame_index = 0;  // the frame the keyframe was made from
  double ms = 0;
  // The mapping thread's CPU time for it: in a threaded run `ms` also holds the time tracking
  // had the core.
  double cpu_ms = 0;
  MappingResult result;
};

// A frame made ready for tracking without the map: its ORB features with their labels, and the
// consistency check's inputs. System::Prepare makes it, System::Track consumes it.
struct PreparedFrame {
  Frame frame;
  std::optional<ConsistencyInput> consistency;
  double features_ms = 0;
  // The frame's grey image (made once: extraction and the check share it) and depth image, for
  // the check's inputs.
  cv::Mat gray, depth;
};

// The library's face: feed RGB-D frames in order, read trajectories. Local mapping runs inline,
// or (threaded, mapping.concurrent) in a thread fed by a bounded queue; Shutdown() (or the
// destructor) lets it finish the queued keyframes and joins it.
class System {
 public:
  System(const CameraOptions& camera, const SlamOptions& options);
  ~System();
  System(const System&) = delete;
  System& operator=(const System&) = delete;

  // bgr: CV_8UC3; depth: CV_32FC1 metres (0 = none), registered to the colour image.
  // dynamic_labels: optional CV_8U image (0 = static) from a dynamic-object front end;
  // features on non-zero pixels are never tracked nor mapped.
  // segments: optional CV_32S segment id per pixel (−1: none; any size of the image's aspect),
  // with `locked_segments` (per segment, 1 = movable known class). When given, the scene-flow
  // consistency check (tracking.consistency) refines the static set and culls landmarks that
  // moved; without segments the frame is tracked on the labels alone.
  TrackingResult TrackRgbd(size_t index, double timestamp, const cv::Mat& bgr, const cv::Mat& depth,
                           FrameTiming* timing = nullptr, const cv::Mat& dynamic_labels = cv::Mat(),
                           const cv::Mat& segments = cv::Mat(),
                           const std::vector<uint8_t>& locked_segments = {});

  // TrackRgbd in two steps, so that a pipeline can prepare frame k + 1 (feature extraction,
  // which needs no map) in one thread while frame k is tracked in another. Prepare validates the
  // inputs (Error naming the frame) and may run concurrently with Track, but not with itself:
  // one preparing thread at a time. Track takes frames in order. TrackRgbd(...) is exactly
  // Track(Prepare(...)).
  PreparedFrame Prepare(size_t index, double timestamp, const cv::Mat& bgr, const cv::Mat& depth,
                        const cv::Mat& dynamic_labels = cv::Mat(),
                        const cv::Mat& segments = cv::Mat(),
                        const std::vector<uint8_t>& locked_segments = {}) const;
  // Prepare in two steps, so that feature extraction can run beside a dynamic front end that
  // makes the labels and segments: Prepare(...) is exactly ExtractFeatures(index, timestamp,
  // bgr, depth, {}, dynamic_labels) followed by AddDynamicInputs(&prepared, dynamic_labels,
  // segments, locked_segments). Each validates its own inputs.
  // `gray`: `bgr` in grey where the caller has made it already (a front end that works on grey
  // too shares it); made here otherwise. `dynamic_labels` (CV_8U, non-zero: dynamic, or empty):
  // with orb.budget_on_static the features are spread over the static part (OrbOptions).
  PreparedFrame ExtractFeatures(size_t index, double timestamp, const cv::Mat& bgr,
                                const cv::Mat& depth, const cv::Mat& gray = cv::Mat(),
                                const cv::Mat& dynamic_labels = cv::Mat()) const;
  // `unmapped` (CV_8U, image size, or empty): features that make no map point (Frame::
  // SetUnmappable; the front end's SdoResult::unmapped).
  void AddDynamicInputs(PreparedFrame* prepared, const cv::Mat& dynamic_labels,
                        const cv::Mat& segments, const std::vector<uint8_t>& locked_segments,
                        const cv::Mat& unmapped = cv::Mat()) const;
  TrackingResult Track(PreparedFrame&& prepared, FrameTiming* timing = nullptr);

  // Every tracked frame (lost ones left out), with its pose relative to its reference keyframe
  // composed with that keyframe's current (refined) pose. T_world_camera per pose.
  // Call after Shutdown() in threaded mode to include the last keyframes' refinement.
  Trajectory CameraTrajectory() const;
  Trajectory KeyFrameTrajectory() const;
  // The static map as a coloured point cloud, in the world frame (the first camera's): every
  // map point alive that at least `min_observations` keyframes saw, coloured with the mean of
  // the image colours where they saw it. Points the consistency check counts as moved since
  // their last consistent match are left out, as are (never made) points on features the front
  // end labelled dynamic. The default of 2 leaves out points one keyframe made from its depth
  // and nobody confirmed: they carry the depth sensor's noise and the last keyframe's unculled
  // points. In id order, so a sequential run gives the same cloud every time.
  std::vector<ColoredPoint> StaticMapCloud(int min_observations = 2) const;
  // Finishes local mapping of the queued keyframes and stops the mapping thread. Idempotent.
  void Shutdown();
  const Map& map() const { return *map_; }
  // Each processed keyframe's mapping time and statistics, in processing order.
  std::vector<MappingRecord> MappingRecords() const;
  // Loops closed, in order.
  std::vector<LoopRecord> LoopRecords() const;

 private:
  // Local mapping and loop closing run in threads of their own (a threaded run with
  // mapping.concurrent); otherwise inline, after the frame that made the keyframe.
  bool MapsBesideTracking() const { return !options_.sequential && options_.mapping.concurrent; }
  void MappingLoop();
  void LoopLoop();
  void CloseLoops(KeyFrame* keyframe);
  // Concurrent mapping: waits until local mapping has finished every keyframe made more than
  // mapping.max_tracking_lead frames before frame `index`. Adds the wait to
  // timing->lock_wait_ms and sets timing->mapping_lag_frames.
  void WaitForMapping(size_t index, FrameTiming* timing);
  // Where frame `index`'s features go, from its dynamic labels (OrbOptions::budget_on_static;
  // none without labels).
  ExtractionAreas ExtractionAreasOf(size_t index, const cv::Mat& dynamic_labels) const;
  // Error naming frame `index` unless `dynamic_labels` is CV_8U at the camera's size.
  void CheckDynamicLabels(size_t index, const cv::Mat& dynamic_labels) const;

  SlamOptions options_;
  OrbExtractor extractor_;
  std::shared_ptr<const FrameGeometry> geometry_;
  std::unique_ptr<Map> map_;
  std::unique_ptr<Tracker> tracker_;
  std::unique_ptr<LocalMapper> mapper_;
  std::unique_ptr<Vocabulary> own_vocabulary_;  // when options name a file
  std::unique_ptr<KeyFramePlaces> places_;
  std::unique_ptr<LoopCloser> loop_closer_;

  mutable std::mutex map_mutex_;  // guards the map between tracking and the mapping thread
  // Guarded by map_mutex_: tracking is inside a frame (it lets go of the lock while it solves);
  // loop correction waits for frame_done_ until it is not.
  bool in_frame_ = false;
  std::condition_variable frame_done_;
  // Concurrent mapping: keyframes for local mapping (its waiting() flag stops local BA), and the
  // keyframes local mapping has finished, for loop closing.
  BoundedQueue<KeyFrame*> mapping_queue_;
  BoundedQueue<KeyFrame*> loop_queue_;
  mutable std::mutex records_mutex_;  // guards the two logs below
  std::vector<MappingRecord> mapping_records_;
  std::vector<LoopRecord> loop_records_;
  std::thread mapping_thread_;
  std::thread loop_thread_;
};

}  // namespace sdoslam
