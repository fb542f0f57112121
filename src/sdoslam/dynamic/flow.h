#pragma once

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace sdoslam {

// Dense optical flow from the previous to the current image.
class FlowEstimator {
 public:
  virtual ~FlowEstimator() = default;
  // A BGR image in the form ComputePrepared takes it: grey at the work width (DIS, Farnebäck),
  // the network's input blob (ONNX), in memory of its own: a front end prepares each frame once
  // and keeps it, after the frame's image is gone, for the pairs the frame is part of (with
  // flow.frame_gap = 3, three).
  virtual cv::Mat Prepare(const cv::Mat& bgr) const = 0;
  // Prepare for a frame whose grey image (`gray`, CV_8UC1, may be empty) the caller has made
  // already: estimators that work on grey take it instead of converting `bgr` once more.
  virtual cv::Mat PrepareWithGray(const cv::Mat& bgr, const cv::Mat& /*gray*/) const {
    return Prepare(bgr);
  }
  // Flow between two prepared images: CV_32FC2 at (work) resolution, displacement in pixels of
  // that resolution. The result may be smaller than the images; its aspect is the images'.
  virtual cv::Mat ComputePrepared(const cv::Mat& previous, const cv::Mat& current) = 0;
  cv::Mat Compute(const cv::Mat& previous_bgr, const cv::Mat& current_bgr) {
    return ComputePrepared(Prepare(previous_bgr), Prepare(current_bgr));
  }
};

struct FlowOptions {
  // Flow runs at this width (aspect kept). 256 rather than 320, for accuracy, not speed (the
  // cost is about the same): DIS's smoothing then spans more of the scene and the motion
  // boundaries come out cleaner, better on the real-background plays and the same on synthetic
  // scenarios; 192 was worse on the carried box (docs/performance.md, The front end).
  int work_width = 256;
  // DIS preset: 0 ultrafast, 1 fast, 2 medium (OpenCV's DISOpticalFlow presets).
  int dis_preset = 1;
  // Flow from frame k − frame_gap to frame k. Slow objects move too little between two frames
  // at 30 Hz for their boundary to stand out of DIS's smoothing; a longer baseline scales their
  // flow difference (the camera-rotation term still cancels between neighbours).
  int frame_gap = 3;
  // onnx backend: names of the two image inputs (previous, current). Empty: a model with one
  // input takes 1×6×H×W, previous RGB then current RGB; a model with two takes previous then
  // current in the order the file declares its inputs.
  std::vector<std::string> onnx_input_names;
  void Check(const std::string& path = "dynamic.flow.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("work_width", o.work_width);
    visit("dis_preset", o.dis_preset);
    visit("frame_gap", o.frame_gap);
    visit("onnx_input_names", o.onnx_input_names);
  }
};

// OpenCV's DIS optical flow (Kroeger et al. 2016): fast on a CPU, the default.
std::unique_ptr<FlowEstimator> MakeDisFlow(const FlowOptions& options);
// OpenCV's Farnebäck polynomial-expansion flow: slower, smoother.
std::unique_ptr<FlowEstimator> MakeFarnebackFlow(const FlowOptions& options);
// A learned-flow network exported to ONNX (e.g. PWC-Net, RAFT): the two images as RGB scaled to
// [0, 1], either stacked in one 1×6×H×W input or as two 1×3×H×W inputs (named in
// `onnx_input_names`, or in the file's order); one output 1×2×H×W of flow in pixels of the input
// size. H×W is the model's declared input size, or the work size when dynamic. Throws Error naming
// the file when it is missing or its inputs/outputs do not fit.
std::unique_ptr<FlowEstimator> MakeOnnxFlow(const std::filesystem::path& model,
                                            const FlowOptions& options);

}  // namespace sdoslam
