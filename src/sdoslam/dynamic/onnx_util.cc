#include "sdoslam/dynamic/onnx_util.h"

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"

namespace sdoslam {

cv::dnn::Net LoadOnnxModel(const std::filesystem::path& path, const std::string& backend) {
  if (path.empty()) throw Error(backend + ": no model file given");
  if (!std::filesystem::is_regular_file(path))
    throw Error(path.string() + ": model file for '" + backend + "' does not exist");
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNetFromONNX(path.string());
  } catch (const cv::Exception& e) {
    throw Error(path.string() + ": not a model OpenCV can load as ONNX (" + e.err + ")");
  }
  if (net.empty()) throw Error(path.string() + ": empty ONNX model");
  net.setPreferableBackend(cv::dnn::DNN_BACKEND_OPENCV);
  net.setPreferableTarget(cv::dnn::DNN_TARGET_CPU);
  return net;
}

std::vector<cv::Mat> ForwardAll(cv::dnn::Net& net, const cv::Mat& blob) {
  net.setInput(blob);
  std::vector<cv::Mat> outputs;
  net.forward(outputs, net.getUnconnectedOutLayersNames());
  return outputs;
}

std::string ShapeString(const cv::Mat& m) {
  std::string s;
  for (int i = 0; i < m.dims; ++i) s += (i ? "x" : "") + std::to_string(m.size[i]);
  return s;
}

cv::Size ModelInputSize(const cv::dnn::Net& net, cv::Size fallback) {
  std::vector<cv::dnn::MatShape> in, out;
  try {
    net.getLayerShapes(cv::dnn::MatShape(), 0, in, out);
  } catch (const cv::Exception&) {
    return fallback;
  }
  if (in.empty() || in[0].size() != 4 || in[0][2] <= 0 || in[0][3] <= 0) return fallback;
  return {in[0][3], in[0][2]};
}

double Letterbox(const cv::Mat& bgr, cv::Size size, cv::Mat* out) {
  const double scale = std::min(static_cast<double>(size.width) / bgr.cols,
                                static_cast<double>(size.height) / bgr.rows);
  cv::Mat resized;
  cv::resize(bgr, resized,
             {static_cast<int>(std::lround(bgr.cols * scale)),
              static_cast<int>(std::lround(bgr.rows * scale))},
             0, 0, cv::INTER_LINEAR);
  out->create(size, bgr.type());
  out->setTo(cv::Scalar::all(114));
  resized.copyTo((*out)(cv::Rect(0, 0, resized.cols, resized.rows)));
  return scale;
}

}  // namespace sdoslam
