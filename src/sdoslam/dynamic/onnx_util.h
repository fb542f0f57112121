#pragma once

#include <cstdint>
#include <filesystem>
#include <opencv2/dnn.hpp>
#include <string>
#include <vector>

namespace sdoslam {

// Loads an ONNX model with OpenCV dnn (CPU). Throws Error naming the file when it is missing or
// does not parse.
cv::dnn::Net LoadOnnxModel(const std::filesystem::path& path, const std::string& backend);

// Runs `net` on `blob` and returns every unconnected output.
std::vector<cv::Mat> ForwardAll(cv::dnn::Net& net, const cv::Mat& blob);

// "1x84x8400" for messages.
std::string ShapeString(const cv::Mat& m);

// A graph input of an ONNX file as declared: its name and dimensions, −1 where a dimension is
// symbolic or unset (a dynamic export).
struct OnnxInput {
  std::string name;
  std::vector<int64_t> dims;
};
// The graph inputs that are not weights, in file order. Throws Error naming the file when it
// cannot be read or is not an ONNX protobuf.
std::vector<OnnxInput> ReadOnnxInputs(const std::filesystem::path& path);

// The model's declared input size (W, H from its first input's N×C×H×W) when fixed; `fallback`
// when dynamic or undeclared.
cv::Size ModelInputSize(const std::filesystem::path& path, cv::Size fallback);
cv::Size ModelInputSize(const std::vector<OnnxInput>& inputs, cv::Size fallback);

// Letterbox: resize keeping the aspect into `size`, pad with grey (114) at the bottom/right.
// Returns the scale applied.
double Letterbox(const cv::Mat& bgr, cv::Size size, cv::Mat* out);

}  // namespace sdoslam
