#include "sdoslam/dynamic/flow.h"

#include <fmt/format.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/onnx_util.h"

namespace sdoslam {
namespace {

// `given_gray`: bgr in grey, or empty (made here from bgr).
cv::Mat GrayAtWidth(const cv::Mat& bgr, const cv::Mat& given_gray, int width) {
  cv::Mat gray = given_gray, small;
  if (gray.empty()) cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  if (width >= gray.cols) return given_gray.empty() ? gray : gray.clone();  // memory of its own
  const double s = static_cast<double>(width) / gray.cols;
  cv::resize(gray, small, {width, std::max(1, static_cast<int>(std::lround(gray.rows * s)))}, 0, 0,
             cv::INTER_AREA);
  return small;
}

class DisFlow : public FlowEstimator {
 public:
  explicit DisFlow(const FlowOptions& options)
      : options_(options), dis_(cv::DISOpticalFlow::create(options.dis_preset)) {}
  cv::Mat Prepare(const cv::Mat& bgr) const override {
    return GrayAtWidth(bgr, cv::Mat(), options_.work_width);
  }
  cv::Mat PrepareWithGray(const cv::Mat& bgr, const cv::Mat& gray) const override {
    return GrayAtWidth(bgr, gray, options_.work_width);
  }
  cv::Mat ComputePrepared(const cv::Mat& previous, const cv::Mat& current) override {
    cv::Mat flow;
    dis_->calc(previous, current, flow);
    return flow;
  }

 private:
  FlowOptions options_;
  cv::Ptr<cv::DISOpticalFlow> dis_;
};

class FarnebackFlow : public FlowEstimator {
 public:
  explicit FarnebackFlow(const FlowOptions& options) : options_(options) {}
  cv::Mat Prepare(const cv::Mat& bgr) const override {
    return GrayAtWidth(bgr, cv::Mat(), options_.work_width);
  }
  cv::Mat PrepareWithGray(const cv::Mat& bgr, const cv::Mat& gray) const override {
    return GrayAtWidth(bgr, gray, options_.work_width);
  }
  cv::Mat ComputePrepared(const cv::Mat& previous, const cv::Mat& current) override {
    cv::Mat flow;
    cv::calcOpticalFlowFarneback(previous, current, flow, 0.5, 3, 15, 3, 5, 1.2, 0);
    return flow;
  }

 private:
  FlowOptions options_;
};

class OnnxFlow : public FlowEstimator {
 public:
  OnnxFlow(const std::filesystem::path& model, const FlowOptions& options)
      : path_(model), names_(options.onnx_input_names), net_(LoadOnnxModel(model, "onnx flow")) {
    // A two-input model needs its inputs named; unless the user did, take the file's order.
    const std::vector<OnnxInput> inputs = ReadOnnxInputs(model);
    if (names_.empty() && inputs.size() == 2) names_ = {inputs[0].name, inputs[1].name};
    size_ = ModelInputSize(inputs, {options.work_width, options.work_width * 3 / 4});
    const cv::Mat blank = Blob(cv::Mat(size_, CV_8UC3, cv::Scalar::all(127)));
    cv::Mat out;
    try {
      out = Run(blank, blank);
    } catch (const cv::Exception& e) {
      throw Error(fmt::format("{}: the flow model does not run on {} input(s) of {}x{}: {}",
                              path_.string(), names_.empty() ? "one 6-channel" : "two 3-channel",
                              size_.height, size_.width, e.err));
    }
    if (out.dims != 4 || out.size[0] != 1 || out.size[1] != 2) {
      throw Error(fmt::format("{}: output {} does not match the onnx flow format 1x2xHxW",
                              path_.string(), ShapeString(out)));
    }
  }

  cv::Mat Prepare(const cv::Mat& bgr) const override { return Blob(bgr); }
  cv::Mat ComputePrepared(const cv::Mat& previous, const cv::Mat& current) override {
    const cv::Mat out = Run(previous, current);
    const int h = out.size[2], w = out.size[3];
    float* data = const_cast<float*>(out.ptr<float>());
    const cv::Mat u(h, w, CV_32F, data), v(h, w, CV_32F, data + static_cast<size_t>(h) * w);
    cv::Mat flow;
    cv::merge(std::vector<cv::Mat>{u, v}, flow);
    return flow;
  }

 private:
  // The network's input blob: RGB scaled to [0, 1] at its input size. (Not Prepare itself: the
  // constructor calls it, where a virtual call would not dispatch.)
  cv::Mat Blob(const cv::Mat& bgr) const {
    return cv::dnn::blobFromImage(bgr, 1.0 / 255.0, size_, cv::Scalar(), true);
  }
  // a, b: prepared blobs of the previous and the current image.
  cv::Mat Run(const cv::Mat& a, const cv::Mat& b) {
    if (names_.empty()) {
      const int shape[] = {1, 6, size_.height, size_.width};
      cv::Mat stacked(4, shape, CV_32F);
      const size_t half = a.total();
      std::copy_n(a.ptr<float>(), half, stacked.ptr<float>());
      std::copy_n(b.ptr<float>(), half, stacked.ptr<float>() + half);
      net_.setInput(stacked);
    } else {
      net_.setInput(a, names_[0]);
      net_.setInput(b, names_[1]);
    }
    return net_.forward().clone();
  }

  std::filesystem::path path_;
  std::vector<std::string> names_;
  cv::dnn::Net net_;
  cv::Size size_;
};

}  // namespace

void FlowOptions::Check(const std::string& path) const {
  if (work_width < 32) throw Error(path + "work_width must be at least 32");
  if (dis_preset < 0 || dis_preset > 2) throw Error(path + "dis_preset must be 0, 1 or 2");
  if (frame_gap < 1 || frame_gap > 30) throw Error(path + "frame_gap must be in [1, 30]");
  if (!onnx_input_names.empty() && onnx_input_names.size() != 2)
    throw Error(path + "onnx_input_names must name exactly two inputs (previous, current)");
}

std::unique_ptr<FlowEstimator> MakeDisFlow(const FlowOptions& options) {
  options.Check();
  return std::make_unique<DisFlow>(options);
}
std::unique_ptr<FlowEstimator> MakeFarnebackFlow(const FlowOptions& options) {
  options.Check();
  return std::make_unique<FarnebackFlow>(options);
}
std::unique_ptr<FlowEstimator> MakeOnnxFlow(const std::filesystem::path& model,
                                            const FlowOptions& options) {
  options.Check();
  return std::make_unique<OnnxFlow>(model, options);
}

}  // namespace sdoslam
