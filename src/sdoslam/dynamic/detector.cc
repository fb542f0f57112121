#include "sdoslam/dynamic/detector.h"

#include <fmt/format.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"

namespace sdoslam {

const std::vector<std::string>& CocoClassNames() {
  static const std::vector<std::string> kNames = {"person",        "bicycle",      "car",
                                                  "motorcycle",    "airplane",     "bus",
                                                  "train",         "truck",        "boat",
                                                  "traffic light", "fire hydrant", "stop sign",
                                                  "parking meter", "bench",        "bird",
                                                  "cat",           "dog",          "horse",
                                                  "sheep",         "cow",          "elephant",
                                                  "bear",          "zebra",        "giraffe",
                                                  "backpack",      "umbrella",     "handbag",
                                                  "tie",           "suitcase",     "frisbee",
                                                  "skis",          "snowboard",    "sports ball",
                                                  "kite",          "baseball bat", "baseball glove",
                                                  "skateboard",    "surfboard",    "tennis racket",
                                                  "bottle",        "wine glass",   "cup",
                                                  "fork",          "knife",        "spoon",
                                                  "bowl",          "banana",       "apple",
                                                  "sandwich",      "orange",       "broccoli",
                                                  "carrot",        "hot dog",      "pizza",
                                                  "donut",         "cake",         "chair",
                                                  "couch",         "potted plant", "bed",
                                                  "dining table",  "toilet",       "tv",
                                                  "laptop",        "mouse",        "remote",
                                                  "keyboard",      "cell phone",   "microwave",
                                                  "oven",          "toaster",      "sink",
                                                  "refrigerator",  "book",         "clock",
                                                  "vase",          "scissors",     "teddy bear",
                                                  "hair drier",    "toothbrush"};
  return kNames;
}

void DetectorOptions::Check(const std::string& path) const {
  if (score_threshold < 0 || score_threshold > 1)
    throw Error(path + "score_threshold must be in [0, 1]");
  if (nms_iou <= 0 || nms_iou > 1) throw Error(path + "nms_iou must be in (0, 1]");
}

std::vector<Detection> SuppressNonMaxima(std::vector<Detection> detections, double iou) {
  std::stable_sort(detections.begin(), detections.end(),
                   [](const Detection& a, const Detection& b) { return a.score > b.score; });
  std::vector<Detection> kept;
  for (const Detection& d : detections) {
    bool suppressed = false;
    for (const Detection& k : kept) {
      if (k.class_name != d.class_name) continue;
      const float inter = (k.box & d.box).area();
      const float uni = k.box.area() + d.box.area() - inter;
      if (uni > 0 && inter / uni > iou) {
        suppressed = true;
        break;
      }
    }
    if (!suppressed) kept.push_back(d);
  }
  return kept;
}

void HogDetectorOptions::Check(const std::string& path) const {
  if (work_width < 64) throw Error(path + "work_width must be at least 64");
  if (scale <= 1.0) throw Error(path + "scale must exceed 1");
}

struct HogDetector::Impl {
  cv::HOGDescriptor hog;
};

HogDetector::HogDetector(const HogDetectorOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  options_.Check();
  impl_->hog.setSVMDetector(cv::HOGDescriptor::getDefaultPeopleDetector());
}

HogDetector::~HogDetector() = default;

std::vector<Detection> HogDetector::Detect(const FrontEndFrame& frame) {
  const double s = std::min(1.0, static_cast<double>(options_.work_width) / frame.bgr.cols);
  cv::Mat small;
  cv::resize(frame.bgr, small, {}, s, s, cv::INTER_AREA);
  std::vector<cv::Rect> boxes;
  std::vector<double> weights;
  impl_->hog.detectMultiScale(small, boxes, weights, options_.hit_threshold, cv::Size(8, 8),
                              cv::Size(), options_.scale);
  std::vector<Detection> out;
  for (size_t i = 0; i < boxes.size(); ++i) {
    const cv::Rect2f b(boxes[i].x / s, boxes[i].y / s, boxes[i].width / s, boxes[i].height / s);
    // The SVM margin is unbounded; squash it to (0, 1) so that thresholds read like scores.
    const float score = static_cast<float>(1.0 / (1.0 + std::exp(-weights[i])));
    out.push_back({0, "person", score, b});
  }
  return out;
}

FileDetector::FileDetector(const std::filesystem::path& path) {
  const std::optional<std::string> text = ReadRegularFileIfExists(path);
  if (!text) throw Error(path.string() + ": cannot open the detections file");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(*text);
  } catch (const nlohmann::json::exception& e) {
    throw Error(path.string() + ": not valid JSON: " + e.what());
  }
  const auto& names = CocoClassNames();
  try {
    if (!j.contains("frames") || !j["frames"].is_array())
      throw Error("missing the \"frames\" array");
    size_t frame_index = 0;
    for (const auto& f : j["frames"]) {
      const std::string where = fmt::format("frames[{}]", frame_index++);
      if (!f.contains("rgb")) throw Error(where + ": missing \"rgb\"");
      std::vector<Detection> detections;
      size_t k = 0;
      for (const auto& d : f.value("detections", nlohmann::json::array())) {
        const std::string at = fmt::format("{}.detections[{}]", where, k++);
        const auto& box = d.at("box");
        if (!box.is_array() || box.size() != 4) throw Error(at + ": \"box\" must be [x, y, w, h]");
        Detection det;
        det.class_name = d.at("class").get<std::string>();
        const auto it = std::find(names.begin(), names.end(), det.class_name);
        det.class_id = it == names.end() ? -1 : static_cast<int>(it - names.begin());
        det.score = d.value("score", 1.0f);
        det.box = cv::Rect2f(box[0].get<float>(), box[1].get<float>(), box[2].get<float>(),
                             box[3].get<float>());
        if (det.box.width <= 0 || det.box.height <= 0) throw Error(at + ": empty box");
        detections.push_back(det);
      }
      by_frame_[std::filesystem::path(f["rgb"].get<std::string>()).filename().string()] =
          std::move(detections);
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(path.string() + ": " + e.what());
  } catch (const Error& e) {
    throw Error(path.string() + ": " + e.what());
  }
}

std::vector<Detection> FileDetector::Detect(const FrontEndFrame& frame) {
  const auto it = by_frame_.find(frame.rgb_path.filename().string());
  return it == by_frame_.end() ? std::vector<Detection>{} : it->second;
}

}  // namespace sdoslam
