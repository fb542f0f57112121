#include "sdoslam/dynamic/yoloseg.h"

#include <fmt/format.h>

#include <numeric>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/onnx_util.h"

namespace sdoslam {

void YoloSegOptions::Check(const std::string& path) const {
  if (score_threshold < 0 || score_threshold > 1 || mask_threshold <= 0 || mask_threshold >= 1)
    throw Error(path + "score_threshold in [0, 1] and " + path +
                "mask_threshold in (0, 1) are required");
  if (nms_iou <= 0 || nms_iou > 1) throw Error(path + "nms_iou must be in (0, 1]");
  if (max_instances < 1 || max_instances > 65535)
    throw Error(path + "max_instances must be in [1, 65535]");
}

struct OnnxYoloSegSegmenter::Impl {
  std::filesystem::path path;
  YoloSegOptions options;
  cv::dnn::Net net;
  cv::Size input;

  // The detection and prototype outputs, told apart by rank; "" when they fit.
  std::string Identify(const std::vector<cv::Mat>& outputs, const cv::Mat** detections,
                       const cv::Mat** prototypes) const {
    *detections = *prototypes = nullptr;
    if (outputs.size() != 2) return "expected two outputs (detections, prototypes)";
    for (const cv::Mat& m : outputs) {
      if (m.dims == 3) *detections = &m;
      if (m.dims == 4) *prototypes = &m;
    }
    if (*detections == nullptr || *prototypes == nullptr)
      return "expected a 1×(4+C+M)×N and a 1×M×h×w output";
    const int m = (*prototypes)->size[1];
    if ((*detections)->size[1] < 4 + 1 + m)
      return fmt::format("detections have {} rows, fewer than 4 + 1 class + {} coefficients",
                         (*detections)->size[1], m);
    return "";
  }

  std::vector<cv::Mat> Run(const cv::Mat& bgr, double* scale) {
    cv::Mat boxed;
    *scale = Letterbox(bgr, input, &boxed);
    return ForwardAll(net, cv::dnn::blobFromImage(boxed, 1.0 / 255.0, {}, cv::Scalar(), true));
  }
};

OnnxYoloSegSegmenter::OnnxYoloSegSegmenter(const std::filesystem::path& model,
                                           const YoloSegOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.Check();
  impl_->path = model;
  impl_->options = options;
  impl_->net = LoadOnnxModel(model, "onnx-yoloseg");
  impl_->input = ModelInputSize(model, {640, 640});
  std::vector<cv::Mat> outputs;
  double scale = 1;
  try {
    outputs = impl_->Run(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(127)), &scale);
  } catch (const cv::Exception& e) {
    throw Error(model.string() + ": the model does not run on an onnx-yoloseg input: " + e.err);
  }
  const cv::Mat *det, *proto;
  const std::string problem = impl_->Identify(outputs, &det, &proto);
  if (!problem.empty()) {
    std::string shapes;
    for (const cv::Mat& m : outputs) shapes += (shapes.empty() ? "" : ", ") + ShapeString(m);
    throw Error(fmt::format("{}: outputs [{}] do not match the 'onnx-yoloseg' format: {}",
                            model.string(), shapes, problem));
  }
}

OnnxYoloSegSegmenter::~OnnxYoloSegSegmenter() = default;

Segmentation OnnxYoloSegSegmenter::Segment(const FrontEndFrame& frame) {
  const YoloSegOptions& o = impl_->options;
  double scale = 1;
  const std::vector<cv::Mat> outputs = impl_->Run(frame.bgr, &scale);
  const cv::Mat *det, *proto;
  impl_->Identify(outputs, &det, &proto);
  const int rows = det->size[1], n = det->size[2];
  const int m = proto->size[1], ph = proto->size[2], pw = proto->size[3];
  const int classes = rows - 4 - m;
  const float* d = det->ptr<float>();
  auto at = [&](int row, int i) { return d[static_cast<size_t>(row) * n + i]; };

  std::vector<cv::Rect> boxes;
  std::vector<float> scores;
  std::vector<int> candidates;
  for (int i = 0; i < n; ++i) {
    float best = 0;
    for (int c = 0; c < classes; ++c) best = std::max(best, at(4 + c, i));
    if (best < o.score_threshold) continue;
    const float cx = at(0, i), cy = at(1, i), w = at(2, i), h = at(3, i);
    boxes.emplace_back(static_cast<int>(cx - w / 2), static_cast<int>(cy - h / 2),
                       static_cast<int>(w), static_cast<int>(h));
    scores.push_back(best);
    candidates.push_back(i);
  }
  std::vector<int> keep;
  cv::dnn::NMSBoxes(boxes, scores, static_cast<float>(o.score_threshold),
                    static_cast<float>(o.nms_iou), keep, 1.0f, o.max_instances);
  // Lowest score first, so that higher scores overwrite overlaps.
  std::sort(keep.begin(), keep.end(), [&](int a, int b) { return scores[a] < scores[b]; });

  const cv::Mat protos(m, ph * pw, CV_32F, const_cast<float*>(proto->ptr<float>()));
  const cv::Size input = impl_->input;
  const cv::Rect content(
      0, 0, std::min(input.width, static_cast<int>(std::lround(frame.bgr.cols * scale))),
      std::min(input.height, static_cast<int>(std::lround(frame.bgr.rows * scale))));
  cv::Mat ids(frame.bgr.size(), CV_32S, cv::Scalar(0));
  int next_id = 1;
  for (int k : keep) {
    const int i = candidates[static_cast<size_t>(k)];
    cv::Mat coefficients(1, m, CV_32F);
    for (int j = 0; j < m; ++j) coefficients.at<float>(0, j) = at(4 + classes + j, i);
    const cv::Mat product = coefficients * protos;
    const cv::Mat logits = product.reshape(1, ph);
    // Sigmoid threshold = logit threshold: no exp needed.
    const double logit_threshold = std::log(o.mask_threshold / (1 - o.mask_threshold));
    cv::Mat mask_input;
    cv::resize(logits, mask_input, input, 0, 0, cv::INTER_LINEAR);
    cv::Mat crop_mask(input, CV_8U, cv::Scalar(0));
    crop_mask(boxes[static_cast<size_t>(k)] & cv::Rect(cv::Point(), input)).setTo(255);
    cv::Mat mask = (mask_input > logit_threshold) & crop_mask;
    cv::Mat mask_image;
    cv::resize(mask(content), mask_image, frame.bgr.size(), 0, 0, cv::INTER_NEAREST);
    ids.setTo(next_id++, mask_image);
  }
  return SegmentationFromInstanceIds(ids);
}

}  // namespace sdoslam
