#include "sdoslam/slam/system.h"

#include <yaml-cpp/yaml.h>

#include <chrono>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "sdoslam/core/error.h"
#include "sdoslam/core/stopwatch.h"

namespace sdoslam {

void SlamOptions::Check() const {
  orb.Check();
  tracking.Check();
  mapping.Check();
  if (!(bf > 0)) throw Error("rgbd.bf must be positive");
  if (!(close_depth_baselines > 0)) throw Error("rgbd.close_depth_baselines must be positive");
  if (max_queued_keyframes < 1) throw Error("mapping.max_queued_keyframes must be >= 1");
}

SlamOptions ReadSlamOptions(ConfigMap& root) {
  SlamOptions o;
  if (auto s = root.Section("orb")) {
    s->Read("num_features", &o.orb.num_features);
    s->Read("scale_factor", &o.orb.scale_factor);
    s->Read("num_levels", &o.orb.num_levels);
    s->Read("fast_threshold", &o.orb.fast_threshold);
    s->Read("min_fast_threshold", &o.orb.min_fast_threshold);
    s->RejectUnknownKeys();
  }
  if (auto s = root.Section("rgbd")) {
    s->Read("bf", &o.bf);
    s->Read("close_depth_baselines", &o.close_depth_baselines);
    s->RejectUnknownKeys();
  }
  if (auto s = root.Section("tracking")) {
    s->Read("min_inliers", &o.tracking.min_inliers);
    s->Read("max_frames_between_keyframes", &o.tracking.max_frames_between_keyframes);
    s->Read("reference_ratio", &o.tracking.reference_ratio);
    s->Read("projection_radius", &o.tracking.projection_radius);
    s->Read("relocalization_candidates", &o.tracking.relocalization_candidates);
    s->Read("relocalization_prior_frames", &o.tracking.relocalization_prior_frames);
    s->Read("relocalization_radius_factor", &o.tracking.relocalization_radius_factor);
    s->RejectUnknownKeys();
  }
  if (auto s = root.Section("consistency")) {
    SceneFlowOptions::VisitFields(o.tracking.consistency,
                                  [&](const char* key, auto& value) { s->Read(key, &value); });
    s->RejectUnknownKeys();
  }
  if (auto s = root.Section("mapping")) {
    s->Read("fuse_neighbours", &o.mapping.fuse_neighbours);
    s->Read("redundant_ratio", &o.mapping.redundant_ratio);
    s->Read("local_keyframes", &o.mapping.local_keyframes);
    s->Read("fixed_keyframes", &o.mapping.fixed_keyframes);
    s->Read("ba_iterations", &o.mapping.bundle_adjustment.iterations);
    s->Read("ba_refine_iterations", &o.mapping.bundle_adjustment.refine_iterations);
    s->RejectUnknownKeys();
  }
  try {
    o.Check();
  } catch (const Error& e) {
    throw Error(root.origin() + ": " + e.what());
  }
  return o;
}

void WriteSlamOptions(const SlamOptions& o, YAML::Emitter* out) {
  YAML::Emitter& y = *out;
  y << YAML::Key << "orb" << YAML::Value << YAML::BeginMap << YAML::Key << "num_features"
    << YAML::Value << o.orb.num_features << YAML::Key << "scale_factor" << YAML::Value
    << o.orb.scale_factor << YAML::Key << "num_levels" << YAML::Value << o.orb.num_levels
    << YAML::Key << "fast_threshold" << YAML::Value << o.orb.fast_threshold << YAML::Key
    << "min_fast_threshold" << YAML::Value << o.orb.min_fast_threshold << YAML::EndMap;
  y << YAML::Key << "rgbd" << YAML::Value << YAML::BeginMap << YAML::Key << "bf" << YAML::Value
    << o.bf << YAML::Key << "close_depth_baselines" << YAML::Value << o.close_depth_baselines
    << YAML::EndMap;
  y << YAML::Key << "tracking" << YAML::Value << YAML::BeginMap << YAML::Key << "min_inliers"
    << YAML::Value << o.tracking.min_inliers << YAML::Key << "max_frames_between_keyframes"
    << YAML::Value << o.tracking.max_frames_between_keyframes << YAML::Key
    << "relocalization_candidates" << YAML::Value << o.tracking.relocalization_candidates
    << YAML::Key << "relocalization_prior_frames" << YAML::Value
    << o.tracking.relocalization_prior_frames << YAML::Key << "relocalization_radius_factor"
    << YAML::Value << o.tracking.relocalization_radius_factor << YAML::Key << "reference_ratio"
    << YAML::Value << o.tracking.reference_ratio << YAML::Key << "projection_radius" << YAML::Value
    << o.tracking.projection_radius << YAML::EndMap;
  y << YAML::Key << "consistency" << YAML::Value << YAML::BeginMap;
  SceneFlowOptions::VisitFields(o.tracking.consistency, [&](const char* key, const auto& value) {
    y << YAML::Key << key << YAML::Value << value;
  });
  y << YAML::EndMap;
  y << YAML::Key << "mapping" << YAML::Value << YAML::BeginMap << YAML::Key << "fuse_neighbours"
    << YAML::Value << o.mapping.fuse_neighbours << YAML::Key << "redundant_ratio" << YAML::Value
    << o.mapping.redundant_ratio << YAML::Key << "local_keyframes" << YAML::Value
    << o.mapping.local_keyframes << YAML::Key << "fixed_keyframes" << YAML::Value
    << o.mapping.fixed_keyframes << YAML::Key << "ba_iterations" << YAML::Value
    << o.mapping.bundle_adjustment.iterations << YAML::Key << "ba_refine_iterations" << YAML::Value
    << o.mapping.bundle_adjustment.refine_iterations << YAML::EndMap;
}

System::System(const CameraOptions& camera, const SlamOptions& options)
    : options_(options), extractor_((options.Check(), options.orb)) {
  const Camera cam(camera);
  geometry_ = std::make_shared<FrameGeometry>(
      cam, extractor_, options_.bf, options_.close_depth_baselines * options_.bf / camera.fx);
  map_ = std::make_unique<Map>();
  tracker_ = std::make_unique<Tracker>(map_.get(), options_.tracking);
  mapper_ = std::make_unique<LocalMapper>(map_.get(), options_.mapping);
  if (!options_.sequential) mapping_thread_ = std::thread([this] { MappingLoop(); });
}

System::~System() { Shutdown(); }

void System::Shutdown() {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stop_ = true;
  }
  queue_changed_.notify_all();
  if (mapping_thread_.joinable()) mapping_thread_.join();
}

void System::MappingLoop() {
  for (;;) {
    KeyFrame* keyframe = nullptr;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_changed_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, and everything queued is mapped
      keyframe = queue_.front();
      queue_.pop_front();
      mapping_busy_ = true;
    }
    const auto start = std::chrono::steady_clock::now();
    const MappingResult result = mapper_->Process(keyframe, &map_mutex_);
    const double ms = MsSince(start);
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      mapping_busy_ = false;
      mapping_records_.push_back({keyframe->frame.index, ms, result});
    }
  }
}

std::vector<MappingRecord> System::MappingRecords() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return mapping_records_;
}

TrackingResult System::TrackRgbd(size_t index, double timestamp, const cv::Mat& bgr,
                                 const cv::Mat& depth, FrameTiming* timing,
                                 const cv::Mat& dynamic_labels, const cv::Mat& segments,
                                 const std::vector<uint8_t>& locked_segments) {
  return Track(Prepare(index, timestamp, bgr, depth, dynamic_labels, segments, locked_segments),
               timing);
}

PreparedFrame System::Prepare(size_t index, double timestamp, const cv::Mat& bgr,
                              const cv::Mat& depth, const cv::Mat& dynamic_labels,
                              const cv::Mat& segments,
                              const std::vector<uint8_t>& locked_segments) const {
  const CameraOptions& c = geometry_->camera.options();
  if (bgr.cols != c.width || bgr.rows != c.height || depth.size() != bgr.size()) {
    throw Error("frame " + std::to_string(index) + ": images are not " + std::to_string(c.width) +
                "x" + std::to_string(c.height));
  }
  const auto start = std::chrono::steady_clock::now();
  if (!dynamic_labels.empty() &&
      (dynamic_labels.size() != bgr.size() || dynamic_labels.type() != CV_8UC1)) {
    throw Error("frame " + std::to_string(index) +
                ": the dynamic label image is not 8-bit single-channel of the frame's size");
  }
  if (!segments.empty() &&
      (segments.type() != CV_32SC1 || segments.cols > bgr.cols || segments.rows > bgr.rows)) {
    throw Error("frame " + std::to_string(index) +
                ": the segment image is not 32-bit single-channel of at most the frame's size");
  }
  // The grey image is made once: feature extraction and the consistency check share it.
  cv::Mat gray;
  if (bgr.channels() == 3) {
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  } else {
    gray = bgr;
  }
  PreparedFrame prepared{Frame(index, timestamp, gray, depth, geometry_, extractor_), {}, 0};
  if (!dynamic_labels.empty()) prepared.frame.SetLabels(dynamic_labels);
  if (!segments.empty()) {
    prepared.consistency.emplace();
    prepared.consistency->gray = gray;
    prepared.consistency->depth = depth;
    prepared.consistency->segments = segments;
    prepared.consistency->locked_segments = locked_segments;
  }
  prepared.features_ms = MsSince(start);
  return prepared;
}

TrackingResult System::Track(PreparedFrame&& prepared, FrameTiming* timing) {
  FrameTiming t;
  t.features_ms = prepared.features_ms;
  auto start = std::chrono::steady_clock::now();
  KeyFrame* keyframe = nullptr;
  bool idle = true, accepts = true;
  if (!options_.sequential) {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    idle = queue_.empty() && !mapping_busy_;
    accepts = static_cast<int>(queue_.size()) < options_.max_queued_keyframes;
  }
  TrackingResult result;
  {
    const auto wait_start = std::chrono::steady_clock::now();
    std::unique_lock<std::mutex> lock(map_mutex_);
    t.lock_wait_ms = MsSince(wait_start);
    result = tracker_->Track(std::move(prepared.frame), &keyframe, idle, accepts,
                             prepared.consistency ? &*prepared.consistency : nullptr,
                             options_.sequential ? nullptr : &lock);
    t.lock_wait_ms += tracker_->last_lock_wait_ms();
    result.keyframes_alive = map_->GoodKeyFrames();
    result.map_points_alive = map_->GoodPoints();
  }
  t.tracking_ms = MsSince(start);
  if (keyframe != nullptr) {
    if (options_.sequential) {
      start = std::chrono::steady_clock::now();
      const MappingResult mapped = mapper_->Process(keyframe);
      t.mapping_ms = MsSince(start);
      mapping_records_.push_back({keyframe->frame.index, t.mapping_ms, mapped});
    } else {
      {
        std::lock_guard<std::mutex> lock(queue_mutex_);
        queue_.push_back(keyframe);
      }
      queue_changed_.notify_one();
    }
  }
  if (timing != nullptr) *timing = t;
  return result;
}

Trajectory System::CameraTrajectory() const {
  std::lock_guard<std::mutex> lock(map_mutex_);
  Trajectory out;
  for (const Tracker::TrajectoryEntry& e : tracker_->trajectory()) {
    if (e.reference == nullptr) continue;
    // A culled reference hands over to its parent through the pose it had relative to it.
    const Eigen::Isometry3d T_camera_world =
        ComposeWithReference(e.reference, e.T_camera_reference);
    out.push_back({e.timestamp, T_camera_world.inverse()});
  }
  return out;
}

Trajectory System::KeyFrameTrajectory() const {
  std::lock_guard<std::mutex> lock(map_mutex_);
  Trajectory out;
  for (const auto& [id, kf] : map_->keyframes()) {
    if (!kf->bad) out.push_back({kf->frame.timestamp, kf->pose().inverse()});
  }
  return out;
}

}  // namespace sdoslam
