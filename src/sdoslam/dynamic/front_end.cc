#include "sdoslam/dynamic/front_end.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <limits>
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

// Boxes follow their object on frames without detection: each moves by the median flow of its
// nearer pixels (nearer than the box's median depth; all of them without depth), the object in
// it rather than the wall around it. A box holds much background (the mean flow of a block's
// exact box lagged a third behind it: DIS blurs motion across outlines). `flow` spans `span`
// frames (flow.frame_gap once that many have passed) and the boxes are one frame old, so they
// move by a `span`-th of it: moved by all of it, a box ran ahead of a walking person by twice
// its frame-to-frame motion.
void ShiftByFlow(const cv::Mat& flow, int span, const cv::Mat& depth, cv::Size image,
                 std::vector<Detection>* detections) {
  if (flow.empty() || span < 1) return;
  const double s = static_cast<double>(flow.cols) / image.width;
  auto median = [](std::vector<float>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  for (Detection& d : *detections) {
    const cv::Rect r = cv::Rect(static_cast<int>(d.box.x * s), static_cast<int>(d.box.y * s),
                                std::max(1, static_cast<int>(d.box.width * s)),
                                std::max(1, static_cast<int>(d.box.height * s))) &
                       cv::Rect(0, 0, flow.cols, flow.rows);
    if (r.area() <= 0) continue;
    std::vector<float> z;  // depth at each of the box's flow pixels, 0 = none
    z.reserve(static_cast<size_t>(r.area()));
    for (int y = r.y; y < r.y + r.height; ++y) {
      for (int x = r.x; x < r.x + r.width; ++x) {
        const int u = std::min(image.width - 1, static_cast<int>(x / s));
        const int v = std::min(image.height - 1, static_cast<int>(y / s));
        z.push_back(depth.empty() ? 0.0f : depth.at<float>(v, u));
      }
    }
    std::vector<float> valid;
    for (float metres : z) {
      if (metres > 0) valid.push_back(metres);
    }
    const float near_limit = valid.empty() ? 0.0f : median(valid);
    std::vector<float> dx, dy;
    size_t i = 0;
    for (int y = r.y; y < r.y + r.height; ++y) {
      const cv::Vec2f* row = flow.ptr<cv::Vec2f>(y);
      for (int x = r.x; x < r.x + r.width; ++x, ++i) {
        if (near_limit > 0 && !(z[i] > 0 && z[i] <= near_limit)) continue;
        dx.push_back(row[x][0]);
        dy.push_back(row[x][1]);
      }
    }
    if (dx.empty()) continue;
    d.box.x += static_cast<float>(median(dx) / (s * span));
    d.box.y += static_cast<float>(median(dy) / (s * span));
  }
}

}  // namespace

// Each segment moves as a whole by the median flow of its pixels (the object in it, not the
// outline where DIS blends it with what is behind), nearer segments drawn over farther ones.
// Warping each pixel by the flow instead fails at both outlines: the flow lies on the older
// frame's grid, so where an object has just moved to, it shows the background's motion, and
// where it has just left, its own. By hand: OpenCV has no warp of a label image by regions.
Segmentation CarrySegmentsAlongFlow(const Segmentation& last, const cv::Mat& flow, int span,
                                    const cv::Mat& depth) {
  Segmentation carried;
  carried.count = last.count;
  if (last.labels.empty() || flow.empty() || span < 1 || last.count <= 0) {
    carried.labels = last.labels.clone();
    return carried;
  }
  CV_Assert(last.labels.type() == CV_32S && flow.type() == CV_32FC2);
  CV_Assert(depth.empty() || depth.type() == CV_32F);
  const int W = last.labels.cols, H = last.labels.rows;
  const size_t count = static_cast<size_t>(last.count);
  // The flow and depth pixel under each label pixel's centre, by column and by row.
  const float sx = static_cast<float>(flow.cols) / W, sy = static_cast<float>(flow.rows) / H;
  std::vector<int> flow_column(static_cast<size_t>(W)), depth_column(static_cast<size_t>(W));
  for (int x = 0; x < W; ++x) {
    flow_column[x] = std::min(flow.cols - 1, static_cast<int>((x + 0.5f) * sx));
    depth_column[x] = depth.empty() ? 0 : std::min(depth.cols - 1, x * depth.cols / W);
  }
  // Each segment's flow and depths.
  std::vector<std::vector<float>> fx(count), fy(count), z(count);
  for (int y = 0; y < H; ++y) {
    const int* labels = last.labels.ptr<int>(y);
    const cv::Vec2f* f =
        flow.ptr<cv::Vec2f>(std::min(flow.rows - 1, static_cast<int>((y + 0.5f) * sy)));
    const float* d =
        depth.empty() ? nullptr : depth.ptr<float>(std::min(depth.rows - 1, y * depth.rows / H));
    for (int x = 0; x < W; ++x) {
      const int label = labels[x];
      if (label < 0 || label >= last.count) continue;
      const cv::Vec2f& v = f[flow_column[x]];
      fx[label].push_back(v[0]);
      fy[label].push_back(v[1]);
      if (d != nullptr && d[depth_column[x]] > 0) z[label].push_back(d[depth_column[x]]);
    }
  }
  auto median = [](std::vector<float>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  // A frame's worth of the span's motion, in label pixels, and the median depth (none: infinite).
  std::vector<int> dx(count, 0), dy(count, 0);
  std::vector<float> far(count, std::numeric_limits<float>::infinity());
  std::vector<int> order;
  for (size_t c = 0; c < count; ++c) {
    if (fx[c].empty()) continue;
    dx[c] = static_cast<int>(std::lround(median(fx[c]) / (sx * span)));
    dy[c] = static_cast<int>(std::lround(median(fy[c]) / (sy * span)));
    if (!z[c].empty()) far[c] = median(z[c]);
    order.push_back(static_cast<int>(c));
  }
  // Rank 0 the farthest: a pixel takes the nearest segment that moves onto it.
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return far[a] > far[b]; });
  std::vector<int> rank(count, -1);
  for (size_t r = 0; r < order.size(); ++r) rank[order[r]] = static_cast<int>(r);
  carried.labels = cv::Mat(H, W, CV_32S, cv::Scalar(-1));
  cv::Mat drawn_rank(H, W, CV_32S, cv::Scalar(-1));
  for (int y = 0; y < H; ++y) {
    const int* labels = last.labels.ptr<int>(y);
    for (int x = 0; x < W; ++x) {
      const int label = labels[x];
      if (label < 0 || label >= last.count) continue;
      const int tx = x + dx[label], ty = y + dy[label];
      if (tx < 0 || ty < 0 || tx >= W || ty >= H) continue;
      int& drawn = drawn_rank.at<int>(ty, tx);
      if (rank[label] > drawn) {
        drawn = rank[label];
        carried.labels.at<int>(ty, tx) = label;
      }
    }
  }
  return carried;
}

void FrontEndOptions::Check() const {
  CheckName("segmenter", segmenter, kSegmenters);
  CheckName("detector", detector, kDetectors);
  CheckName("flow", flow, kFlows);
  if (detect_every < 1) throw Error("dynamic.detector.every must be at least 1");
  if (segment_every < 1) throw Error("dynamic.segmenter.every must be at least 1");
  rgbd.Check("dynamic.segmenter.rgbd.");
  geometric.Check("dynamic.segmenter.geometric.");
  yoloseg.Check("dynamic.segmenter.yoloseg.");
  detection.Check("dynamic.detector.");
  hold.Check("dynamic.detector.");
  hog.Check("dynamic.detector.hog.");
  flow_options.Check("dynamic.flow.");
  boundaries.Check("dynamic.boundaries.");
  classifier.Check("dynamic.classifier.");
  if (segmenter == "onnx-yoloseg" && segmenter_model.empty())
    throw Error("segmenter 'onnx-yoloseg' needs dynamic.segmenter.model (an ONNX file)");
  if (segmenter == "file" && masks_folder.empty())
    throw Error("segmenter 'file' needs dynamic.segmenter.folder (instance-mask PNGs)");
  if ((detector == "nanodet" || detector == "fastestdet" || detector == "yolov8") &&
      detector_model.empty())
    throw Error("detector '" + detector + "' needs dynamic.detector.model (an ONNX file)");
  if (detector == "file" && detections_file.empty())
    throw Error("detector 'file' needs dynamic.detector.file (a detections JSON)");
  if (flow == "onnx" && flow_model.empty()) throw Error("flow 'onnx' needs dynamic.flow.model");
}

FrontEndOptions ReadFrontEndOptions(ConfigMap& root) {
  FrontEndOptions o;
  std::optional<ConfigMap> section = root.Section("dynamic");
  if (!section) return o;
  ReadFields(*section, &o);
  section->RejectUnknownKeys();
  try {
    o.Check();
  } catch (const Error& e) {
    throw Error(root.origin() + ": " + e.what());
  }
  return o;
}

void WriteFrontEndOptions(const FrontEndOptions& o, YAML::Emitter* out) {
  *out << YAML::Key << "dynamic" << YAML::Value << YAML::BeginMap;
  WriteFields(o, out);
  *out << YAML::EndMap;
}

FrontEnd::FrontEnd(const FrontEndOptions& options, const std::filesystem::path& dataset_folder,
                   cv::Size image_size, const std::vector<std::filesystem::path>& rgb_paths,
                   const cv::Matx33d& K)
    : options_(options),
      image_size_(image_size),
      classifier_(options.classifier),
      detections_(options.hold) {
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
  if (!frame.depth.empty() &&
      (frame.depth.size() != image_size_ || frame.depth.type() != CV_32FC1)) {
    throw Error(fmt::format(
        "frame {}: depth is {}x{} ({} channel(s), depth code {}), the front end expects {}x{} "
        "32-bit float",
        frame.index, frame.depth.cols, frame.depth.rows, frame.depth.channels(),
        frame.depth.depth(), image_size_.width, image_size_.height));
  }
  if (!frame.gray.empty() && (frame.gray.size() != image_size_ || frame.gray.type() != CV_8UC1)) {
    throw Error(fmt::format("frame {}: the grey image is not 8-bit single-channel {}x{}",
                            frame.index, image_size_.width, image_size_.height));
  }
  FrontEndTiming t;
  auto start = std::chrono::steady_clock::now();
  cv::Mat flow, boundaries;
  const int flow_span = static_cast<int>(previous_flow_inputs_.size());  // frames the flow spans
  cv::Mat flow_input = flow_->PrepareWithGray(frame.bgr, frame.gray);
  if (!previous_flow_inputs_.empty()) {
    flow = flow_->ComputePrepared(previous_flow_inputs_.front(), flow_input);
    boundaries = MotionBoundaryMask(flow, options_.boundaries);
  }
  t.flow_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  // The boxes in force follow the flow to this frame; on a detector frame fresh boxes replace
  // those they continue, and the others are held a while (DetectionHold). Without holding, a
  // detector frame's old boxes are all replaced: they need not be moved first.
  const bool detector_frame = frames_ % static_cast<size_t>(options_.detect_every) == 0;
  if (!detector_frame) detections_.Skip();
  if (!detector_frame || options_.hold.hold_frames > 0)
    ShiftByFlow(flow, flow_span, frame.depth, image_size_, &detections_.Boxes());
  if (detector_frame) detections_.Observe(detector_->Detect(frame));
  t.detect_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  Segmentation segments;
  if (frames_ % static_cast<size_t>(options_.segment_every) == 0 || last_segments_.labels.empty()) {
    segments = segmenter_->Segment(frame);
  } else {
    segments = CarrySegmentsAlongFlow(last_segments_, flow, flow_span, frame.depth);
  }
  last_segments_ = segments;  // the labels are not written again: a new image each frame
  t.segment_ms = MsSince(start);

  start = std::chrono::steady_clock::now();
  SdoResult result = classifier_.Classify(segments, detections_.Boxes(), boundaries, flow,
                                          frame.depth, image_size_);
  detections_.Follow(result.detection_extents);
  t.classify_ms = MsSince(start);
  previous_flow_inputs_.push_back(std::move(flow_input));
  if (static_cast<int>(previous_flow_inputs_.size()) > options_.flow_options.frame_gap)
    previous_flow_inputs_.pop_front();
  ++frames_;
  if (timing != nullptr) *timing = t;
  return result;
}

}  // namespace sdoslam
