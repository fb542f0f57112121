// The Python module `sdoslam`: the Pipeline frame by frame on NumPy arrays, a dataset reader
// that decodes frames as `sdoslam run` does, and run / evaluate / synth as the commands do them.
// The API is documented in docs/python.md.

#include <fmt/format.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <mutex>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/core/error.h"
#include "sdoslam/core/logging.h"
#include "sdoslam/core/memory.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/core/timestamps.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/dataset.h"
#include "sdoslam/io/result_set.h"
#include "sdoslam/pipeline/pipeline.h"
#include "sdoslam/runner/run_on_dataset.h"
#include "sdoslam/synth/sequence.h"

namespace py = pybind11;

namespace sdoslam {
namespace {

// ---- Arrays in and out ---------------------------------------------------------------------

// "float32 of shape (480, 640)": what a caller passed, for error messages.
std::string Describe(const py::array& array) {
  std::string shape;
  for (py::ssize_t k = 0; k < array.ndim(); ++k)
    shape += fmt::format("{}{}", k > 0 ? ", " : "", array.shape(k));
  if (array.ndim() == 1) shape += ",";
  return fmt::format("{} of shape ({})", py::str(array.dtype()).cast<std::string>(), shape);
}

// `object` as a NumPy array, or ValueError naming the argument.
py::array AsArray(const py::handle& object, const char* name) {
  if (!py::isinstance<py::array>(object)) {
    throw py::value_error(fmt::format("{}: expected a NumPy array, got {}", name,
                                      py::str(py::type::of(object)).cast<std::string>()));
  }
  return py::reinterpret_borrow<py::array>(object);
}

// `array` (checked to hold T) in C order: itself, or a copy when it is a strided view.
template <class T>
py::array_t<T, py::array::c_style> Contiguous(const py::array& array) {
  auto contiguous = py::array_t<T, py::array::c_style>::ensure(array);
  if (!contiguous) throw std::bad_alloc();  // the copy failed (numpy clears its reason)
  return contiguous;
}

// A copy of `array` (checked to hold T at `shape`) into a new cv::Mat of `type`, so that the
// work after it may run without the GIL while Python code changes or frees the array.
template <class T>
cv::Mat CopyIntoMat(const py::array& array, int rows, int cols, int type) {
  const auto contiguous = Contiguous<T>(array);
  cv::Mat mat(rows, cols, type);
  std::memcpy(mat.data, contiguous.data(), mat.total() * mat.elemSize());
  return mat;
}

bool HasShape(const py::array& array, std::initializer_list<py::ssize_t> shape) {
  if (array.ndim() != static_cast<py::ssize_t>(shape.size())) return false;
  py::ssize_t k = 0;
  for (py::ssize_t extent : shape) {
    if (array.shape(k++) != extent) return false;
  }
  return true;
}

cv::Mat ColourImage(const py::handle& object, const CameraOptions& camera) {
  const py::array array = AsArray(object, "bgr");
  if (!array.dtype().equal(py::dtype::of<uint8_t>()) ||
      !HasShape(array, {camera.height, camera.width, 3})) {
    throw py::value_error(fmt::format(
        "bgr: expected uint8 of shape ({}, {}, 3) (BGR, the camera config's {}x{}), got {}",
        camera.height, camera.width, camera.width, camera.height, Describe(array)));
  }
  return CopyIntoMat<uint8_t>(array, camera.height, camera.width, CV_8UC3);
}

// Depth in metres as the runner has it from a depth PNG (io/dataset.cc, LoadRgbdFrame): values
// outside the camera's [depth_min, depth_max] are no depth (0), and so are NaN and infinities,
// which no PNG holds but a caller's conversion may.
cv::Mat DepthImage(const py::handle& object, const CameraOptions& camera) {
  const py::array array = AsArray(object, "depth_m");
  if (!array.dtype().equal(py::dtype::of<float>()) ||
      !HasShape(array, {camera.height, camera.width})) {
    std::string hint;
    if (array.dtype().kind() == 'u' || array.dtype().kind() == 'i') {
      hint = fmt::format(
          " (raw sensor units? divide by the camera's depth_factor, {:g}, and convert with "
          ".astype(numpy.float32))",
          camera.depth_factor);
    } else if (array.dtype().equal(py::dtype::of<double>())) {
      hint = " (convert with .astype(numpy.float32))";
    }
    throw py::value_error(
        fmt::format("depth_m: expected float32 metres of shape ({}, {}), got {}{}", camera.height,
                    camera.width, Describe(array), hint));
  }
  // Copied and clamped in one pass, branch-free so that it vectorises: a branch per pixel (valid
  // and missing depth alternate at random) or a bound re-read each step made it 1-1.6 ms a frame
  // instead of about 0.2.
  const auto contiguous = Contiguous<float>(array);
  cv::Mat depth(camera.height, camera.width, CV_32FC1);
  const float* from = contiguous.data();
  float* to = depth.ptr<float>();
  const size_t n = depth.total();
  const auto min = static_cast<float>(camera.depth_min);
  const auto max = static_cast<float>(camera.depth_max);
  for (size_t i = 0; i < n; ++i) {
    const float d = from[i];
    to[i] = (d >= min) & (d <= max) ? d : 0.0f;  // false for NaN
  }
  return depth;
}

cv::Mat MaskImage(const py::handle& object, const CameraOptions& camera) {
  const py::array array = AsArray(object, "dynamic_mask");
  if (!array.dtype().equal(py::dtype::of<uint8_t>()) &&
      !array.dtype().equal(py::dtype::of<bool>())) {
    throw py::value_error(
        fmt::format("dynamic_mask: expected uint8 or bool of shape ({}, {}), got {}", camera.height,
                    camera.width, Describe(array)));
  }
  if (!HasShape(array, {camera.height, camera.width})) {
    throw py::value_error(fmt::format("dynamic_mask: expected shape ({}, {}), got {}",
                                      camera.height, camera.width, Describe(array)));
  }
  // bool is one byte, 0 or 1: the same bytes as a uint8 mask.
  return CopyIntoMat<uint8_t>(array.dtype().equal(py::dtype::of<bool>())
                                  ? array.attr("view")(py::dtype::of<uint8_t>()).cast<py::array>()
                                  : array,
                              camera.height, camera.width, CV_8UC1);
}

// A NumPy array that owns `mat` (no copy): the Mat's buffer lives as long as the array. Only for
// Mats nobody else holds (a freshly decoded image).
py::array OwningArray(cv::Mat mat) {
  CV_Assert(mat.isContinuous());
  std::vector<py::ssize_t> shape = {mat.rows, mat.cols};
  if (mat.channels() > 1) shape.push_back(mat.channels());
  auto* owned = new cv::Mat(std::move(mat));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<cv::Mat*>(p); });
  const py::dtype dtype =
      owned->depth() == CV_32F ? py::dtype::of<float>() : py::dtype::of<uint8_t>();
  return py::array(dtype, shape, owned->data, free_when_done);
}

// A copy of a CV_8U image (the labels may be shared with the front end's state).
py::array CopyOfLabels(const cv::Mat& labels, const CameraOptions& camera) {
  py::array_t<uint8_t> out({camera.height, camera.width});
  if (labels.empty()) {
    std::memset(out.mutable_data(), 0, static_cast<size_t>(out.size()));
  } else {
    cv::Mat view(camera.height, camera.width, CV_8UC1, out.mutable_data());
    labels.copyTo(view);
  }
  return out;
}

py::array_t<double> PoseMatrix(const Eigen::Isometry3d& pose) {
  py::array_t<double> out({4, 4});
  auto m = out.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = pose.matrix()(r, c);
  }
  return out;
}

// N×8 rows `timestamp tx ty tz qx qy qz qw`, as WriteTumTrajectory writes them (but unrounded).
py::array_t<double> TumRows(const Trajectory& trajectory) {
  py::array_t<double> out({static_cast<py::ssize_t>(trajectory.size()), py::ssize_t{8}});
  auto rows = out.mutable_unchecked<2>();
  for (size_t i = 0; i < trajectory.size(); ++i) {
    const StampedPose& pose = trajectory[i];
    const Eigen::Quaterniond q(pose.T_world_camera.rotation());
    const Eigen::Vector3d t = pose.T_world_camera.translation();
    const double row[8] = {pose.timestamp, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w()};
    for (int k = 0; k < 8; ++k) rows(static_cast<py::ssize_t>(i), k) = row[k];
  }
  return out;
}

py::array_t<double> Points(const std::vector<Eigen::Vector3d>& points) {
  py::array_t<double> out({static_cast<py::ssize_t>(points.size()), py::ssize_t{3}});
  auto rows = out.mutable_unchecked<2>();
  for (size_t i = 0; i < points.size(); ++i) {
    for (int k = 0; k < 3; ++k) rows(static_cast<py::ssize_t>(i), k) = points[i][k];
  }
  return out;
}

// A trajectory given as N×8 TUM rows, checked as ReadTumTrajectory checks a file's lines.
Trajectory TrajectoryFromRows(const py::handle& object, const std::string& name) {
  const py::array array = AsArray(object, name.c_str());
  if (array.ndim() != 2 || array.shape(1) != 8 ||
      (array.dtype().kind() != 'f' && array.dtype().kind() != 'i' && array.dtype().kind() != 'u')) {
    throw py::value_error(
        fmt::format("{}: expected N×8 numbers (timestamp tx ty tz qx qy qz qw per row), got {}",
                    name, Describe(array)));
  }
  const auto rows = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  if (!rows) throw std::bad_alloc();
  const auto v = rows.unchecked<2>();
  static const TrajectoryReadOptions kLimits;
  Trajectory trajectory;
  for (py::ssize_t i = 0; i < v.shape(0); ++i) {
    const std::string where = fmt::format("{}: row {}: ", name, i);
    for (int k = 0; k < 8; ++k) {
      if (!std::isfinite(v(i, k))) throw py::value_error(where + "not a finite number");
    }
    if (std::abs(v(i, 0)) > kMaxAbsTimestamp)
      throw py::value_error(where + fmt::format("timestamp {:g} is not in seconds", v(i, 0)));
    const double values[8] = {v(i, 0), v(i, 1), v(i, 2), v(i, 3),
                              v(i, 4), v(i, 5), v(i, 6), v(i, 7)};
    try {
      AppendTumPose(values, kLimits, "row", &trajectory);
    } catch (const Error& e) {
      throw py::value_error(where + e.what());
    }
  }
  if (trajectory.empty()) throw py::value_error(name + ": no poses in this trajectory");
  return trajectory;
}

// nlohmann::json (the eval report's JSON) as Python objects.
py::object FromJson(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::null:
      return py::none();
    case nlohmann::json::value_t::boolean:
      return py::bool_(j.get<bool>());
    case nlohmann::json::value_t::number_integer:
      return py::int_(j.get<int64_t>());
    case nlohmann::json::value_t::number_unsigned:
      return py::int_(j.get<uint64_t>());
    case nlohmann::json::value_t::number_float:
      return py::float_(j.get<double>());
    case nlohmann::json::value_t::string:
      return py::str(j.get<std::string>());
    case nlohmann::json::value_t::array: {
      py::list list;
      for (const auto& item : j) list.append(FromJson(item));
      return list;
    }
    case nlohmann::json::value_t::object: {
      py::dict dict;
      for (const auto& [key, value] : j.items()) dict[py::str(key)] = FromJson(value);
      return dict;
    }
    default:
      return py::none();
  }
}

// One estimate's evaluation as a dict: the keys `sdoslam eval --json` writes for it, the
// evaluation's settings under "settings", and the matched poses as arrays (for plots).
py::dict EvaluationDict(const EstimateEvaluation& e, const EvaluationOptions& options) {
  nlohmann::json j = ToJson({e}, options);
  py::dict out = FromJson(j["estimates"][0]).cast<py::dict>();
  j.erase("estimates");
  out["settings"] = FromJson(j);
  py::dict matched;
  matched["timestamps"] = py::array_t<double>(static_cast<py::ssize_t>(e.ate.timestamps.size()),
                                              e.ate.timestamps.data());
  matched["ground_truth"] = Points(e.ate.ground_truth);
  matched["estimate_aligned"] = Points(e.ate.estimate_aligned);
  matched["errors"] =
      py::array_t<double>(static_cast<py::ssize_t>(e.ate.errors.size()), e.ate.errors.data());
  out["matched"] = matched;
  return out;
}

py::dict CameraDict(const CameraOptions& c) {
  py::dict d;
  d["name"] = c.name;
  d["width"] = c.width;
  d["height"] = c.height;
  d["fx"] = c.fx;
  d["fy"] = c.fy;
  d["cx"] = c.cx;
  d["cy"] = c.cy;
  d["distortion"] = py::make_tuple(c.k1, c.k2, c.p1, c.p2, c.k3);
  d["fps"] = c.fps;
  d["depth_factor"] = c.depth_factor;
  d["depth_min"] = c.depth_min;
  d["depth_max"] = c.depth_max;
  d["readout_s"] = c.readout_s;
  return d;
}

// ---- Pipeline --------------------------------------------------------------------------------

// sdoslam::Pipeline for Python: frames are copied in, tracked without the GIL, and their result
// handed back as a dict. One frame at a time: a second Python thread waits for the first.
class PyPipeline {
 public:
  PyPipeline(const std::filesystem::path& config, const std::optional<std::string>& mode,
             bool sequential) {
    RunOptions run = LoadRunConfig(config);
    if (mode) run.mode = ParseRunMode(*mode);
    if (run.camera.from_dataset) {
      throw Error(config.string() +
                  ": camera.from_dataset: a Pipeline has no dataset to take the intrinsics from; "
                  "give width, height, fx, fy, cx, cy in the camera: section");
    }
    // As `sdoslam run`: --sequential or the config's run.sequential; threaded, feature
    // extraction beside the front end, on the other core.
    run.slam.sequential = run.slam.sequential || sequential;
    const PipelineOptions options =
        PipelineOptionsOf(run, /*rgb_paths=*/{}, /*prepare_ahead=*/!run.slam.sequential);
    py::gil_scoped_release release;  // the vocabulary and the front end's models load here
    pipeline_ = std::make_unique<Pipeline>(options);
  }

  py::dict Track(const py::object& bgr, const py::object& depth_m, double timestamp,
                 const py::object& dynamic_mask) {
    const CameraOptions& camera = pipeline_->options().camera;
    if (!std::isfinite(timestamp)) throw py::value_error("timestamp: not a finite number");
    RgbdFrame frame;
    frame.timestamp = timestamp;
    frame.bgr = ColourImage(bgr, camera);
    frame.depth = DepthImage(depth_m, camera);
    const cv::Mat mask = dynamic_mask.is_none() ? cv::Mat() : MaskImage(dynamic_mask, camera);
    FrameOutput out;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      CheckRunning("track");
      frame.index = frames_;
      out = pipeline_->Track(std::move(frame), mask);
      ++frames_;
    }
    const TrackingResult& r = out.tracking;
    py::dict result;
    result["pose"] = r.state == TrackingState::kOk
                         ? py::object(PoseMatrix(r.T_camera_world.inverse()))
                         : py::object(py::none());
    result["state"] = ToString(r.state);
    result["labels"] = CopyOfLabels(out.labels, camera);
    result["keyframes"] = r.keyframes_alive;
    result["index"] = r.index;
    result["timestamp"] = r.timestamp;
    result["keyframe"] = r.keyframe;
    result["map_points"] = r.map_points_alive;
    result["features"] = r.features;
    result["inliers"] = r.inliers;
    py::dict timing;
    timing["front_end_ms"] = out.front_end_timing.total();
    timing["features_ms"] = out.timing.features_ms;
    timing["tracking_ms"] = out.timing.tracking_ms;
    timing["mapping_ms"] = out.timing.mapping_ms;
    timing["total_ms"] = out.latency_ms;  // the whole of Pipeline::Track
    result["timing"] = timing;
    return result;
  }

  py::array_t<double> MapPoints(int min_observations) {
    if (min_observations < 1) throw py::value_error("min_observations must be >= 1");
    std::vector<ColoredPoint> cloud;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      cloud = pipeline_->slam().StaticMapCloud(min_observations);
    }
    std::vector<Eigen::Vector3d> positions;
    positions.reserve(cloud.size());
    for (const ColoredPoint& p : cloud) positions.push_back(p.position.cast<double>());
    return Points(positions);
  }

  py::array_t<double> CameraTrajectory() {
    return TrajectoryRows([](const System& slam) { return slam.CameraTrajectory(); });
  }
  py::array_t<double> KeyFrameTrajectory() {
    return TrajectoryRows([](const System& slam) { return slam.KeyFrameTrajectory(); });
  }

  // The trajectory `read` takes from the system, as TUM rows: read under the lock, without the
  // GIL (the mapping thread may hold the map).
  template <class Read>
  py::array_t<double> TrajectoryRows(Read read) {
    Trajectory trajectory;
    {
      py::gil_scoped_release release;
      std::lock_guard<std::mutex> lock(mutex_);
      trajectory = read(pipeline_->slam());
    }
    return TumRows(trajectory);
  }

  // Lets the mapping thread finish its queued keyframes and stops it (System::Shutdown).
  void Shutdown() {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(mutex_);
    pipeline_->slam().Shutdown();
    shut_down_ = true;
  }

  size_t frames() const { return frames_; }
  bool sequential() const { return pipeline_->options().slam.sequential; }
  std::string mode() const { return ToString(pipeline_->options().mode); }
  py::dict camera() const { return CameraDict(pipeline_->options().camera); }

 private:
  void CheckRunning(const char* what) const {
    if (shut_down_) throw Error(fmt::format("Pipeline.{}: the pipeline was shut down", what));
  }

  std::mutex mutex_;  // one call into the pipeline at a time
  std::unique_ptr<Pipeline> pipeline_;
  size_t frames_ = 0;  // tracked so far: the next frame's index
  bool shut_down_ = false;
};

// ---- Dataset ---------------------------------------------------------------------------------

// A sequence folder read as `sdoslam run` reads it (RgbdDataset), frame by frame.
class PyDataset {
 public:
  PyDataset(const std::filesystem::path& folder, const std::filesystem::path& config,
            const std::string& layout, const std::optional<std::filesystem::path>& associations) {
    const RunOptions run = LoadRunConfig(config);
    DatasetOptions options;
    options.layout = ParseDatasetLayout(layout);
    if (associations) options.tum.associations = *associations;
    py::gil_scoped_release release;
    dataset_ = std::make_unique<RgbdDataset>(folder, run.camera, options);
  }

  size_t size() const { return dataset_->size(); }

  // (bgr, depth_m, timestamp) of frame `index` (negative: from the end).
  py::tuple Frame(py::ssize_t index) const {
    const auto count = static_cast<py::ssize_t>(dataset_->size());
    if (index < 0) index += count;
    if (index < 0 || index >= count)
      throw py::index_error(fmt::format("frame index out of range (0..{})", count - 1));
    RgbdFrame frame;
    {
      py::gil_scoped_release release;  // decoding two PNGs
      frame = dataset_->Load(static_cast<size_t>(index));
    }
    return py::make_tuple(OwningArray(std::move(frame.bgr)), OwningArray(std::move(frame.depth)),
                          frame.timestamp);
  }

  py::array_t<double> Timestamps() const {
    py::array_t<double> out(static_cast<py::ssize_t>(dataset_->size()));
    auto t = out.mutable_unchecked<1>();
    for (size_t i = 0; i < dataset_->size(); ++i)
      t(static_cast<py::ssize_t>(i)) = dataset_->entries()[i].timestamp;
    return out;
  }

  py::object GroundTruth() const {
    if (!dataset_->ground_truth()) return py::none();
    return TumRows(*dataset_->ground_truth());
  }

  py::dict camera() const { return CameraDict(dataset_->camera()); }
  std::string layout() const { return ToString(dataset_->layout()); }
  std::filesystem::path folder() const { return dataset_->folder(); }

 private:
  std::unique_ptr<RgbdDataset> dataset_;
};

// ---- run, evaluate, synth --------------------------------------------------------------------

py::dict SummaryDict(const RunSummary& s, const RunOptions& run) {
  py::dict d;
  d["out"] = run.out.string();
  d["mode"] = ToString(run.mode);
  d["sequential"] = run.slam.sequential;
  d["frames"] = s.frames;
  d["requested"] = s.requested;
  d["interrupted"] = s.interrupted;
  d["tracked"] = s.tracked;
  d["lost"] = s.lost;
  d["not_initialized"] = s.not_initialized;
  d["keyframes"] = s.keyframes;
  d["map_points"] = s.map_points;
  d["map_cloud_points"] = s.map_cloud_points;
  d["median_frame_ms"] = s.median_frame_ms;
  d["median_front_end_ms"] = s.median_front_end_ms;
  d["median_total_ms"] = s.median_total_ms;
  d["median_mapping_ms"] = s.median_mapping_ms;
  d["wall_ms_per_frame"] = s.wall_ms_per_frame;
  d["median_latency_ms"] = s.median_latency_ms;
  d["median_queued_ms"] = s.median_queued_ms;
  py::list loops;
  for (const LoopRecord& l : s.loops) {
    py::dict loop;
    loop["frame_index"] = l.frame_index;
    loop["loop_frame_index"] = l.loop_frame_index;
    loop["correction_m"] = l.correction_m;
    loops.append(loop);
  }
  d["loops"] = loops;
  d["relocalizations"] = s.relocalizations;
  d["trajectory"] = TumRows(s.trajectory);
  d["keyframe_trajectory"] = TumRows(s.keyframe_trajectory);
  const EvaluationOptions defaults;  // what the run evaluates with
  d["evaluation"] =
      s.evaluation ? py::object(EvaluationDict(*s.evaluation, defaults)) : py::object(py::none());
  d["keyframe_evaluation"] = s.keyframe_evaluation
                                 ? py::object(EvaluationDict(*s.keyframe_evaluation, defaults))
                                 : py::object(py::none());
  d["text"] = FormatRunSummary(s);
  return d;
}

// `sdoslam run`, its options as keyword arguments; None keeps the config's.
py::dict Run(const std::optional<std::filesystem::path>& dataset,
             const std::filesystem::path& config, const std::filesystem::path& out,
             const std::optional<std::string>& mode, bool sequential,
             const std::optional<size_t>& max_frames, const std::optional<std::string>& layout,
             const std::optional<std::filesystem::path>& associations, bool save_overlays,
             bool save_masks, bool save_map, bool save_objects, bool camera_rate) {
  RunOptions run = LoadRunConfig(config);
  if (mode) run.mode = ParseRunMode(*mode);
  // The arguments win over a config's run: section (a run's own config.yaml has one).
  if (dataset) run.dataset = *dataset;
  if (run.dataset.empty())
    throw py::value_error(
        "dataset is required (or a config with run.dataset, as a run's "
        "config.yaml)");
  if (layout) run.layout = ParseDatasetLayout(*layout);
  if (associations) run.associations = *associations;
  if (max_frames) run.max_frames = *max_frames;
  run.slam.sequential = run.slam.sequential || sequential;
  run.save_overlays = run.save_overlays || save_overlays;
  run.save_masks = run.save_masks || save_masks;
  run.save_map = run.save_map || save_map;
  run.save_objects = run.save_objects || save_objects;
  run.camera_rate = run.camera_rate || camera_rate;
  run.out = out;
  // Ctrl-C stops the run as SIGINT stops `sdoslam run`: the frames so far are written, marked
  // interrupted, and KeyboardInterrupt is raised after.
  bool stop = false;
  run.stop_requested = [&stop] {
    if (!stop) {
      py::gil_scoped_acquire acquire;
      stop = PyErr_CheckSignals() != 0;
    }
    return stop;
  };
  RunSummary summary;
  {
    py::gil_scoped_release release;
    summary = RunOnDataset(run);
  }
  if (stop) throw py::error_already_set();
  return SummaryDict(summary, run);
}

// A trajectory argument of evaluate: a TUM file (checked as `sdoslam eval` checks it) or rows.
Trajectory TrajectoryArgument(const py::handle& argument, const std::string& name) {
  if (py::isinstance<py::array>(argument)) return TrajectoryFromRows(argument, name);
  const std::filesystem::path path = argument.cast<std::filesystem::path>();
  RejectNonRegularFile(path);  // before its manifest is consulted, which would hash it
  // A file of an sdoslam result set must match its manifest (not a half-replaced set).
  if (const auto manifest = VerifyResultFile(path); manifest && manifest->status != "complete") {
    std::cerr << fmt::format("note: {} is from an interrupted run ({} of {} frames)\n",
                             path.string(), manifest->info.value("frames_processed", size_t{0}),
                             manifest->info.value("frames_requested", size_t{0}));
  }
  Trajectory t = ReadTumTrajectory(path);
  if (t.empty()) throw Error(path.string() + ": no poses in this trajectory file");
  return t;
}

py::dict Evaluate(const py::object& gt, const py::object& est, const std::string& align,
                  double max_time_diff, double offset, double delta, const std::string& delta_unit,
                  const std::string& rte_pairing, const std::optional<std::string>& label) {
  EvaluationOptions options;
  options.ate.alignment = ParseAlignmentMode(align);
  options.ate.max_time_difference = max_time_diff;
  options.ate.time_offset = offset;
  options.rte.delta = delta;
  options.rte.unit = ParseDeltaUnit(delta_unit);
  options.rte.pairing = ParseRtePairing(rte_pairing);
  options.Check();
  const Trajectory ground_truth = TrajectoryArgument(gt, "gt");
  const Trajectory estimate = TrajectoryArgument(est, "est");
  const bool est_is_file = !py::isinstance<py::array>(est);
  const std::string name =
      label ? *label
            : (est_is_file ? est.cast<std::filesystem::path>().stem().string() : "estimate");
  EstimateEvaluation evaluation;
  {
    py::gil_scoped_release release;
    try {
      evaluation = EvaluateEstimate(ground_truth, estimate, name, options);
    } catch (const Error& e) {
      // As `sdoslam eval`: the estimate's file in front of what is wrong with it.
      if (!est_is_file) throw;
      throw Error(fmt::format("{}: {}", name, e.what()));
    }
  }
  return EvaluationDict(evaluation, options);
}

py::dict Synth(const std::filesystem::path& out, const std::string& scenario, int frames,
               uint32_t seed, bool noise, const std::optional<std::string>& motion, int motion_blur,
               int supersample, bool exposure_changes, double depth_factor, bool overwrite) {
  synth::SynthOptions options;
  options.scenario = scenario;
  if (motion) options.motion = synth::ParseCameraMotion(*motion);
  options.frames = frames;
  options.seed = seed;
  options.sensor.enabled = noise;
  options.sensor.motion_blur_samples = motion_blur;
  options.sensor.supersampling = supersample;
  options.sensor.exposure_changes = exposure_changes;
  options.depth_factor = depth_factor;
  synth::SequenceSummary s;
  {
    py::gil_scoped_release release;
    s = synth::WriteSequence(options, out, overwrite);
  }
  py::dict d;
  d["out"] = out.string();
  d["frames"] = s.frames;
  d["render_seconds"] = s.render_seconds;
  d["total_seconds"] = s.total_seconds;
  d["dynamic_fraction_mean"] = s.dynamic_fraction_mean;
  d["dynamic_fraction_max"] = s.dynamic_fraction_max;
  return d;
}

}  // namespace
}  // namespace sdoslam

PYBIND11_MODULE(sdoslam, m) {
  using namespace sdoslam;
  using py::arg;
  m.doc() =
      "sdoslam: RGB-D visual SLAM for scenes that move. Pipeline tracks NumPy frames; Dataset "
      "reads a sequence folder as `sdoslam run` does; run, evaluate and synth do what the "
      "commands of the same name do. docs/python.md has the details.";
  m.attr("__version__") = SDOSLAM_VERSION;

  // As `sdoslam` does first thing (core/memory.h): every frame allocates and frees images of a
  // few MB, which glibc would otherwise hand back to the kernel and fault in again each frame.
  KeepImageBuffersForReuse();

  // sdoslam::Error (bad input: files, options) → sdoslam.Error, a RuntimeError; IoError (results
  // cannot be written) → sdoslam.IoError, an sdoslam.Error. Registered in this order because
  // pybind11 tries the translator registered last first.
  // sdoslam::Error (bad input: files, options) → sdoslam.Error, a RuntimeError; IoError (results
  // cannot be written) → sdoslam.IoError, an sdoslam.Error. pybind11 tries the translator
  // registered last first, so IoError is caught before Error catches it.
  const py::exception<Error>& error = py::register_exception<Error>(m, "Error", PyExc_RuntimeError);
  py::register_exception<IoError>(m, "IoError", error);
  // The file system refused something (permissions, space): its message names the path.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const std::filesystem::filesystem_error& e) {
      PyErr_SetString(PyExc_OSError, e.what());
    }
  });

  py::class_<PyPipeline>(m, "Pipeline",
                         "The dynamic front end and SLAM for one camera, one frame at a time.")
      .def(py::init<const std::filesystem::path&, const std::optional<std::string>&, bool>(),
           arg("config"), arg("mode") = "sdo", arg("sequential") = false,
           "config: a run config (camera: section, optional SLAM and dynamic: sections). mode: "
           "'sdo', 'conventional' or 'oracle'; None takes the config's mode:. sequential: local "
           "mapping inline after each keyframe (deterministic); False maps in a thread beside "
           "tracking, as `sdoslam run` does without --sequential.")
      .def("track", &PyPipeline::Track, arg("bgr"), arg("depth_m"), arg("timestamp"),
           arg("dynamic_mask") = py::none(),
           "Tracks one frame: bgr uint8 H×W×3, depth_m float32 H×W in metres (0: none), "
           "timestamp in seconds. Returns a dict: pose (4×4 T_world_camera, or None when not "
           "tracked), state, labels (H×W uint8), keyframes, index, timestamp, keyframe, "
           "map_points, features, inliers, timing.")
      .def("map_points", &PyPipeline::MapPoints, arg("min_observations") = 2,
           "The static map's points seen by at least min_observations keyframes, N×3 float64 in "
           "the world frame (the first camera's), as map.ply has them.")
      .def("trajectory", &PyPipeline::CameraTrajectory,
           "Every tracked frame's pose after mapping's refinement, N×8 rows of timestamp tx ty "
           "tz qx qy qz qw (T_world_camera), as CameraTrajectory.txt. Threaded: call shutdown() "
           "first for the final one.")
      .def("keyframe_trajectory", &PyPipeline::KeyFrameTrajectory,
           "The keyframes alive, N×8 rows as trajectory() (KeyFrameTrajectory.txt).")
      .def("shutdown", &PyPipeline::Shutdown,
           "Lets mapping finish its queued keyframes and stops its thread; track() refuses "
           "frames after it. Idempotent.")
      .def("__enter__", [](py::object self) { return self; })
      .def("__exit__", [](PyPipeline& self, const py::object&, const py::object&,
                          const py::object&) { self.Shutdown(); })
      .def_property_readonly("frames", &PyPipeline::frames, "frames tracked so far")
      .def_property_readonly("mode", &PyPipeline::mode)
      .def_property_readonly("sequential", &PyPipeline::sequential)
      .def_property_readonly("camera", &PyPipeline::camera, "the camera's settings, a dict");

  py::class_<PyDataset>(m, "Dataset",
                        "A sequence folder (TUM, Bonn, OMD, sdoslam synth) read as `sdoslam run` "
                        "reads it: dataset[i] is (bgr, depth_m, timestamp).")
      .def(py::init<const std::filesystem::path&, const std::filesystem::path&, const std::string&,
                    const std::optional<std::filesystem::path>&>(),
           arg("folder"), arg("config"), arg("layout") = "auto", arg("associations") = py::none(),
           "config: the run config whose camera: section gives the depth scale and range (and "
           "the image size the frames must have).")
      .def("__len__", &PyDataset::size)
      .def("__getitem__", &PyDataset::Frame, arg("index"))
      .def_property_readonly("timestamps", &PyDataset::Timestamps)
      .def_property_readonly("ground_truth", &PyDataset::GroundTruth,
                             "N×8 TUM rows of the camera's ground truth, or None")
      .def_property_readonly("camera", &PyDataset::camera)
      .def_property_readonly("layout", &PyDataset::layout)
      .def_property_readonly("folder", &PyDataset::folder);

  m.def("run", &Run, py::kw_only(), arg("dataset") = py::none(), arg("config"), arg("out"),
        arg("mode") = py::none(), arg("sequential") = false, arg("max_frames") = py::none(),
        arg("layout") = py::none(), arg("associations") = py::none(), arg("save_overlays") = false,
        arg("save_masks") = false, arg("save_map") = false, arg("save_objects") = false,
        arg("camera_rate") = false,
        "`sdoslam run`: SLAM over a sequence, its result set written to out. Returns the run's "
        "summary as a dict.");
  m.def("evaluate", &Evaluate, arg("gt"), arg("est"), py::kw_only(), arg("align") = "se3",
        arg("max_time_diff") = 0.02, arg("offset") = 0.0, arg("delta") = 1.0,
        arg("delta_unit") = "s", arg("rte_pairing") = "tum", arg("label") = py::none(),
        "`sdoslam eval`: ATE and RTE of est against gt, each a TUM file or N×8 rows. Returns "
        "the numbers `sdoslam eval --json` writes for the estimate, as a dict.");
  m.def("synth", &Synth, py::kw_only(), arg("out"), arg("scenario") = "walking_xyz",
        arg("frames") = 300, arg("seed") = 1, arg("noise") = true, arg("motion") = py::none(),
        arg("motion_blur") = 0, arg("supersample") = 1, arg("exposure_changes") = false,
        arg("depth_factor") = 5000.0, arg("overwrite") = false,
        "`sdoslam synth`: renders a synthetic sequence with ground truth into out.");
  m.def("set_log_level", &SetLogLevel, arg("level"),
        "The library's log level: trace, debug, info, warn, error, critical, off.");
}
