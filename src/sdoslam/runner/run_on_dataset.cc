#include "sdoslam/runner/run_on_dataset.h"

#include <ceres/version.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Core>
#include <algorithm>
#include <exception>
#include <fstream>
#include <future>
#include <opencv2/core/version.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <thread>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/bounded_queue.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/stopwatch.h"
#include "sdoslam/dynamic/overlay.h"
#include "sdoslam/io/png_reader.h"
#include "sdoslam/io/result_set.h"

namespace sdoslam {

RunOptions LoadRunConfig(const std::filesystem::path& config) {
  RunOptions run;
  ConfigMap root = ConfigMap::LoadFile(config.string());
  std::string mode = "conventional";
  root.Read("mode", &mode);  // a run's resolved config.yaml records it
  run.mode = ParseRunMode(mode);
  std::optional<ConfigMap> camera_section = root.Section("camera");
  if (!camera_section) throw Error(config.string() + ": missing the 'camera:' section");
  run.camera = ReadCameraOptions(*camera_section);
  run.slam = ReadSlamOptions(root);
  // A run maps in its own thread unless its run: section or --sequential says otherwise
  // (SlamOptions defaults to sequential for library callers; a run config without run: was
  // therefore always sequential, whatever the help said).
  run.slam.sequential = false;
  run.front_end = ReadFrontEndOptions(root);
  if (std::optional<ConfigMap> section = root.Section("run")) {
    std::string text;
    if (section->Has("dataset")) {
      section->Read("dataset", &text);
      run.dataset = text;
    }
    if (section->Has("layout")) {
      section->Read("layout", &text);
      run.layout = ParseDatasetLayout(text);
    }
    if (section->Has("associations")) {
      section->Read("associations", &text);
      run.associations = text;
    }
    int64_t max_frames = 0;
    section->Read("max_frames", &max_frames);
    if (max_frames < 0) throw Error(config.string() + ": run.max_frames must be >= 0");
    run.max_frames = static_cast<size_t>(max_frames);
    section->Read("sequential", &run.slam.sequential);
    section->Read("save_overlays", &run.save_overlays);
    section->Read("save_masks", &run.save_masks);
    section->Read("save_map", &run.save_map);
    section->Read("save_objects", &run.save_objects);
    section->Read("camera_rate", &run.camera_rate);
    section->RejectUnknownKeys();
  }
  if (std::optional<ConfigMap> section = root.Section("objects")) {
    ReadFields(*section, &run.objects);
    section->RejectUnknownKeys();
    try {
      run.objects.Check();
    } catch (const Error& e) {
      throw Error(config.string() + ": " + e.what());
    }
  }
  if (std::optional<ConfigMap> versions = root.Section("versions")) {
    // Informative: what wrote the file. Read so that it is not an unknown key.
    std::string ignored;
    for (const char* key : {"sdoslam", "opencv", "ceres", "eigen", "detector_model_sha256",
                            "segmenter_model_sha256", "flow_model_sha256"})
      versions->Read(key, &ignored);
    versions->RejectUnknownKeys();
  }
  root.RejectUnknownKeys();
  return run;
}

namespace {

// Ground-truth dynamic masks of a synthetic sequence as a label image.
cv::Mat LoadOracleLabels(const std::filesystem::path& dataset, const std::filesystem::path& rgb,
                         cv::Size size) {
  const auto path = dataset / "dynamic" / rgb.filename();
  const cv::Mat mask = ReadImage(path, cv::IMREAD_GRAYSCALE);
  if (mask.empty()) throw Error(path.string() + ": cannot read the ground-truth dynamic mask");
  if (mask.size() != size) throw Error(path.string() + ": mask size differs from the images");
  cv::Mat labels(size, CV_8U, cv::Scalar(kStatic));
  labels.setTo(kMovingUnknown, mask);
  return labels;
}

// config.yaml of a run: every option as resolved, and the `run:` section, so that
// `sdoslam run --config OUT/config.yaml --out OTHER` repeats the run (bit-identical under
// --sequential); `versions:` says what wrote it.
std::string ResolvedConfig(const RunOptions& run) {
  namespace fs = std::filesystem;
  YAML::Emitter resolved;
  resolved << YAML::BeginMap;
  resolved << YAML::Key << "mode" << YAML::Value << ToString(run.mode);
  resolved << YAML::Key << "run" << YAML::Value << YAML::BeginMap;
  resolved << YAML::Key << "dataset" << YAML::Value
           << fs::absolute(run.dataset).lexically_normal().string();
  resolved << YAML::Key << "layout" << YAML::Value << ToString(run.layout);
  if (!run.associations.empty()) {
    resolved << YAML::Key << "associations" << YAML::Value
             << fs::absolute(run.associations).lexically_normal().string();
  }
  resolved << YAML::Key << "max_frames" << YAML::Value << run.max_frames;
  resolved << YAML::Key << "sequential" << YAML::Value << run.slam.sequential;
  resolved << YAML::Key << "save_overlays" << YAML::Value << run.save_overlays;
  resolved << YAML::Key << "save_masks" << YAML::Value << run.save_masks;
  resolved << YAML::Key << "save_map" << YAML::Value << run.save_map;
  resolved << YAML::Key << "save_objects" << YAML::Value << run.save_objects;
  resolved << YAML::Key << "camera_rate" << YAML::Value << run.camera_rate;
  resolved << YAML::EndMap;
  WriteCameraOptions(run.camera, &resolved);
  WriteSlamOptions(run.slam, &resolved);
  if (run.mode == RunMode::kSdo) WriteFrontEndOptions(run.front_end, &resolved);
  if (run.save_objects) {
    resolved << YAML::Key << "objects" << YAML::Value << YAML::BeginMap;
    WriteFields(run.objects, &resolved);
    resolved << YAML::EndMap;
  }
  resolved << YAML::Key << "versions" << YAML::Value << YAML::BeginMap;
  resolved << YAML::Key << "sdoslam" << YAML::Value << SDOSLAM_VERSION;
  resolved << YAML::Key << "opencv" << YAML::Value << CV_VERSION;
  resolved << YAML::Key << "ceres" << YAML::Value << CERES_VERSION_STRING;
  resolved << YAML::Key << "eigen" << YAML::Value
           << fmt::format("{}.{}.{}", EIGEN_WORLD_VERSION, EIGEN_MAJOR_VERSION,
                          EIGEN_MINOR_VERSION);
  if (run.mode == RunMode::kSdo) {
    for (const auto& [key, model] :
         {std::pair{"detector_model_sha256", run.front_end.detector_model},
          {"segmenter_model_sha256", run.front_end.segmenter_model},
          {"flow_model_sha256", run.front_end.flow_model}}) {
      if (!model.empty() && fs::is_regular_file(model))
        resolved << YAML::Key << key << YAML::Value << Sha256OfFile(model);
    }
  }
  resolved << YAML::EndMap;
  resolved << YAML::EndMap;
  return std::string(resolved.c_str()) + "\n";
}

}  // namespace

namespace {

// Runs `make(i)` for i = 0, 1, ... in a thread of its own, up to `capacity` items ahead of the
// caller, who takes them in order with Next(). Stopping early (Close, or destruction while
// items are queued) ends the thread cleanly; an exception in `make` reaches the caller from
// Next() after the items made before it. `nice` > 0 lowers the thread's scheduling priority
// (Linux nice value; where it cannot be set, the thread runs at the process's priority).
template <class T>
class AheadStage {
 public:
  AheadStage(size_t count, size_t capacity, std::function<T(size_t)> make, int nice = 0)
      : queue_(capacity), make_(std::move(make)) {
    thread_ = std::thread([this, count, nice] {
      if (nice != 0) {
        // Per thread: on Linux a thread id names one thread to setpriority.
        (void)setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), nice);
      }
      try {
        for (size_t i = 0; i < count; ++i) {
          if (!queue_.Push(make_(i))) return;  // closed by the consumer
        }
      } catch (...) {
        error_ = std::current_exception();
      }
      queue_.Close();
    });
  }
  ~AheadStage() {
    queue_.Close();
    if (thread_.joinable()) thread_.join();
  }
  AheadStage(const AheadStage&) = delete;
  AheadStage& operator=(const AheadStage&) = delete;
  // The next item, or nullopt at the end (every item delivered, or the stage stopped).
  // Rethrows the stage's exception once the items before it are taken.
  std::optional<T> Next() {
    std::optional<T> item = queue_.Pop();
    if (!item) {
      if (thread_.joinable()) thread_.join();
      if (error_) std::rethrow_exception(error_);
    }
    return item;
  }

 private:
  BoundedQueue<T> queue_;
  std::function<T(size_t)> make_;
  std::exception_ptr error_;  // written by the thread before it closes the queue
  std::thread thread_;
};

// A CSV file's columns: each one's name beside how a row's value is written, so that the header
// and the rows come from one list.
template <class Row>
struct CsvColumn {
  const char* name;
  std::function<std::string(const Row&)> format;
};

template <class Row>
std::string CsvHeader(const std::vector<CsvColumn<Row>>& columns) {
  std::string line;
  for (size_t k = 0; k < columns.size(); ++k) {
    if (k > 0) line += ',';
    line += columns[k].name;
  }
  line += '\n';
  return line;
}

template <class Row>
void AppendCsvRow(const std::vector<CsvColumn<Row>>& columns, const Row& row, std::string* csv) {
  for (size_t k = 0; k < columns.size(); ++k) {
    if (k > 0) *csv += ',';
    *csv += columns[k].format(row);
  }
  *csv += '\n';
}

// Column formats: a count or a name as is, milliseconds to 0.01, a flag as 0 or 1.
std::string Plain(auto value) { return fmt::format("{}", value); }
std::string Ms(double ms) { return fmt::format("{:.2f}", ms); }
std::string Flag(bool flag) { return flag ? "1" : "0"; }

// frames.csv: one row per frame.
struct FrameRow {
  size_t index;
  const FrameOutput& out;
  int dynamic_features;  // features labelled anything but static
  double objects_ms;     // the object tracker's time on the frame (run --save-objects), else 0
};

const std::vector<CsvColumn<FrameRow>>& FrameColumns() {
  using R = const FrameRow&;
  static const std::vector<CsvColumn<FrameRow>> columns = {
      {"index", [](R f) { return Plain(f.index); }},
      {"timestamp", [](R f) { return fmt::format("{:.6f}", f.out.tracking.timestamp); }},
      {"state", [](R f) { return std::string(ToString(f.out.tracking.state)); }},
      {"features", [](R f) { return Plain(f.out.tracking.features); }},
      {"features_with_depth", [](R f) { return Plain(f.out.tracking.features_with_depth); }},
      {"dynamic_features", [](R f) { return Plain(f.dynamic_features); }},
      {"matches", [](R f) { return Plain(f.out.tracking.matches); }},
      {"inliers", [](R f) { return Plain(f.out.tracking.inliers); }},
      {"keyframe", [](R f) { return Flag(f.out.tracking.keyframe); }},
      {"check_iterations", [](R f) { return Plain(f.out.tracking.check_iterations); }},
      {"check_converged", [](R f) { return Flag(f.out.tracking.check_converged); }},
      {"check_reverted", [](R f) { return Flag(f.out.tracking.check_reverted); }},
      {"check_measured", [](R f) { return Plain(f.out.tracking.check_measured); }},
      {"check_dynamic", [](R f) { return Plain(f.out.tracking.check_dynamic); }},
      {"culled_points", [](R f) { return Plain(f.out.tracking.culled_points); }},
      {"front_end_ms", [](R f) { return Ms(f.out.front_end_timing.total()); }},
      {"segment_ms", [](R f) { return Ms(f.out.front_end_timing.segment_ms); }},
      {"detect_ms", [](R f) { return Ms(f.out.front_end_timing.detect_ms); }},
      {"flow_ms", [](R f) { return Ms(f.out.front_end_timing.flow_ms); }},
      {"classify_ms", [](R f) { return Ms(f.out.front_end_timing.classify_ms); }},
      {"features_ms", [](R f) { return Ms(f.out.timing.features_ms); }},
      {"tracking_ms", [](R f) { return Ms(f.out.timing.tracking_ms); }},
      {"mapping_ms", [](R f) { return Ms(f.out.timing.mapping_ms); }},
      {"keyframes", [](R f) { return Plain(f.out.tracking.keyframes_alive); }},
      {"map_points", [](R f) { return Plain(f.out.tracking.map_points_alive); }},
      {"check_samples", [](R f) { return Plain(f.out.tracking.check_samples); }},
      {"check_rough_samples", [](R f) { return Plain(f.out.tracking.check_rough_samples); }},
      {"check_static_samples", [](R f) { return Plain(f.out.tracking.check_static_samples); }},
      {"check_replaced", [](R f) { return Flag(f.out.tracking.check_replaced); }},
      {"latency_ms", [](R f) { return Ms(f.out.latency_ms); }},
      {"lock_wait_ms", [](R f) { return Ms(f.out.timing.lock_wait_ms); }},
      {"relocalized", [](R f) { return Flag(f.out.tracking.relocalized); }},
      {"restarted", [](R f) { return Flag(f.out.tracking.restarted); }},
      {"queued_ms", [](R f) { return Ms(f.out.queued_ms); }},
      {"local_map_matches", [](R f) { return Plain(f.out.tracking.local_map_matches); }},
      {"reference_matches", [](R f) { return Plain(f.out.tracking.reference_matches); }},
      {"close_tracked", [](R f) { return Plain(f.out.tracking.close_tracked); }},
      {"close_untracked", [](R f) { return Plain(f.out.tracking.close_untracked); }},
      {"check_readmitted", [](R f) { return Plain(f.out.tracking.check_readmitted); }},
      {"objects_ms", [](R f) { return Ms(f.objects_ms); }},
  };
  return columns;
}

// mapping.csv: one row per keyframe local mapping processed.
const std::vector<CsvColumn<MappingRecord>>& MappingColumns() {
  using R = const MappingRecord&;
  static const std::vector<CsvColumn<MappingRecord>> columns = {
      {"frame_index", [](R m) { return Plain(m.frame_index); }},
      {"ms", [](R m) { return Ms(m.ms); }},
      {"insert_ms", [](R m) { return Ms(m.result.insert_ms); }},
      {"triangulate_ms", [](R m) { return Ms(m.result.triangulate_ms); }},
      {"fuse_ms", [](R m) { return Ms(m.result.fuse_ms); }},
      {"ba_ms", [](R m) { return Ms(m.result.ba_ms); }},
      {"ba_solve_ms", [](R m) { return Ms(m.result.ba_solve_ms); }},
      {"cull_ms", [](R m) { return Ms(m.result.cull_ms); }},
      {"lock_wait_ms", [](R m) { return Ms(m.result.lock_wait_ms); }},
      {"culled_points", [](R m) { return Plain(m.result.culled_points); }},
      {"triangulated_points", [](R m) { return Plain(m.result.triangulated_points); }},
      {"fused_points", [](R m) { return Plain(m.result.fused_points); }},
      {"local_keyframes", [](R m) { return Plain(m.result.local_keyframes); }},
      {"fixed_keyframes", [](R m) { return Plain(m.result.fixed_keyframes); }},
      {"local_points", [](R m) { return Plain(m.result.local_points); }},
      {"ba_observations", [](R m) { return Plain(m.result.ba.observations); }},
      {"ba_iterations", [](R m) { return Plain(m.result.ba.iterations); }},
      {"ba_stopped",
       [](R m) {
         const MappingResult& r = m.result;
         return std::string(r.ba_spaced    ? "spaced"
                            : r.ba_skipped ? "skipped"
                            : r.ba.stopped ? "stopped"
                                           : "");
       }},
      {"culled_keyframes", [](R m) { return Plain(m.result.culled_keyframes); }},
      {"freed_points", [](R m) { return Plain(m.result.freed_points); }},
      {"cpu_ms", [](R m) { return Ms(m.cpu_ms); }},
  };
  return columns;
}

// loops.csv: one row per loop closed.
const std::vector<CsvColumn<LoopRecord>>& LoopColumns() {
  using R = const LoopRecord&;
  static const std::vector<CsvColumn<LoopRecord>> columns = {
      {"frame_index", [](R l) { return Plain(l.frame_index); }},
      {"loop_frame_index", [](R l) { return Plain(l.loop_frame_index); }},
      {"matches", [](R l) { return Plain(l.matches); }},
      {"inliers", [](R l) { return Plain(l.inliers); }},
      {"projected_inliers", [](R l) { return Plain(l.projected_inliers); }},
      {"fused_points", [](R l) { return Plain(l.fused_points); }},
      {"graph_keyframes", [](R l) { return Plain(l.graph_keyframes); }},
      {"graph_edges", [](R l) { return Plain(l.graph_edges); }},
      {"correction_m", [](R l) { return fmt::format("{:.4f}", l.correction_m); }},
      {"ms", [](R l) { return Ms(l.ms); }},
      {"verify_ms", [](R l) { return Ms(l.verify_ms); }},
      {"fuse_ms", [](R l) { return Ms(l.fuse_ms); }},
      {"pose_graph_ms", [](R l) { return Ms(l.pose_graph_ms); }},
      {"points_ms", [](R l) { return Ms(l.points_ms); }},
      {"global_ba_observations", [](R l) { return Plain(l.global_ba_observations); }},
      {"global_ba_ms", [](R l) { return Ms(l.global_ba_ms); }},
      {"global_ba",
       [](R l) {
         return std::string(l.global_ba_skipped     ? "skipped"
                            : l.global_ba_discarded ? "discarded"
                            : l.global_ba_ms > 0    ? "run"
                                                    : "off");
       }},
  };
  return columns;
}

template <class Row>
std::string Csv(const std::vector<CsvColumn<Row>>& columns, const std::vector<Row>& rows) {
  std::string csv = CsvHeader(columns);
  for (const Row& row : rows) AppendCsvRow(columns, row, &csv);
  return csv;
}

// A frame as read from the dataset, with what oracle mode reads beside it.
struct LoadedFrame {
  RgbdFrame frame;
  cv::Mat oracle;
  std::chrono::steady_clock::duration reading{};  // how long reading it took
};

// A run's frames, read and prepared (the front end, the features) for tracking, in order.
// Threaded runs read one frame ahead in a thread of their own and prepare frames ahead in
// another (the front end and feature extraction of frame k + 1 overlap the tracking of frame
// k); sequential runs do both inline.
class StagedFrames {
 public:
  StagedFrames(const RunOptions& run, const RgbdDataset& dataset,
               const std::vector<std::filesystem::path>& rgb_paths, bool ahead, Pipeline* pipeline)
      : run_(run),
        dataset_(dataset),
        rgb_paths_(rgb_paths),
        pipeline_(pipeline),
        paced_from_(std::chrono::steady_clock::now()),
        frame_period_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(1.0 / run.camera.fps))) {
    if (!ahead) return;
    // Decoding the PNGs (5 ms of CPU a frame) in the preparing stage left a core idle whenever
    // tracking and mapping had nothing to do. At nice 10 the reader takes a core only when the
    // stages after it leave one free, which is when its frame is needed anyway (bench
    // --threaded, 3 alternated rounds: the mixed play's sdo 45.0-45.4 -> 47.4-49.7 fps,
    // conventional 73.5-74.9 -> 112-115; at nice 0 sdo gained half as much).
    loader_.emplace(
        rgb_paths.size(), 1, [this](size_t i) { return Load(i); }, /*nice=*/10);
    stage_.emplace(rgb_paths.size(), run.prepare_queue_capacity,
                   [this](size_t i) { return Prepare(i); });
  }
  // Frame i, the frames taken in order; nullopt only when a stage ended early.
  std::optional<StagedFrame> Next(size_t i) {
    if (stage_) return stage_->Next();
    return Prepare(i);
  }
  // Stops reading and preparing (an interrupted run).
  void Stop() {
    stage_.reset();
    loader_.reset();
  }

 private:
  // Reading frame i (colour and depth, and in oracle mode its ground-truth labels).
  // camera_rate: frame i is read no earlier than i frame periods after the first, as a camera
  // would deliver it (a sleep, not a wait in a loop).
  LoadedFrame Load(size_t i) const {
    if (run_.camera_rate)
      std::this_thread::sleep_until(paced_from_ + static_cast<int64_t>(i) * frame_period_);
    LoadedFrame loaded;
    const auto start = std::chrono::steady_clock::now();
    loaded.frame = dataset_.Load(i);
    if (run_.mode == RunMode::kOracle) {
      loaded.oracle = LoadOracleLabels(run_.dataset, rgb_paths_[i],
                                       cv::Size(run_.camera.width, run_.camera.height));
    }
    loaded.reading = std::chrono::steady_clock::now() - start;
    return loaded;
  }
  StagedFrame Prepare(size_t i) {
    std::optional<LoadedFrame> loaded;
    if (loader_) {
      loaded = loader_->Next();
      if (!loaded) throw Error("the frame reader stopped early");  // Next() throws its reason
    } else {
      loaded = Load(i);
    }
    // The latency a camera would see counts the frame's reading, but not the time a frame read
    // ahead waited for this stage: a camera's frame arrives when it is taken.
    const auto started = std::chrono::steady_clock::now() - loaded->reading;
    loaded->frame.index = i;
    StagedFrame staged = pipeline_->Prepare(std::move(loaded->frame), loaded->oracle);
    staged.started = started;
    return staged;
  }

  const RunOptions& run_;
  const RgbdDataset& dataset_;
  const std::vector<std::filesystem::path>& rgb_paths_;
  Pipeline* pipeline_;
  const std::chrono::steady_clock::time_point paced_from_;
  const std::chrono::steady_clock::duration frame_period_;
  // The stage is stopped before the reader it takes its frames from.
  std::optional<AheadStage<LoadedFrame>> loader_;
  std::optional<AheadStage<StagedFrame>> stage_;
};

// A frame `r` that did not start the map: after 30 of them with no map yet, the run ends with
// what the best of them lacked (`best_depth_features`: the most features with depth so far).
void CountNotInitialized(const RunOptions& run, const System& slam, const TrackingResult& r,
                         int* best_depth_features, RunSummary* summary) {
  *best_depth_features = std::max(*best_depth_features, r.features_with_depth);
  if (++summary->not_initialized >= 30 && slam.map().keyframes().empty()) {
    throw Error(
        fmt::format("{}: the first {} frames have too little depth to start the map (best: {} "
                    "features with depth, {} needed)",
                    run.dataset.string(), summary->not_initialized, *best_depth_features,
                    run.slam.tracking.min_initial_depth_features));
  }
}

// The trajectories, the mapping and loop records and the map's size, once SLAM has shut down.
void CollectFromSlam(const System& slam, RunSummary* summary) {
  summary->trajectory = slam.CameraTrajectory();
  summary->mapping = slam.MappingRecords();
  summary->loops = slam.LoopRecords();
  summary->keyframe_trajectory = slam.KeyFrameTrajectory();
  summary->tracked = summary->trajectory.size();
  summary->keyframes = slam.map().GoodKeyFrames();
  summary->map_points = slam.map().GoodPoints();
}

// Whether the run scores its masks: the front end's, against a synthetic sequence's ground truth.
bool EvaluatesMasks(const RunOptions& run) {
  return run.evaluate_masks && run.mode != RunMode::kConventional &&
         std::filesystem::is_directory(run.dataset / "dynamic") &&
         std::filesystem::is_directory(run.dataset / "instance");
}

// Where a run started at `run_start` stands after frame `r`.
RunProgress Progress(const RunSummary& summary, std::chrono::steady_clock::time_point run_start,
                     const TrackingResult& r) {
  return {summary.frames, summary.requested,
          std::chrono::duration<double>(std::chrono::steady_clock::now() - run_start).count(),
          r.state, r.keyframes_alive};
}

// Makes the staged files the run's result set, marked complete or interrupted.
void CommitRun(const RunOptions& run, RunSummary* run_summary, ResultSetWriter* results) {
  // The frame loop sees a stop only before a frame: one that came during the last frame, while
  // mapping finished or while the files were staged ended no loop early, yet the user asked to
  // stop and must not be told "complete" with exit 0 after seeing "interrupted" printed.
  if (run.stop_requested && run.stop_requested()) run_summary->interrupted = true;
  const RunSummary& summary = *run_summary;
  results->Commit(summary.interrupted ? "interrupted" : "complete",
                  {{"mode", ToString(run.mode)},
                   {"dataset", std::filesystem::absolute(run.dataset).lexically_normal().string()},
                   {"frames_requested", summary.requested},
                   {"frames_processed", summary.frames},
                   {"frames_tracked", summary.tracked},
                   {"sdoslam_version", SDOSLAM_VERSION}});
}

// The timings of a run's frames, for its medians.
struct RunTimings {
  std::vector<double> frame_ms, front_end_ms, total_ms, latency_ms, queued_ms;
  std::vector<double> segment_ms, detect_ms, flow_ms, classify_ms;

  void Add(const FrameOutput& out, bool has_front_end) {
    const FrontEndTiming& front = out.front_end_timing;
    if (has_front_end) {
      front_end_ms.push_back(front.total());
      segment_ms.push_back(front.segment_ms);
      detect_ms.push_back(front.detect_ms);
      flow_ms.push_back(front.flow_ms);
      classify_ms.push_back(front.classify_ms);
    }
    frame_ms.push_back(out.timing.features_ms + out.timing.tracking_ms);
    total_ms.push_back(frame_ms.back() + front.total());
    latency_ms.push_back(out.latency_ms);
    queued_ms.push_back(out.queued_ms);
  }
  // The medians into `summary` (its mapping records already there).
  void Summarize(RunSummary* summary) const {
    std::vector<double> mapping_ms;
    for (const MappingRecord& m : summary->mapping) mapping_ms.push_back(m.ms);
    summary->median_latency_ms = ComputeErrorStats(latency_ms).median;
    summary->median_queued_ms = ComputeErrorStats(queued_ms).median;
    summary->median_frame_ms = ComputeErrorStats(frame_ms).median;
    summary->median_front_end_ms = ComputeErrorStats(front_end_ms).median;
    summary->median_front_end_stages = {
        ComputeErrorStats(segment_ms).median, ComputeErrorStats(detect_ms).median,
        ComputeErrorStats(flow_ms).median, ComputeErrorStats(classify_ms).median};
    summary->median_total_ms = ComputeErrorStats(total_ms).median;
    summary->median_mapping_ms = ComputeErrorStats(mapping_ms).median;
  }
};

// Oracle mode reads each frame's ground-truth dynamic mask: all must be there before the first.
void CheckOracleMasks(const std::filesystem::path& dataset,
                      const std::vector<std::filesystem::path>& rgb_paths) {
  for (const auto& rgb : rgb_paths) {
    const auto path = dataset / "dynamic" / rgb.filename();
    if (!std::filesystem::exists(path))
      throw Error(path.string() +
                  ": oracle mode needs the ground-truth dynamic masks of a "
                  "synthetic sequence (sdoslam synth writes them)");
  }
}

// The moving objects of frame `out` (its label image), added to `objects`; returns how many.
size_t FollowObjects(const FrameOutput& out, ObjectTracker* tracker,
                     std::vector<ObjectObservation>* objects) {
  const TrackingResult& r = out.tracking;
  std::vector<ClassHint> hints;
  if (out.sdo) {
    for (const Detection& d : out.sdo->detections) hints.push_back({d.class_name, d.box});
  }
  cv::Mat gray;
  cv::cvtColor(out.input.bgr, gray, cv::COLOR_BGR2GRAY);
  std::vector<ObjectObservation> seen =
      tracker->Update(r.index, r.timestamp, gray, out.input.depth, out.labels, hints,
                      r.T_camera_world.inverse(), r.state == TrackingState::kOk);
  for (ObjectObservation& o : seen) objects->push_back(std::move(o));
  return seen.size();
}

// Each object's id (and class) written on `overlay` at its centroid.
void DrawObjectIds(const Camera& camera, const std::vector<ObjectObservation>& objects,
                   cv::Mat* overlay) {
  for (const ObjectObservation& o : objects) {
    if (o.centroid_camera.z() <= 0) continue;
    Eigen::Vector2d uv = camera.Project(o.centroid_camera);
    if (camera.HasDistortion()) uv = camera.Distort(uv);
    const cv::Point at(static_cast<int>(uv.x()), static_cast<int>(uv.y()));
    const std::string text =
        fmt::format("#{}{}", o.id, o.class_name == "unknown" ? "" : " " + o.class_name);
    cv::putText(*overlay, text, at, cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0), 3);
    cv::putText(*overlay, text, at, cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(255, 255, 255), 1);
  }
}

// Frame `index`'s overlay and mask (`name`: its image's file name), as the run asks for them;
// the mask's features go to `feature_log` (features.csv). `objects`: the frame's, labelled on the
// overlay.
void SaveFrameImages(const RunOptions& run, const ResultSetWriter& results, size_t index,
                     const std::string& name, const FrameOutput& out,
                     const std::vector<ObjectObservation>& objects, std::string* feature_log) {
  const TrackingResult& r = out.tracking;
  const cv::Mat& labels = out.labels;
  const cv::Size image_size(run.camera.width, run.camera.height);
  if (run.save_overlays &&
      (run.overlay_frames.empty() || std::find(run.overlay_frames.begin(), run.overlay_frames.end(),
                                               index) != run.overlay_frames.end())) {
    const cv::Mat empty_labels(image_size, CV_8U, cv::Scalar(0));
    cv::Mat overlay =
        DrawOverlay(out.input.bgr, labels.empty() ? empty_labels : labels,
                    out.sdo ? &*out.sdo : nullptr, r.feature_points, r.feature_labels);
    DrawObjectIds(Camera(run.camera), objects, &overlay);
    const auto path = results.Stage("overlays/" + name);
    if (!cv::imwrite(path.string(), overlay)) throw IoError(path.string() + ": cannot write");
  }
  if (run.save_masks) {
    const cv::Mat empty_labels(image_size, CV_8U, cv::Scalar(0));
    const auto path = results.Stage("masks/" + name);
    if (!cv::imwrite(path.string(), labels.empty() ? empty_labels : labels))
      throw IoError(path.string() + ": cannot write");
    for (size_t k = 0; k < r.feature_points.size(); ++k) {
      *feature_log += fmt::format("{},{:.2f},{:.2f},{}\n", index, r.feature_points[k].x,
                                  r.feature_points[k].y, r.feature_labels[k]);
    }
  }
}

// The run's files (trajectories, config, logs, the map when asked for) staged in `results`.
void WriteRunFiles(const RunOptions& run, const System& slam, const std::string& resolved_config,
                   const std::string& frames_csv, const std::string& features_csv,
                   const std::vector<ObjectObservation>& objects, ResultSetWriter& results,
                   RunSummary* summary) {
  WriteTumTrajectory(results.Stage("CameraTrajectory.txt"), summary->trajectory);
  WriteTumTrajectory(results.Stage("KeyFrameTrajectory.txt"), summary->keyframe_trajectory);
  results.WriteText("config.yaml", resolved_config);
  results.WriteText("frames.csv", frames_csv);
  results.WriteText("mapping.csv", Csv(MappingColumns(), summary->mapping));
  results.WriteText("loops.csv", Csv(LoopColumns(), summary->loops));
  if (run.save_masks) results.WriteText("features.csv", features_csv);
  if (run.save_objects) {
    // In the final trajectory's world, where local BA and loop closing left the camera.
    results.WriteText("objects.csv", ObjectsCsv(objects, summary->trajectory));
    for (const auto& [id, track] : ObjectCentroidTracks(objects, summary->trajectory))
      WriteTumTrajectory(results.Stage(fmt::format("objects/{}.txt", id)), track);
  }
  if (run.save_map) {
    const std::vector<ColoredPoint> cloud = slam.StaticMapCloud();
    summary->map_cloud_points = cloud.size();
    const auto path = results.Stage("map.ply");
    std::ofstream out(path, std::ios::binary);
    WritePly(out, cloud,
             {fmt::format("sdoslam {} static map, mode {}, world frame = first camera",
                          SDOSLAM_VERSION, ToString(run.mode))});
    out.close();
    if (!out) throw IoError(path.string() + ": cannot write");
  }
}

// ATE and RTE of the run's trajectories against the ground truth `gt`.
void Evaluate(const Trajectory& gt, RunMode mode, RunSummary* summary) {
  if (summary->trajectory.size() < 3) return;
  summary->evaluation = EvaluateEstimate(gt, summary->trajectory, ToString(mode), {});
  if (summary->keyframe_trajectory.size() >= 3) {
    summary->keyframe_evaluation =
        EvaluateEstimate(gt, summary->keyframe_trajectory, "keyframes", {});
    summary->keyframe_ate_in_frame_alignment = ComputeAteUnderAlignment(
        gt, summary->keyframe_trajectory, summary->evaluation->ate.alignment);
  }
}

// The options a run over `dataset` goes by: the dataset's camera (with intrinsics from the
// dataset where the config asks for them), and no tracking lead for a live camera, which cannot
// be made to wait for local mapping (mapping.max_tracking_lead bounds a run that reads its files
// as fast as it tracks them).
RunOptions RunOptionsFor(const RunOptions& options, const RgbdDataset& dataset) {
  RunOptions run = options;
  run.camera = dataset.camera();
  if (run.camera_rate) run.slam.mapping.max_tracking_lead = 0;
  return run;
}

}  // namespace

PipelineOptions PipelineOptionsOf(const RunOptions& run,
                                  const std::vector<std::filesystem::path>& rgb_paths,
                                  bool prepare_ahead) {
  PipelineOptions options;
  options.camera = run.camera;
  options.slam = run.slam;
  options.front_end = run.front_end;
  options.mode = run.mode;
  options.dataset_folder = run.dataset;
  options.rgb_paths = rgb_paths;
  options.extract_beside_front_end = prepare_ahead;
  return options;
}

RunSummary RunOnDataset(const RunOptions& options) {
  // An unwritable --out fails here, before anything else is read.
  ResultSetWriter results(options.out);
  DatasetOptions dataset_options;
  dataset_options.layout = options.layout;
  dataset_options.tum.associations = options.associations;
  const RgbdDataset dataset(options.dataset, options.camera, dataset_options);
  const RunOptions run = RunOptionsFor(options, dataset);
  RunSummary summary;
  summary.requested =
      run.max_frames > 0 ? std::min(dataset.size(), run.max_frames) : dataset.size();
  std::vector<std::filesystem::path> rgb_paths;
  for (size_t i = 0; i < summary.requested; ++i) rgb_paths.push_back(dataset.entries()[i].rgb_path);

  if (run.mode == RunMode::kOracle) CheckOracleMasks(run.dataset, rgb_paths);
  std::optional<MaskEvaluator> mask_evaluator;
  if (EvaluatesMasks(run)) mask_evaluator.emplace(run.dataset);

  const std::string resolved = ResolvedConfig(run);

  // Everything that can be wrong with the front end's inputs fails here, before the first frame.
  const bool prepare_ahead = run.prepare_ahead.value_or(!run.slam.sequential);
  Pipeline pipeline(PipelineOptionsOf(run, rgb_paths, prepare_ahead));
  const System& slam = pipeline.slam();
  StagedFrames frames(run, dataset, rgb_paths, prepare_ahead, &pipeline);

  std::string log = CsvHeader(FrameColumns());
  std::string feature_log = "index,x,y,label\n";
  std::optional<ObjectTracker> object_tracker;
  if (run.save_objects) object_tracker.emplace(run.camera, run.objects);
  std::vector<ObjectObservation> objects;
  RunTimings timings;
  int best_depth_features = 0;
  const auto run_start = std::chrono::steady_clock::now();
  for (size_t i = 0; i < summary.requested; ++i) {
    if (run.stop_requested && run.stop_requested()) {
      summary.interrupted = true;
      break;
    }
    std::optional<StagedFrame> staged = frames.Next(i);
    if (!staged) break;  // cannot happen unless the stage ended early, which Next() throws
    summary.frames = i + 1;
    const bool has_front_end = staged->sdo.has_value();
    const FrameOutput out = pipeline.Finish(std::move(*staged));
    const TrackingResult& r = out.tracking;
    timings.Add(out, has_front_end);
    if (r.state == TrackingState::kNotInitialized)
      CountNotInitialized(run, slam, r, &best_depth_features, &summary);
    const cv::Mat& labels = out.labels;
    summary.lost += r.state == TrackingState::kLost;
    const int dynamic_features = static_cast<int>(std::count_if(
        r.feature_labels.begin(), r.feature_labels.end(), [](uint8_t l) { return l != 0; }));
    if (r.relocalized) summary.relocalizations.push_back(i);
    if (r.restarted) {
      spdlog::warn("frame {}: lost while the map was young; the map starts again from this frame",
                   i);
    }
    if (!labels.empty() && mask_evaluator) {
      mask_evaluator->AddFrame(rgb_paths[i], labels, r.feature_points, r.feature_labels);
    }
    const auto objects_start = std::chrono::steady_clock::now();
    const size_t seen = object_tracker ? FollowObjects(out, &*object_tracker, &objects) : 0;
    const double objects_ms = object_tracker ? MsSince(objects_start) : 0.0;
    AppendCsvRow(FrameColumns(), FrameRow{i, out, dynamic_features, objects_ms}, &log);
    SaveFrameImages(run, results, i, rgb_paths[i].filename().string(), out,
                    {objects.end() - static_cast<std::ptrdiff_t>(seen), objects.end()},
                    &feature_log);
    spdlog::debug("frame {} {} inliers {} keyframe {}", i, ToString(r.state), r.inliers,
                  r.keyframe);
    if (run.after_frame) run.after_frame(r, slam);
    if (run.progress) run.progress(Progress(summary, run_start, r));
  }
  frames.Stop();               // an interrupted run stops reading and preparing frames
  pipeline.slam().Shutdown();  // the mapping thread finishes the queued keyframes
  const double run_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - run_start).count();
  summary.wall_ms_per_frame =
      summary.frames > 0 ? 1000.0 * run_seconds / static_cast<double>(summary.frames) : 0;
  CollectFromSlam(slam, &summary);
  timings.Summarize(&summary);
  if (mask_evaluator) summary.masks = mask_evaluator->result();

  WriteRunFiles(run, slam, resolved, log, feature_log, objects, results, &summary);
  CommitRun(run, &summary, &results);

  if (dataset.ground_truth()) Evaluate(*dataset.ground_truth(), run.mode, &summary);
  return summary;
}

std::string FormatRunProgress(const RunProgress& p) {
  const double fps = p.elapsed_s > 0 ? static_cast<double>(p.frames_done) / p.elapsed_s : 0.0;
  return fmt::format("frame {}/{}  {:.1f} fps  {}  {} keyframes", p.frames_done, p.frames_requested,
                     fps, ToString(p.state), p.keyframes_alive);
}

namespace {

// "loops closed: 1 (frame 1432 on frame 12, moved 0.041 m); relocalized: 2 (frames 80, 311)".
std::string FormatPlaceEvents(const RunSummary& s) {
  std::string loops, relocalized;
  for (const LoopRecord& l : s.loops) {
    loops += fmt::format("{}frame {} on frame {}, moved {:.3f} m", loops.empty() ? "" : "; ",
                         l.frame_index, l.loop_frame_index, l.correction_m);
  }
  const size_t shown = std::min<size_t>(s.relocalizations.size(), 10);
  for (size_t k = 0; k < shown; ++k) {
    relocalized += fmt::format("{}{}", k == 0 ? "" : ", ", s.relocalizations[k]);
  }
  if (shown < s.relocalizations.size()) relocalized += ", ...";
  return fmt::format("loops closed: {}{}; relocalized: {}{}\n", s.loops.size(),
                     loops.empty() ? "" : " (" + loops + ")", s.relocalizations.size(),
                     relocalized.empty() ? "" : " (frames " + relocalized + ")");
}

}  // namespace

std::string FormatRunSummary(const RunSummary& s) {
  return fmt::format(
             "{} frames: {} tracked, {} lost, {} before initialisation; {} keyframes, {} map "
             "points\n"
             "median per frame: {:.1f} ms (features + tracking); median local mapping per "
             "keyframe: "
             "{:.1f} ms{}\n"
             "throughput: {:.1f} ms per frame ({:.1f} fps, loading and every stage included); "
             "median "
             "latency {:.1f} ms{}\n",
             s.frames, s.tracked, s.lost, s.not_initialized, s.keyframes, s.map_points,
             s.median_frame_ms, s.median_mapping_ms,
             s.median_front_end_ms > 0
                 ? fmt::format("; dynamic front end {:.1f} ms per frame", s.median_front_end_ms)
                 : "",
             s.wall_ms_per_frame, s.wall_ms_per_frame > 0 ? 1000.0 / s.wall_ms_per_frame : 0.0,
             s.median_latency_ms,
             s.median_queued_ms > 0.05
                 ? fmt::format(" (and {:.1f} ms queued for tracking)", s.median_queued_ms)
                 : "") +
         FormatPlaceEvents(s);
}

}  // namespace sdoslam
