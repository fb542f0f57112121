// ONNX detector backends (NanoDet, FastestDet, YOLOv8) through OpenCV dnn. Each decodes its
// model's raw output tensors; the formats are those of the public exports (see detector.h).
#include <fmt/format.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/detector.h"
#include "sdoslam/dynamic/onnx_util.h"

namespace sdoslam {
namespace {

float Sigmoid(float x) { return 1.0f / (1.0f + std::exp(-x)); }

Detection MakeDetection(int class_id, float score, float x0, float y0, float x1, float y1,
                        cv::Size image) {
  const auto& names = CocoClassNames();
  x0 = std::clamp(x0, 0.0f, static_cast<float>(image.width));
  x1 = std::clamp(x1, 0.0f, static_cast<float>(image.width));
  y0 = std::clamp(y0, 0.0f, static_cast<float>(image.height));
  y1 = std::clamp(y1, 0.0f, static_cast<float>(image.height));
  return {class_id,
          class_id < static_cast<int>(names.size()) ? names[class_id]
                                                    : "class" + std::to_string(class_id),
          score, cv::Rect2f(x0, y0, x1 - x0, y1 - y0)};
}

// Base: loads, validates with one blank forward pass, and runs.
class OnnxDetector : public Detector {
 public:
  OnnxDetector(const std::filesystem::path& model, const std::string& backend,
               const DetectorOptions& options)
      : path_(model), backend_(backend), options_(options), net_(LoadOnnxModel(model, backend)) {
    options_.Check();
  }

  std::vector<Detection> Detect(const FrontEndFrame& frame) override {
    std::vector<cv::Mat> outputs = ForwardAll(net_, MakeBlob(frame.bgr));
    return SuppressNonMaxima(Decode(outputs, frame.bgr.size()), options_.nms_iou);
  }

 protected:
  // Called at the end of each derived constructor: a model whose outputs do not fit the
  // backend fails here, before any frame is processed.
  void Validate() {
    const cv::Mat blank(480, 640, CV_8UC3, cv::Scalar::all(127));
    std::vector<cv::Mat> outputs;
    try {
      outputs = ForwardAll(net_, MakeBlob(blank));
    } catch (const cv::Exception& e) {
      throw Error(fmt::format("{}: the model does not run on a '{}' input: {}", path_.string(),
                              backend_, e.err));
    }
    const std::string problem = CheckOutputs(outputs);
    if (!problem.empty()) {
      std::string shapes;
      for (const cv::Mat& m : outputs) shapes += (shapes.empty() ? "" : ", ") + ShapeString(m);
      throw Error(fmt::format("{}: outputs [{}] do not match the '{}' format: {}", path_.string(),
                              shapes, backend_, problem));
    }
  }
  virtual cv::Mat MakeBlob(const cv::Mat& bgr) = 0;
  virtual std::string CheckOutputs(const std::vector<cv::Mat>& outputs) = 0;
  virtual std::vector<Detection> Decode(const std::vector<cv::Mat>& outputs, cv::Size image) = 0;

  std::filesystem::path path_;
  std::string backend_;
  DetectorOptions options_;
  cv::dnn::Net net_;
};

class NanoDet : public OnnxDetector {
 public:
  NanoDet(const std::filesystem::path& model, const DetectorOptions& options)
      : OnnxDetector(model, "nanodet", options) {
    Validate();
  }

 private:
  static constexpr int kSize = 320, kClasses = 80, kBins = 8;
  static constexpr int kStrides[3] = {8, 16, 32};

  cv::Mat MakeBlob(const cv::Mat& bgr) override {
    cv::Mat resized;
    cv::resize(bgr, resized, {kSize, kSize});
    resized.convertTo(resized, CV_32FC3);
    cv::subtract(resized, cv::Scalar(103.53, 116.28, 123.675), resized);
    cv::divide(resized, cv::Scalar(57.375, 57.12, 58.395), resized);
    return cv::dnn::blobFromImage(resized);
  }

  // The score and box tensors of each stride, matched by their element counts.
  bool Match(const std::vector<cv::Mat>& outputs, int stride, const cv::Mat** scores,
             const cv::Mat** boxes) const {
    const size_t n = static_cast<size_t>((kSize / stride) * (kSize / stride));
    *scores = *boxes = nullptr;
    for (const cv::Mat& m : outputs) {
      if (m.total() == n * kClasses) *scores = &m;
      if (m.total() == n * 4 * kBins) *boxes = &m;
    }
    return *scores != nullptr && *boxes != nullptr;
  }

  std::string CheckOutputs(const std::vector<cv::Mat>& outputs) override {
    if (outputs.size() != 6) return "expected 6 outputs (scores and boxes for 3 strides)";
    for (int stride : kStrides) {
      const cv::Mat *s, *b;
      if (!Match(outputs, stride, &s, &b))
        return fmt::format("no N×80 scores and N×32 boxes for stride {}", stride);
    }
    return "";
  }

  std::vector<Detection> Decode(const std::vector<cv::Mat>& outputs, cv::Size image) override {
    std::vector<Detection> out;
    const float sx = static_cast<float>(image.width) / kSize,
                sy = static_cast<float>(image.height) / kSize;
    for (int stride : kStrides) {
      const cv::Mat *scores_mat, *boxes_mat;
      Match(outputs, stride, &scores_mat, &boxes_mat);
      const float* scores = scores_mat->ptr<float>();
      const float* boxes = boxes_mat->ptr<float>();
      const int cols = kSize / stride;
      for (int cell = 0; cell < cols * cols; ++cell) {
        const float* s = scores + static_cast<size_t>(cell) * kClasses;
        const int best = static_cast<int>(std::max_element(s, s + kClasses) - s);
        if (s[best] < options_.score_threshold) continue;
        // Each side: expectation of a softmax over 8 distance bins, in strides.
        float side[4];
        for (int k = 0; k < 4; ++k) {
          const float* bins = boxes + static_cast<size_t>(cell) * 4 * kBins + k * kBins;
          const float top = *std::max_element(bins, bins + kBins);
          float sum = 0, expectation = 0;
          for (int b = 0; b < kBins; ++b) {
            const float e = std::exp(bins[b] - top);
            sum += e;
            expectation += e * static_cast<float>(b);
          }
          side[k] = expectation / sum * static_cast<float>(stride);
        }
        const float cx = static_cast<float>((cell % cols) * stride) + (stride - 1) / 2.0f;
        const float cy = static_cast<float>((cell / cols) * stride) + (stride - 1) / 2.0f;
        out.push_back(MakeDetection(best, s[best], (cx - side[0]) * sx, (cy - side[1]) * sy,
                                    (cx + side[2]) * sx, (cy + side[3]) * sy, image));
      }
    }
    return out;
  }
};

class FastestDet : public OnnxDetector {
 public:
  FastestDet(const std::filesystem::path& model, const DetectorOptions& options)
      : OnnxDetector(model, "fastestdet", options) {
    Validate();
  }

 private:
  static constexpr int kSize = 352, kChannels = 85;

  cv::Mat MakeBlob(const cv::Mat& bgr) override {
    return cv::dnn::blobFromImage(bgr, 1.0 / 255.0, {kSize, kSize}, cv::Scalar(), false, false);
  }

  std::string CheckOutputs(const std::vector<cv::Mat>& outputs) override {
    if (outputs.size() != 1) return "expected one output";
    const cv::Mat& m = outputs[0];
    if (m.dims != 4 || m.size[1] != kChannels) return "expected 1×85×H×W";
    return "";
  }

  std::vector<Detection> Decode(const std::vector<cv::Mat>& outputs, cv::Size image) override {
    const cv::Mat& m = outputs[0];
    const int rows = m.size[2], cols = m.size[3];
    const size_t plane = static_cast<size_t>(rows) * cols;
    const float* data = m.ptr<float>();
    std::vector<Detection> out;
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const size_t at = static_cast<size_t>(r) * cols + c;
        auto channel = [&](int k) { return data[static_cast<size_t>(k) * plane + at]; };
        int best = 0;
        for (int k = 1; k < 80; ++k) {
          if (channel(5 + k) > channel(5 + best)) best = k;
        }
        const float score = std::pow(channel(0), 0.6f) * std::pow(channel(5 + best), 0.4f);
        if (score < options_.score_threshold) continue;
        const float cx = (c + std::tanh(channel(1))) / cols * image.width;
        const float cy = (r + std::tanh(channel(2))) / rows * image.height;
        const float w = Sigmoid(channel(3)) * image.width, h = Sigmoid(channel(4)) * image.height;
        out.push_back(
            MakeDetection(best, score, cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2, image));
      }
    }
    return out;
  }
};

class Yolov8 : public OnnxDetector {
 public:
  Yolov8(const std::filesystem::path& model, const DetectorOptions& options)
      : OnnxDetector(model, "yolov8", options) {
    input_size_ = ModelInputSize(model, {640, 640});
    Validate();
  }

 private:
  cv::Mat MakeBlob(const cv::Mat& bgr) override {
    cv::Mat boxed;
    scale_ = Letterbox(bgr, input_size_, &boxed);
    return cv::dnn::blobFromImage(boxed, 1.0 / 255.0, {}, cv::Scalar(), true, false);
  }

  std::string CheckOutputs(const std::vector<cv::Mat>& outputs) override {
    if (outputs.size() != 1) return "expected one output";
    const cv::Mat& m = outputs[0];
    if (m.dims != 3 || m.size[1] != 84) return "expected 1×84×N (4 box values + 80 classes)";
    return "";
  }

  std::vector<Detection> Decode(const std::vector<cv::Mat>& outputs, cv::Size image) override {
    const cv::Mat& m = outputs[0];
    const int n = m.size[2];
    const float* data = m.ptr<float>();
    auto at = [&](int row, int i) { return data[static_cast<size_t>(row) * n + i]; };
    std::vector<Detection> out;
    const float inv = static_cast<float>(1.0 / scale_);
    for (int i = 0; i < n; ++i) {
      int best = 0;
      for (int k = 1; k < 80; ++k) {
        if (at(4 + k, i) > at(4 + best, i)) best = k;
      }
      const float score = at(4 + best, i);
      if (score < options_.score_threshold) continue;
      const float cx = at(0, i), cy = at(1, i), w = at(2, i), h = at(3, i);
      out.push_back(MakeDetection(best, score, (cx - w / 2) * inv, (cy - h / 2) * inv,
                                  (cx + w / 2) * inv, (cy + h / 2) * inv, image));
    }
    return out;
  }

  cv::Size input_size_;
  double scale_ = 1.0;
};

}  // namespace

std::unique_ptr<Detector> MakeNanoDetDetector(const std::filesystem::path& model,
                                              const DetectorOptions& options) {
  return std::make_unique<NanoDet>(model, options);
}
std::unique_ptr<Detector> MakeFastestDetDetector(const std::filesystem::path& model,
                                                 const DetectorOptions& options) {
  return std::make_unique<FastestDet>(model, options);
}
std::unique_ptr<Detector> MakeYolov8Detector(const std::filesystem::path& model,
                                             const DetectorOptions& options) {
  return std::make_unique<Yolov8>(model, options);
}

}  // namespace sdoslam
