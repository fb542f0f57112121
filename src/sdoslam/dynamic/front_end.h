#pragma once

#include <deque>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "sdoslam/core/config.h"
#include "sdoslam/dynamic/classifier.h"
#include "sdoslam/dynamic/detection_hold.h"
#include "sdoslam/dynamic/detector.h"
#include "sdoslam/dynamic/flow.h"
#include "sdoslam/dynamic/geometric_segmenter.h"
#include "sdoslam/dynamic/motion_boundaries.h"
#include "sdoslam/dynamic/segmenter.h"
#include "sdoslam/dynamic/yoloseg.h"

namespace YAML {
class Emitter;
}

namespace sdoslam {

// Backends and settings of the dynamic-object front end (config section `dynamic:`).
struct FrontEndOptions {
  std::string segmenter = "geometric";    // geometric | rgbd | onnx-yoloseg | file
  std::filesystem::path segmenter_model;  // onnx-yoloseg: Fast-SAM / YOLOv8-seg export
  std::filesystem::path masks_folder;     // file: instance PNGs (relative: to the dataset)
  RgbdSegmenterOptions rgbd;
  GeometricSegmenterOptions geometric;
  YoloSegOptions yoloseg;
  // Run the segmenter on every n-th frame; in between, the last segments are carried along the
  // flow (CarrySegmentsAlongFlow). Every frame by default: every 2nd saves about half of the
  // segmenter's cost, but a person filling the view moves too far in a frame and accuracy drops
  // there (docs/performance.md, Trading accuracy for speed).
  int segment_every = 1;

  std::string detector = "hog";           // nanodet | fastestdet | yolov8 | hog | file | none
  std::filesystem::path detector_model;   // ONNX backends
  std::filesystem::path detections_file;  // file: JSON (relative: to the dataset)
  // Run the detector on every n-th frame; in between, boxes follow the median flow of their
  // nearer pixels, one frame's worth of it (front_end.cc: ShiftByFlow).
  // Every 2nd frame by default: half of HOG's cost, while a person who enters or crosses the
  // view close is boxed only a frame late (mask IoU a little lower, ATE unchanged); every 3rd or
  // 4th loses much more IoU (docs/performance.md, Trading accuracy for speed).
  int detect_every = 2;
  DetectorOptions detection;
  DetectionHoldOptions hold;
  HogDetectorOptions hog;

  std::string flow = "dis";  // dis | farneback | onnx
  std::filesystem::path flow_model;
  FlowOptions flow_options;

  MotionBoundaryOptions boundaries;
  SdoClassifierOptions classifier;
  void Check() const;  // Errors name the setting's config path (dynamic.detector.every)

  // Every setting at its config key below dynamic:. The config groups them by stage, each
  // stage's backend, model and options in its own section (dynamic.segmenter.backend,
  // dynamic.segmenter.rgbd.work_width); a backend's own options are a section named as the
  // member, options every backend of a stage shares (detection, flow_options) sit in the
  // stage's section itself.
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("segmenter", OptionGroup{[&](auto&& v) {
            v("backend", o.segmenter);
            v("model", o.segmenter_model);
            v("folder", o.masks_folder);
            v("every", o.segment_every);
            v("rgbd", o.rgbd);
            v("geometric", o.geometric);
            v("yoloseg", o.yoloseg);
          }});
    visit("detector", OptionGroup{[&](auto&& v) {
            v("backend", o.detector);
            v("model", o.detector_model);
            v("file", o.detections_file);
            v("every", o.detect_every);
            DetectorOptions::VisitFields(o.detection, v);
            DetectionHoldOptions::VisitFields(o.hold, v);
            v("hog", o.hog);
          }});
    visit("flow", OptionGroup{[&](auto&& v) {
            v("backend", o.flow);
            v("model", o.flow_model);
            FlowOptions::VisitFields(o.flow_options, v);
          }});
    visit("boundaries", o.boundaries);
    visit("classifier", o.classifier);
  }
};

// Segments of the frame before carried to this one, for frames the segmenter skips: each segment
// moves by the median of its pixels' flow, a span-th of it (the flow, CV_32FC2 at any size of
// the labels' aspect, runs from the frame `span` frames back to this one), and nearer segments
// (median of `depth`, CV_32F metres at any size, may be empty) cover farther ones. Pixels no
// segment moves to are −1.
Segmentation CarrySegmentsAlongFlow(const Segmentation& last, const cv::Mat& flow, int span,
                                    const cv::Mat& depth = cv::Mat());

// Reads the optional `dynamic:` section; unknown keys and backend names are errors naming the
// file and line.
FrontEndOptions ReadFrontEndOptions(ConfigMap& root);
// Writes the `dynamic:` section (ReadFrontEndOptions reads it back to the same options).
void WriteFrontEndOptions(const FrontEndOptions& options, YAML::Emitter* out);

struct FrontEndTiming {
  double segment_ms = 0, detect_ms = 0, flow_ms = 0, classify_ms = 0;
  double total() const { return segment_ms + detect_ms + flow_ms + classify_ms; }
};

// Segmenter + detector + optical flow + motion boundaries + classification, frame after frame.
class FrontEnd {
 public:
  // Builds the backends. Relative file-backend paths resolve against `dataset_folder`. Throws
  // Error for unknown backends, missing or unreadable files, models whose outputs do not match
  // their backend, and (file backends) masks or detections that do not fit `rgb_paths`.
  // K: the camera matrix, which the geometric segmenter needs (zero: none given).
  FrontEnd(const FrontEndOptions& options, const std::filesystem::path& dataset_folder,
           cv::Size image_size, const std::vector<std::filesystem::path>& rgb_paths = {},
           const cv::Matx33d& K = cv::Matx33d::zeros());
  ~FrontEnd();

  SdoResult Process(const FrontEndFrame& frame, FrontEndTiming* timing = nullptr);

 private:
  FrontEndOptions options_;
  cv::Size image_size_;
  std::unique_ptr<Segmenter> segmenter_;
  std::unique_ptr<Detector> detector_;
  std::unique_ptr<FlowEstimator> flow_;
  SdoClassifier classifier_;
  // The last flow_options.frame_gap images as the flow takes them (FlowEstimator::Prepare),
  // oldest first: each frame is converted once, not once for every pair it is part of.
  std::deque<cv::Mat> previous_flow_inputs_;
  DetectionHold detections_;  // the boxes in force, held while the detector misses them
  Segmentation last_segments_;
  size_t frames_ = 0;
};

}  // namespace sdoslam
