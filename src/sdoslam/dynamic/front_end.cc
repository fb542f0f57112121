#include "sdoslam/dynamic/front_end.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/core/stopwatch.h"

namespace sdoslam {
namespace {

const std::vector<std::string> kSegmenters = {"rgbd", "geometric", "onnx-yoloseg", "file"};
const std::vector<std::string> kDetectors = {"nanodet", "fastestdet", "yolov8",
                                             "hog",     "file",       "none"};
const std::vector<std::string> kFlows = {"dis", "farneback", "onnx"};

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

void CheckName(const std::string& kind, const std::string& name,
               const std::vector<std::string>& known) {
  if (std::find(known.begin(), known.end(), name) == known.end())
    throw Error(fmt::format("unknown {} backend '{}' (known: {})", kind, name, Join(known)));
}

std::filesystem::path Resolve(const std::filesystem::path& p, const std::filesystem::path& base) {
  return p.is_relative() ? base / p : p;
}

// Boxes follow the mean flow inside them on frames without detection.
void ShiftByFlow(const cv::Mat& flow, cv::Size image, std::vector<Detection>* detections) {
  if (flow.empty()) return;
  const double s = static_cast<double>(flow.cols) / image.width;
  for (Detection& d : *detections) {
    const cv::Rect r = cv::Rect(static_cast<int>(d.box.x * s), static_cast<int>(d.box.y * s),
                                std::max(1, static_cast<int>(d.box.width * s)),
                                std::max(1, static_cast<int>(d.box.height * s))) &
                       cv::Rect(0, 0, flow.cols, flow.rows);
    if (r.area() <= 0) continue;
    const cv::Scalar mean = cv::mean(flow(r));
    d.box.x += static_cast<float>(mean[0] / s);
    d.box.y += static_cast<float>(mean[1] / s);
  }
}

}  // namespace

void FrontEndOptions::Check() const {
  CheckName("segmenter", segmenter, kSegmenters);
  CheckName("detector", detector, kDetectors);
  CheckName("flow", flow, kFlows);
  if (detect_every < 1) throw Error("detector.every must be at least 1");
  rgbd.Check();
  geometric.Check();
  yoloseg.Check();
  detection.Check();
  hog.Check();
  flow_options.Check();
  boundaries.Check();
  classifier.Check();
  if (segmenter == "onnx-yoloseg" && segmenter_model.empty())
    throw Error("segmenter 'onnx-yoloseg' needs segmenter.model (an ONNX file)");
  if (segmenter == "file" && masks_folder.empty())
    throw Error("segmenter 'file' needs segmenter.folder (instance-mask PNGs)");
  if ((detector == "nanodet" || detector == "fastestdet" || detector == "yolov8") &&
      detector_model.empty())
    throw Error("detector '" + detector + "' needs detector.model (an ONNX file)");
  if (detector == "file" && detections_file.empty())
    throw Error("detector 'file' needs detector.file (a detections JSON)");
  if (flow == "onnx" && flow_model.empty()) throw Error("flow 'onnx' needs flow.model");
}

FrontEndOptions ReadFrontEndOptions(ConfigMap& root) {
  FrontEndOptions o;
  auto section = root.Section("dynamic");
  if (!section) return o;
  std::string path;
  if (auto s = section->Section("segmenter")) {
    s->Read("backend", &o.segmenter);
    if (path.clear(), s->Read("model", &path), !path.empty()) o.segmenter_model = path;
    if (path.clear(), s->Read("folder", &path), !path.empty()) o.masks_folder = path;
    s->Read("work_width", &o.rgbd.work_width);
    s->Read("sigma", &o.rgbd.sigma);
    s->Read("k", &o.rgbd.k);
    s->Read("min_size", &o.rgbd.min_size);
    s->Read("colour_weight", &o.rgbd.colour_weight);
    s->Read("depth_weight", &o.rgbd.depth_weight);
    s->Read("score_threshold", &o.yoloseg.score_threshold);
    s->Read("nms_iou", &o.yoloseg.nms_iou);
    s->Read("mask_threshold", &o.yoloseg.mask_threshold);
    s->Read("max_instances", &o.yoloseg.max_instances);
    if (auto g = s->Section("geometric")) {
      GeometricSegmenterOptions::VisitFields(
          o.geometric, [&](const char* key, auto& value) { g->Read(key, &value); });
      g->RejectUnknownKeys();
    }
    s->RejectUnknownKeys();
  }
  if (auto s = section->Section("detector")) {
    s->Read("backend", &o.detector);
    if (path.clear(), s->Read("model", &path), !path.empty()) o.detector_model = path;
    if (path.clear(), s->Read("file", &path), !path.empty()) o.detections_file = path;
    s->Read("every", &o.detect_every);
    s->Read("score_threshold", &o.detection.score_threshold);
    s->Read("nms_iou", &o.detection.nms_iou);
    s->Read("hog_work_width", &o.hog.work_width);
    s->Read("hog_hit_threshold", &o.hog.hit_threshold);
    s->RejectUnknownKeys();
  }
  if (auto s = section->Section("flow")) {
    s->Read("backend", &o.flow);
    if (path.clear(), s->Read("model", &path), !path.empty()) o.flow_model = path;
    s->Read("work_width", &o.flow_options.work_width);
    s->Read("dis_preset", &o.flow_options.dis_preset);
    s->Read("frame_gap", &o.flow_options.frame_gap);
    s->ReadList("onnx_input_names", &o.flow_options.onnx_input_names);
    s->RejectUnknownKeys();
  }
  if (auto s = section->Section("boundaries")) {
    s->Read("k_magnitude", &o.boundaries.k_magnitude);
    s->Read("k_orientation", &o.boundaries.k_orientation);
    s->Read("strong", &o.boundaries.strong);
    s->Read("threshold", &o.boundaries.threshold);
    s->Read("min_flow_for_angle", &o.boundaries.min_flow_for_angle);
    s->RejectUnknownKeys();
  }
  if (auto s = section->Section("classifier")) {
    SdoClassifierOptions& c = o.classifier;
    s->ReadList("movable_classes", &c.movable_classes);
    s->Read("work_width", &c.work_width);
    s->Read("min_box_iou", &c.min_box_iou);
    s->Read("min_inside_box", &c.min_inside_box);
    s->Read("same_depth_tolerance", &c.same_depth_tolerance);
    s->Read("same_depth_min_m", &c.same_depth_min_m);
    s->Read("boundary_band_px", &c.boundary_band_px);
    s->Read("min_outline_on_boundary", &c.min_outline_on_boundary);
    s->Read("min_in_front", &c.min_in_front);
    s->Read("min_in_front_of_outline", &c.min_in_front_of_outline);
    s->Read("in_front_ratio", &c.in_front_ratio);
    s->Read("max_segment_area", &c.max_segment_area);
    s->Read("persistence_frames", &c.persistence_frames);
    s->Read("persistence_overlap", &c.persistence_overlap);
    s->Read("persistence_large_overlap", &c.persistence_large_overlap);
    s->Read("persistence_min_in_front", &c.persistence_min_in_front);
    s->Read("persistence_min_ordered", &c.persistence_min_ordered);
    s->Read("margin_px", &c.margin_px);
    s->RejectUnknownKeys();
  }
  section->RejectUnknownKeys();
  try {
    o.Check();
  } catch (const Error& e) {
    throw Error(root.origin() + ": dynamic: " + e.what());
  }
  return o;
}

void WriteFrontEndOptions(const FrontEndOptions& o, YAML::Emitter* out) {
  YAML::Emitter& y = *out;
  auto kv = [&](const char* key, const auto& value) {
    y << YAML::Key << key << YAML::Value << value;
  };
  y << YAML::Key << "dynamic" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "segmenter" << YAML::Value << YAML::BeginMap;
  kv("backend", o.segmenter);
  if (!o.segmenter_model.empty()) kv("model", o.segmenter_model.string());
  if (!o.masks_folder.empty()) kv("folder", o.masks_folder.string());
  kv("work_width", o.rgbd.work_width);
  kv("sigma", o.rgbd.sigma);
  kv("k", o.rgbd.k);
  kv("min_size", o.rgbd.min_size);
  kv("colour_weight", o.rgbd.colour_weight);
  kv("depth_weight", o.rgbd.depth_weight);
  kv("score_threshold", o.yoloseg.score_threshold);
  kv("nms_iou", o.yoloseg.nms_iou);
  kv("mask_threshold", o.yoloseg.mask_threshold);
  kv("max_instances", o.yoloseg.max_instances);
  y << YAML::Key << "geometric" << YAML::Value << YAML::BeginMap;
  GeometricSegmenterOptions::VisitFields(o.geometric, kv);
  y << YAML::EndMap;
  y << YAML::EndMap;
  y << YAML::Key << "detector" << YAML::Value << YAML::BeginMap;
  kv("backend", o.detector);
  if (!o.detector_model.empty()) kv("model", o.detector_model.string());
  if (!o.detections_file.empty()) kv("file", o.detections_file.string());
  kv("every", o.detect_every);
  kv("score_threshold", o.detection.score_threshold);
  kv("nms_iou", o.detection.nms_iou);
  kv("hog_work_width", o.hog.work_width);
  kv("hog_hit_threshold", o.hog.hit_threshold);
  y << YAML::EndMap;
  y << YAML::Key << "flow" << YAML::Value << YAML::BeginMap;
  kv("backend", o.flow);
  if (!o.flow_model.empty()) kv("model", o.flow_model.string());
  kv("work_width", o.flow_options.work_width);
  kv("dis_preset", o.flow_options.dis_preset);
  kv("frame_gap", o.flow_options.frame_gap);
  if (!o.flow_options.onnx_input_names.empty())
    y << YAML::Key << "onnx_input_names" << YAML::Value << YAML::Flow
      << o.flow_options.onnx_input_names;
  y << YAML::EndMap;
  y << YAML::Key << "boundaries" << YAML::Value << YAML::BeginMap;
  kv("k_magnitude", o.boundaries.k_magnitude);
  kv("k_orientation", o.boundaries.k_orientation);
  kv("strong", o.boundaries.strong);
  kv("threshold", o.boundaries.threshold);
  kv("min_flow_for_angle", o.boundaries.min_flow_for_angle);
  y << YAML::EndMap;
  const SdoClassifierOptions& c = o.classifier;
  y << YAML::Key << "classifier" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "movable_classes" << YAML::Value << YAML::Flow << c.movable_classes;
  kv("work_width", c.work_width);
  kv("min_box_iou", c.min_box_iou);
  kv("min_inside_box", c.min_inside_box);
  kv("same_depth_tolerance", c.same_depth_tolerance);
  kv("same_depth_min_m", c.same_depth_min_m);
  kv("boundary_band_px", c.boundary_band_px);
  kv("min_outline_on_boundary", c.min_outline_on_boundary);
  kv("min_in_front", c.min_in_front);
  kv("min_in_front_of_outline", c.min_in_front_of_outline);
  kv("in_front_ratio", c.in_front_ratio);
  kv("max_segment_area", c.max_segment_area);
  kv("persistence_frames", c.persistence_frames);
  kv("persistence_overlap", c.persistence_overlap);
  kv("persistence_large_overlap", c.persistence_large_overlap);
  kv("persistence_min_in_front", c.persistence_min_in_front);
  kv("persistence_min_ordered", c.persistence_min_ordered);
  kv("margin_px", c.margin_px);
  y << YAML::EndMap;
  y << YAML::EndMap;
}

FrontEnd::FrontEnd(const FrontEndOptions& options, const std::filesystem::path& dataset_folder,
                   cv::Size image_size, const std::vector<std::filesystem::path>& rgb_paths,
                   const cv::Matx33d& K)
    : options_(options), image_size_(image_size), classifier_(options.classifier) {
  options_.Check();
  if (options_.segmenter == "rgbd") {
    segmenter_ = std::make_unique<RgbdSegmenter>(options_.rgbd);
  } else if (options_.segmenter == "geometric") {
    segmenter_ = std::make_unique<GeometricSegmenter>(options_.geometric, K, image_size);
  } else if (options_.segmenter == "onnx-yoloseg") {
    segmenter_ = std::make_unique<OnnxYoloSegSegmenter>(options_.segmenter_model, options_.yoloseg);
  } else {
    auto file =
        std::make_unique<FileSegmenter>(Resolve(options_.masks_folder, dataset_folder), image_size);
    file->Validate(rgb_paths);
    segmenter_ = std::move(file);
  }
  if (options_.detector == "nanodet") {
    detector_ = MakeNanoDetDetector(options_.detector_model, options_.detection);
  } else if (options_.detector == "fastestdet") {
    detector_ = MakeFastestDetDetector(options_.detector_model, options_.detection);
  } else if (options_.detector == "yolov8") {
    detector_ = MakeYolov8Detector(options_.detector_model, options_.detection);
  } else if (options_.detector == "hog") {
    detector_ = std::make_unique<HogDetector>(options_.hog);
  } else if (options_.detector == "file") {
    detector_ = std::make_unique<FileDetector>(Resolve(options_.detections_file, dataset_folder));
  } else {
    detector_ = std::make_unique<NoDetector>();
  }
  if (options_.flow == "dis") {
    flow_ = MakeDisFlow(options_.flow_options);
  } else if (options_.flow == "farneback") {
    flow_ = MakeFarnebackFlow(options_.flow_options);
  } else {
    flow_ = MakeOnnxFlow(options_.flow_model, options_.flow_options);
  }
}

FrontEnd::~FrontEnd() = default;

SdoResult FrontEnd::Process(const FrontEndFrame& frame, FrontEndTiming* timing) {
  if (frame.bgr.size() != image_size_) {
    throw Error(fmt::format("frame {}: image is {}x{}, the front end expects {}x{}", frame.index,
                            frame.bgr.cols, frame.bgr.rows, image_size_.width, image_size_.height));
  }
  FrontEndTiming t;
  auto start = std::chrono::steady_clock::now();
  cv::Mat flow, boundaries;
  if (!previous_bgr_.empty()) {
    flow = flow_->Compute(previous_bgr_.front(), frame.bgr);
    boundaries = ComputeMotionBoundaries(flow, options_.boundaries).mask;
  }
  t.flow_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  if (frames_ % static_cast<size_t>(options_.detect_every) == 0) {
    last_detections_ = detector_->Detect(frame);
  } else {
    ShiftByFlow(flow, image_size_, &last_detections_);
  }
  t.detect_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  const Segmentation segments = segmenter_->Segment(frame);
  t.segment_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  SdoResult result =
      classifier_.Classify(segments, last_detections_, boundaries, flow, frame.depth, image_size_);
  t.classify_ms = MsSince(start);
  previous_bgr_.push_back(frame.bgr.clone());
  if (static_cast<int>(previous_bgr_.size()) > options_.flow_options.frame_gap)
    previous_bgr_.pop_front();
  ++frames_;
  if (timing != nullptr) *timing = t;
  return result;
}

}  // namespace sdoslam
