#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "sdoslam/dynamic/segmenter.h"

namespace sdoslam {

// The paper's class-agnostic segmentation network: a Fast-SAM or YOLOv8-seg ONNX export run
// through OpenCV dnn. Input: RGB letterboxed to the model's size (640 when dynamic), scaled to
// [0, 1]. Outputs: detections 1×(4 + C + M)×N ([cx, cy, w, h] in input pixels, C class scores —
// C = 1 for Fast-SAM, 80 for YOLOv8-seg — and M mask coefficients) and prototypes 1×M×h×w.
// Each kept instance's mask is sigmoid(coefficients · prototypes), cropped to its box and
// thresholded; overlapping masks go to the higher score. Class-agnostic NMS.
struct YoloSegOptions {
  double score_threshold = 0.4;
  double nms_iou = 0.5;
  double mask_threshold = 0.5;
  int max_instances = 64;
  void Check(
      const std::string& path = "dynamic.segmenter.yoloseg.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("score_threshold", o.score_threshold);
    visit("nms_iou", o.nms_iou);
    visit("mask_threshold", o.mask_threshold);
    visit("max_instances", o.max_instances);
  }
};

class OnnxYoloSegSegmenter : public Segmenter {
 public:
  // Throws Error naming the file when it is missing or its outputs do not have the format.
  OnnxYoloSegSegmenter(const std::filesystem::path& model, const YoloSegOptions& options = {});
  ~OnnxYoloSegSegmenter() override;
  Segmentation Segment(const FrontEndFrame& frame) override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sdoslam
