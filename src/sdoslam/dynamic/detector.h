#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sdoslam/dynamic/frame_input.h"

namespace sdoslam {

// One detected object of a known (COCO) class.
struct Detection {
  int class_id = -1;       // COCO index (0 = person), −1 when only the name is known
  std::string class_name;  // COCO name
  float score = 0;
  cv::Rect2f box;  // pixels of the full image
  // Carried on after the detector frame that last reported it (DetectionHold): it labels only
  // segments in front of their surroundings, never the bare box, and follows their extent.
  bool held = false;
};

class Detector {
 public:
  virtual ~Detector() = default;
  virtual std::vector<Detection> Detect(const FrontEndFrame& frame) = 0;
};

// The 80 COCO class names in the usual model output order (index 0 = person).
const std::vector<std::string>& CocoClassNames();

struct DetectorOptions {
  double score_threshold = 0.4;  // detections below are dropped
  double nms_iou = 0.5;          // per-class non-maximum suppression
  void Check(const std::string& path = "dynamic.detector.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("score_threshold", o.score_threshold);
    visit("nms_iou", o.nms_iou);
  }
};

// Greedy per-class non-maximum suppression, highest score first.
std::vector<Detection> SuppressNonMaxima(std::vector<Detection> detections, double iou);

// Nothing is known: every dynamic object must be found by motion.
class NoDetector : public Detector {
 public:
  std::vector<Detection> Detect(const FrontEndFrame&) override { return {}; }
};

// OpenCV's built-in HOG + linear SVM people detector (Dalal & Triggs): needs no file; finds
// upright people only. Runs at `work_width` to stay affordable.
struct HogDetectorOptions {
  int work_width = 320;
  double hit_threshold = 0.0;
  // Pyramid step. 1.2, not 1.1: 4 levels instead of 7 at 320 px, a little over half the time a
  // call. A person may then be 10 % off the window's size instead of 5 %, a recall cost on real
  // people that no sequence here can show (HOG boxes none of the rendered or composited people;
  // docs/performance.md, The front end).
  double scale = 1.2;
  void Check(
      const std::string& path = "dynamic.detector.hog.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("work_width", o.work_width);
    visit("hit_threshold", o.hit_threshold);
    visit("scale", o.scale);
  }
};
class HogDetector : public Detector {
 public:
  explicit HogDetector(const HogDetectorOptions& options = {});
  ~HogDetector() override;
  std::vector<Detection> Detect(const FrontEndFrame& frame) override;

 private:
  struct Impl;
  HogDetectorOptions options_;
  std::unique_ptr<Impl> impl_;
};

// Detections computed elsewhere, one JSON file for the sequence (the format `sdoslam synth`
// writes): {"frames": [{"rgb": "rgb/x.png", "detections": [{"class": "person", "score": 0.9,
// "box": [x, y, w, h]}]}]}. Frames are matched by the rgb file name; a frame not listed has
// no detections. The whole file is parsed and checked on construction.
class FileDetector : public Detector {
 public:
  explicit FileDetector(const std::filesystem::path& json_path);
  std::vector<Detection> Detect(const FrontEndFrame& frame) override;
  size_t frames() const { return by_frame_.size(); }

 private:
  std::map<std::string, std::vector<Detection>> by_frame_;
};

// ONNX detectors run through OpenCV dnn. The constructors load the model, run it once on a
// blank image and throw Error naming the file when it is missing or its outputs do not have
// the backend's format.
//   nanodet:    NanoDet-m (320×320): per stride 8/16/32 class scores N×80 and boxes N×32 (DFL).
//   fastestdet: FastestDet (352×352): 1×85×H×W, [obj, tx, ty, tw, th, 80 classes].
//   yolov8:     Ultralytics YOLOv8 detection export: 1×84×N, [cx, cy, w, h, 80 classes],
//               letterboxed input of the model's size (640 when dynamic).
std::unique_ptr<Detector> MakeNanoDetDetector(const std::filesystem::path& model,
                                              const DetectorOptions& options);
std::unique_ptr<Detector> MakeFastestDetDetector(const std::filesystem::path& model,
                                                 const DetectorOptions& options);
std::unique_ptr<Detector> MakeYolov8Detector(const std::filesystem::path& model,
                                             const DetectorOptions& options);

}  // namespace sdoslam
