#include "sdoslam/dynamic/onnx_util.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"

namespace sdoslam {

cv::dnn::Net LoadOnnxModel(const std::filesystem::path& path, const std::string& backend) {
  if (path.empty()) throw Error(backend + ": no model file given");
  if (!std::filesystem::exists(path))
    throw Error(path.string() + ": model file for '" + backend + "' does not exist");
  RejectNonRegularFile(path);  // OpenCV would block on a FIFO, or read /dev/zero without end
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
  for (int i = 0; i < m.dims; ++i) {
    if (i > 0) s += 'x';
    s += std::to_string(m.size[i]);
  }
  return s;
}

namespace {

// Just enough of the protobuf wire format to walk an ONNX ModelProto down to its graph inputs.
// Written by hand because OpenCV 4.6 offers no way to read a model's declared input shape
// (Net::getLayerShapes returns an empty shape for the input layer, and crashes asked for all
// layers without shapes), and Debian's libonnx + protobuf would be two more dependencies for
// four integers. Field numbers are those of onnx.proto (stable since ONNX 1.0).
class WireReader {
 public:
  WireReader(const char* begin, const char* end) : at_(begin), end_(end) {}
  bool done() const { return at_ >= end_; }

  // Next field: its number and wire type; for length-delimited fields also the payload.
  bool Next(uint32_t* field, uint32_t* wire_type, WireReader* payload, uint64_t* varint) {
    uint64_t key;
    if (!Varint(&key)) return false;
    *field = static_cast<uint32_t>(key >> 3);
    *wire_type = static_cast<uint32_t>(key & 7);
    switch (*wire_type) {
      case 0:
        return Varint(varint);
      case 1:
        return Skip(8);
      case 5:
        return Skip(4);
      case 2: {
        uint64_t length;
        if (!Varint(&length) || length > static_cast<uint64_t>(end_ - at_)) return false;
        *payload = WireReader(at_, at_ + length);
        at_ += length;
        return true;
      }
      default:  // groups (3, 4) are not used by onnx.proto
        return false;
    }
  }
  std::string Text() const { return std::string(at_, end_); }

 private:
  bool Varint(uint64_t* value) {
    *value = 0;
    for (int shift = 0; shift < 64 && at_ < end_; shift += 7) {
      const auto byte = static_cast<uint8_t>(*at_++);
      *value |= static_cast<uint64_t>(byte & 0x7f) << shift;
      if (!(byte & 0x80)) return true;
    }
    return false;
  }
  bool Skip(ptrdiff_t n) {
    if (end_ - at_ < n) return false;
    at_ += n;
    return true;
  }
  const char* at_;
  const char* end_;
};

// Calls `visit(field, wire_type, payload, varint)` for every field of `message` (`payload` is
// meaningful for length-delimited fields, `varint` for varints) until it returns false; false
// when it did or when the bytes are not a protobuf message.
template <typename Visit>
bool ForEachField(WireReader message, Visit visit) {
  uint32_t field, wire_type;
  uint64_t varint = 0;
  WireReader payload(nullptr, nullptr);
  while (!message.done()) {
    if (!message.Next(&field, &wire_type, &payload, &varint)) return false;
    if (!visit(field, wire_type, payload, varint)) return false;
  }
  return true;
}

// ValueInfoProto {1: name, 2: TypeProto {1: Tensor {2: TensorShapeProto {1: Dimension
// {1: dim_value, 2: dim_param}}}}}.
bool ParseValueInfo(WireReader value_info, OnnxInput* input) {
  auto dims = [&](uint32_t f, uint32_t w, WireReader dimension, uint64_t) {
    if (f != 1 || w != 2) return true;
    int64_t value = -1;
    const bool ok = ForEachField(dimension, [&](uint32_t g, uint32_t x, WireReader, uint64_t v) {
      if (g == 1 && x == 0) value = static_cast<int64_t>(v) > 0 ? static_cast<int64_t>(v) : -1;
      return true;
    });
    input->dims.push_back(value);
    return ok;
  };
  auto tensor = [&](uint32_t f, uint32_t w, WireReader shape, uint64_t) {
    return f != 2 || w != 2 || ForEachField(shape, dims);
  };
  auto type = [&](uint32_t f, uint32_t w, WireReader tensor_type, uint64_t) {
    return f != 1 || w != 2 || ForEachField(tensor_type, tensor);
  };
  return ForEachField(value_info, [&](uint32_t f, uint32_t w, WireReader payload, uint64_t) {
    if (f == 1 && w == 2) input->name = payload.Text();
    if (f == 2 && w == 2) return ForEachField(payload, type);
    return true;
  });
}

}  // namespace

std::vector<OnnxInput> ReadOnnxInputs(const std::filesystem::path& path) {
  // 2 GiB: protobuf's own limit on a message, so no ONNX model is larger.
  const std::optional<std::string> file = ReadRegularFileIfExists(path, uint64_t{2} << 30);
  if (!file) throw Error(path.string() + ": cannot open");
  const std::string& bytes = *file;
  const auto not_onnx = [&] { return Error(path.string() + ": not an ONNX model (protobuf)"); };
  std::vector<OnnxInput> inputs;
  std::vector<std::string> initializers;
  bool has_graph = false;
  const bool ok = ForEachField(
      WireReader(bytes.data(), bytes.data() + bytes.size()),
      [&](uint32_t f, uint32_t w, WireReader graph, uint64_t) {
        if (f != 7 || w != 2) return true;  // ModelProto.graph = 7
        has_graph = true;
        return ForEachField(graph, [&](uint32_t g, uint32_t x, WireReader payload, uint64_t) {
          if (x != 2) return true;
          if (g == 11) {  // GraphProto.input
            inputs.emplace_back();
            return ParseValueInfo(payload, &inputs.back());
          }
          if (g == 5) {  // GraphProto.initializer: TensorProto.name = 8
            return ForEachField(payload, [&](uint32_t t, uint32_t y, WireReader name, uint64_t) {
              if (t == 8 && y == 2) initializers.push_back(name.Text());
              return true;
            });
          }
          return true;
        });
      });
  if (!ok || !has_graph) throw not_onnx();
  // Exports before IR version 4 list the weights among the inputs too.
  std::erase_if(inputs, [&](const OnnxInput& input) {
    return std::find(initializers.begin(), initializers.end(), input.name) != initializers.end();
  });
  return inputs;
}

cv::Size ModelInputSize(const std::filesystem::path& path, cv::Size fallback) {
  return ModelInputSize(ReadOnnxInputs(path), fallback);
}

cv::Size ModelInputSize(const std::vector<OnnxInput>& inputs, cv::Size fallback) {
  if (inputs.empty() || inputs[0].dims.size() != 4) return fallback;
  const int64_t h = inputs[0].dims[2], w = inputs[0].dims[3];
  if (h <= 0 || w <= 0 || h > 16384 || w > 16384) return fallback;
  return {static_cast<int>(w), static_cast<int>(h)};
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
