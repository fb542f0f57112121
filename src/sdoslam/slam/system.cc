#include "sdoslam/slam/system.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "sdoslam/core/error.h"
#include "sdoslam/core/stopwatch.h"
#include "sdoslam/place/default_vocabulary.h"

namespace sdoslam {

void RgbdOptions::Check(const std::string& path) const {
  if (!(bf > 0)) throw Error(path + "bf must be positive");
  if (!(close_depth_baselines > 0)) throw Error(path + "close_depth_baselines must be positive");
  // Positive is not enough (1e308 passed): a baseline of 10 m at an fx of 10^4 pixels is 10^5,
  // and a close-depth limit of 10^4 baselines is none.
  if (!(bf <= 1e5)) throw Error(fmt::format("{}bf must be at most 1e5, got {:g}", path, bf));
  if (!(close_depth_baselines <= 1e4)) {
    throw Error(fmt::format("{}close_depth_baselines must be at most 1e4, got {:g}", path,
                            close_depth_baselines));
  }
}

void SlamOptions::Check() const {
  orb.Check("orb.");
  rgbd.Check("rgbd.");
  tracking.Check("tracking.");
  mapping.Check("mapping.");
  loop_closing.Check("loop_closing.");
}

SlamOptions ReadSlamOptions(ConfigMap& root) {
  SlamOptions o;
  ReadFields(root, &o);
  try {
    o.Check();
  } catch (const Error& e) {
    throw Error(root.origin() + ": " + e.what());
  }
  return o;
}

void WriteSlamOptions(const SlamOptions& o, YAML::Emitter* out) { WriteFields(o, out); }

System::System(const CameraOptions& camera, const SlamOptions& options)
    : options_(options), extractor_((options.Check(), options.orb)) {
  const Camera cam(camera);
  geometry_ = std::make_shared<FrameGeometry>(
      cam, extractor_, options_.rgbd.bf,
      options_.rgbd.close_depth_baselines * options_.rgbd.bf / camera.fx);
  map_ = std::make_unique<Map>();
  const Vocabulary* vocabulary = &DefaultVocabulary();
  if (!options_.vocabulary.empty()) {
    own_vocabulary_ = std::make_unique<Vocabulary>(Vocabulary::Load(options_.vocabulary));
    vocabulary = own_vocabulary_.get();
  }
  places_ = std::make_unique<KeyFramePlaces>(vocabulary);
  tracker_ = std::make_unique<Tracker>(map_.get(), options_.tracking, places_.get());
  mapper_ = std::make_unique<LocalMapper>(map_.get(), options_.mapping);
  loop_closer_ = std::make_unique<LoopCloser>(map_.get(), places_.get(), options_.loop_closing);
  if (MapsBesideTracking()) {
    mapping_thread_ = std::thread([this] { MappingLoop(); });
    loop_thread_ = std::thread([this] { LoopLoop(); });
  }
}

System::~System() { Shutdown(); }

void System::Shutdown() {
  // Local mapping finishes what is queued, then loop closing: the keyframes mapping finished
  // last still get their look.
  mapping_queue_.Close();
  if (mapping_thread_.joinable()) mapping_thread_.join();
  loop_queue_.Close();
  frame_done_.notify_all();  // a frame that ended in an exception notified nobody
  if (loop_thread_.joinable()) loop_thread_.join();
}

void System::LoopLoop() {
  while (const std::optional<KeyFrame*> keyframe = loop_queue_.Pop()) {
    CloseLoops(*keyframe);
    loop_queue_.Done();
  }
}

void System::CloseLoops(KeyFrame* keyframe) {
  LoopResult result;
  if (!MapsBesideTracking()) {
    result = loop_closer_->Process(keyframe);
  } else {
    result =
        loop_closer_->Process(keyframe, &map_mutex_, &frame_done_, [this] { return !in_frame_; });
  }
  if (!result.closed) return;
  spdlog::info("loop closed: frame {} with frame {} ({} inliers, moved {:.3f} m, {:.0f} ms)",
               result.record.frame_index, result.record.loop_frame_index,
               result.record.projected_inliers, result.record.correction_m, result.record.ms);
  std::lock_guard<std::mutex> lock(records_mutex_);
  loop_records_.push_back(result.record);
}

std::vector<LoopRecord> System::LoopRecords() const {
  std::lock_guard<std::mutex> lock(records_mutex_);
  return loop_records_;
}

void System::MappingLoop() {
  // Ends once the queue is closed and everything queued is mapped.
  while (const std::optional<KeyFrame*> keyframe = mapping_queue_.Pop()) {
    const StageClock clock;
    const MappingResult result =
        mapper_->Process(*keyframe, &map_mutex_, &mapping_queue_.waiting());
    const double ms = clock.WallMs(), cpu_ms = clock.CpuMs();
    {
      std::lock_guard<std::mutex> lock(records_mutex_);
      mapping_records_.push_back(
          {.frame_index = (*keyframe)->frame.index, .ms = ms, .cpu_ms = cpu_ms, .result = result});
    }
    loop_queue_.Push(*keyframe);
    mapping_queue_.Done();
  }
}

std::vector<MappingRecord> System::MappingRecords() const {
  std::lock_guard<std::mutex> lock(records_mutex_);
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
  PreparedFrame prepared = ExtractFeatures(index, timestamp, bgr, depth, cv::Mat(), dynamic_labels);
  AddDynamicInputs(&prepared, dynamic_labels, segments, locked_segments);
  return prepared;
}

PreparedFrame System::ExtractFeatures(size_t index, double timestamp, const cv::Mat& bgr,
                                      const cv::Mat& depth, const cv::Mat& given_gray,
                                      const cv::Mat& dynamic_labels) const {
  const CameraOptions& c = geometry_->camera.options();
  if (bgr.cols != c.width || bgr.rows != c.height || depth.size() != bgr.size()) {
    throw Error("frame " + std::to_string(index) + ": images are not " + std::to_string(c.width) +
                "x" + std::to_string(c.height));
  }
  if (bgr.type() != CV_8UC3 && bgr.type() != CV_8UC1) {
    throw Error("frame " + std::to_string(index) +
                ": the image is neither 8-bit colour (3 channels, BGR) nor 8-bit grey");
  }
  const auto start = std::chrono::steady_clock::now();
  if (!given_gray.empty() && (given_gray.size() != bgr.size() || given_gray.type() != CV_8UC1)) {
    throw Error("frame " + std::to_string(index) +
                ": the grey image is not 8-bit single-channel of the frame's size");
  }
  // The grey image is made once: feature extraction and the consistency check share it. The
  // frame takes the colour image as well, for its features' colours (map.ply).
  const cv::Mat gray = given_gray.empty() ? GrayImage(bgr) : given_gray;
  PreparedFrame prepared{Frame(index, timestamp, bgr, depth, geometry_, extractor_, gray,
                               ExtractionAreasOf(index, dynamic_labels)),
                         {},
                         0,
                         gray,
                         depth};
  prepared.features_ms = MsSince(start);
  return prepared;
}

ExtractionAreas System::ExtractionAreasOf(size_t index, const cv::Mat& dynamic_labels) const {
  ExtractionAreas areas;
  if (dynamic_labels.empty() || !options_.orb.budget_on_static) return areas;
  CheckDynamicLabels(index, dynamic_labels);
  // The budget goes to the static part budget_margin_px clear of anything dynamic; the rest of
  // the image (the dynamic part and the ring around it) keeps what a whole-image budget puts
  // there. The ring's keypoints are static features, as without the budget: dropping them cost
  // the blurred, fast-turning real frames (fr1_rpy) 5 mm, where the front end's false selections
  // are many and the ring around them is the static scene (docs/method.md, Features).
  cv::Mat near_dynamic = dynamic_labels != 0;
  // Nothing dynamic: one budget over the image, as without labels (and without sorting the
  // corners twice).
  if (cv::countNonZero(near_dynamic) == 0) return areas;
  const int r = options_.orb.budget_margin_px;
  if (r > 0) {
    cv::dilate(near_dynamic, near_dynamic,
               cv::getStructuringElement(cv::MORPH_ELLIPSE, {2 * r + 1, 2 * r + 1}));
  }
  areas.extra = near_dynamic;
  areas.budget = near_dynamic == 0;
  return areas;
}

void System::CheckDynamicLabels(size_t index, const cv::Mat& dynamic_labels) const {
  const CameraOptions& c = geometry_->camera.options();
  if (dynamic_labels.size() != cv::Size(c.width, c.height) || dynamic_labels.type() != CV_8UC1) {
    throw Error("frame " + std::to_string(index) +
                ": the dynamic label image is not 8-bit single-channel of the frame's size");
  }
}

void System::AddDynamicInputs(PreparedFrame* prepared, const cv::Mat& dynamic_labels,
                              const cv::Mat& segments, const std::vector<uint8_t>& locked_segments,
                              const cv::Mat& unmapped) const {
  const size_t index = prepared->frame.index;
  const cv::Size size = prepared->gray.size();
  const auto start = std::chrono::steady_clock::now();
  if (!dynamic_labels.empty()) CheckDynamicLabels(index, dynamic_labels);
  if (!segments.empty() &&
      (segments.type() != CV_32SC1 || segments.cols > size.width || segments.rows > size.height)) {
    throw Error("frame " + std::to_string(index) +
                ": the segment image is not 32-bit single-channel of at most the frame's size");
  }
  if (!unmapped.empty() && (unmapped.size() != size || unmapped.type() != CV_8UC1)) {
    throw Error("frame " + std::to_string(index) +
                ": the unmapped mask is not 8-bit single-channel of the frame's size");
  }
  if (!dynamic_labels.empty()) prepared->frame.SetLabels(dynamic_labels);
  prepared->frame.SetUnmappable(unmapped);
  if (!segments.empty()) {
    prepared->consistency.emplace();
    prepared->consistency->gray = prepared->gray;
    prepared->consistency->depth = prepared->depth;
    prepared->consistency->segments = segments;
    prepared->consistency->locked_segments = locked_segments;
  }
  prepared->features_ms += MsSince(start);
}

void System::WaitForMapping(size_t index, FrameTiming* timing) {
  if (!MapsBesideTracking()) return;
  const size_t lead = static_cast<size_t>(options_.mapping.max_tracking_lead);
  const auto start = std::chrono::steady_clock::now();
  // Keyframes are mapped in the order they were made: the oldest unfinished one is the one under
  // way, else the queue's first.
  const auto oldest_unmapped = [&](const auto& queue) -> size_t {
    if (queue.under_way) return (*queue.under_way)->frame.index;
    return queue.waiting.empty() ? index : queue.waiting.front()->frame.index;
  };
  if (lead > 0) {
    mapping_queue_.WaitUntil(
        [&](const auto& queue) { return oldest_unmapped(queue) + lead >= index; });
  }
  timing->mapping_lag_frames = index - std::min(index, mapping_queue_.Inspect(oldest_unmapped));
  timing->lock_wait_ms += MsSince(start);
}

TrackingResult System::Track(PreparedFrame&& prepared, FrameTiming* timing) {
  FrameTiming t;
  t.features_ms = prepared.features_ms;
  auto start = std::chrono::steady_clock::now();
  // Counted as waiting for the map: like the map lock, it is time the frame waits on mapping.
  WaitForMapping(prepared.frame.index, &t);
  KeyFrame* keyframe = nullptr;
  bool idle = true, accepts = true;
  if (MapsBesideTracking()) {
    mapping_queue_.Inspect([&](const auto& queue) {
      idle = queue.waiting.empty() && !queue.busy;
      accepts = static_cast<int>(queue.waiting.size()) < options_.mapping.max_queued_keyframes;
    });
  }
  TrackingResult result;
  {
    const auto wait_start = std::chrono::steady_clock::now();
    std::unique_lock<std::mutex> lock(map_mutex_);
    t.lock_wait_ms += MsSince(wait_start);
    // Cleared however the frame ends, an exception included, or loop correction would wait for
    // ever.
    struct InFrame {
      bool* flag;
      explicit InFrame(bool* f) : flag(f) { *flag = true; }
      ~InFrame() { *flag = false; }
    } in_frame(&in_frame_);
    result = tracker_->Track(std::move(prepared.frame), &keyframe, idle, accepts,
                             prepared.consistency ? &*prepared.consistency : nullptr,
                             MapsBesideTracking() ? &lock : nullptr);
    t.lock_wait_ms += tracker_->last_lock_wait_ms();
    result.keyframes_alive = map_->GoodKeyFrames();
    result.map_points_alive = map_->GoodPoints();
  }
  frame_done_.notify_all();
  t.tracking_ms = MsSince(start);
  if (keyframe != nullptr) {
    if (!MapsBesideTracking()) {
      const StageClock clock;
      const MappingResult mapped = mapper_->Process(keyframe);
      CloseLoops(keyframe);
      t.mapping_ms = clock.WallMs();
      mapping_records_.push_back({.frame_index = keyframe->frame.index,
                                  .ms = t.mapping_ms,
                                  .cpu_ms = clock.CpuMs(),
                                  .result = mapped});
    } else {
      mapping_queue_.Push(keyframe);
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

std::vector<ColoredPoint> System::StaticMapCloud(int min_observations) const {
  std::lock_guard<std::mutex> lock(map_mutex_);
  std::vector<ColoredPoint> cloud;
  for (const auto& [id, point] : map_->points()) {
    if (point->bad || point->inconsistent > 0 ||
        static_cast<int>(point->observations.size()) < min_observations) {
      continue;
    }
    Eigen::Vector3d bgr_sum = Eigen::Vector3d::Zero();
    int seen = 0;
    for (const auto& [kf_id, observation] : point->observations) {
      const auto& [keyframe, feature] = observation;
      const auto& colors = keyframe->frame.colors;
      if (keyframe->bad || feature < 0 || static_cast<size_t>(feature) >= colors.size()) continue;
      const cv::Vec3b& c = colors[static_cast<size_t>(feature)];
      bgr_sum += Eigen::Vector3d(c[0], c[1], c[2]);
      ++seen;
    }
    ColoredPoint p;
    p.position = point->position.cast<float>();
    const Eigen::Vector3d bgr =
        seen > 0 ? Eigen::Vector3d(bgr_sum / seen) : Eigen::Vector3d(128, 128, 128);
    for (int k = 0; k < 3; ++k) p.rgb[k] = static_cast<uint8_t>(std::lround(bgr[2 - k]));
    cloud.push_back(p);
  }
  return cloud;
}

}  // namespace sdoslam
