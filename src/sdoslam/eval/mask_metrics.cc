#include "sdoslam/eval/mask_metrics.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/io/png_reader.h"

namespace sdoslam {

double MaskCounts::Precision() const {
  const uint64_t p = true_positive + false_positive;
  return p == 0 ? 1.0 : static_cast<double>(true_positive) / static_cast<double>(p);
}
double MaskCounts::Recall() const {
  const uint64_t t = true_positive + false_negative;
  return t == 0 ? 1.0 : static_cast<double>(true_positive) / static_cast<double>(t);
}
double MaskCounts::Iou() const {
  const uint64_t u = true_positive + false_positive + false_negative;
  return u == 0 ? 1.0 : static_cast<double>(true_positive) / static_cast<double>(u);
}
MaskCounts& MaskCounts::operator+=(const MaskCounts& o) {
  true_positive += o.true_positive;
  false_positive += o.false_positive;
  false_negative += o.false_negative;
  true_negative += o.true_negative;
  return *this;
}

MaskEvaluator::MaskEvaluator(const std::filesystem::path& sequence) : sequence_(sequence) {
  for (const char* folder : {"dynamic", "instance"}) {
    if (!std::filesystem::is_directory(sequence / folder))
      throw Error((sequence / folder).string() +
                  ": no ground-truth masks (mask evaluation needs a synthetic sequence)");
  }
  const auto objects = sequence / "objects.json";
  const std::optional<std::string> text = ReadRegularFileIfExists(objects);
  if (!text) throw Error(objects.string() + ": cannot open");
  std::map<int, std::string> class_of_instance;
  try {
    const nlohmann::json j = nlohmann::json::parse(*text);
    for (const auto& o : j.at("objects")) {
      const bool known = o.value("known", false) && o.at("class").is_string();
      class_of_instance[o.at("id").get<int>()] =
          known ? o.at("class").get<std::string>() : "unknown";
    }
  } catch (const nlohmann::json::exception& e) {
    throw Error(objects.string() + ": " + e.what());
  }
  const auto slot_of = [this](const std::string& name) {
    const auto it = std::find(class_names_.begin(), class_names_.end(), name);
    if (it != class_names_.end()) return static_cast<int>(it - class_names_.begin());
    class_names_.push_back(name);
    return static_cast<int>(class_names_.size()) - 1;
  };
  unknown_slot_ = slot_of("unknown");
  for (const auto& [id, name] : class_of_instance) {
    if (id < 0 || id > 65535) continue;  // an 8- or 16-bit instance image holds no such id
    if (static_cast<size_t>(id) >= slot_of_instance_.size())
      slot_of_instance_.resize(static_cast<size_t>(id) + 1, unknown_slot_);
    slot_of_instance_[static_cast<size_t>(id)] = slot_of(name);
  }
}

namespace {

void Count(bool is, bool said, MaskCounts* c) {
  c->true_positive += is && said;
  c->false_positive += !is && said;
  c->false_negative += is && !said;
  c->true_negative += !is && !said;
}

// Every pixel: ground truth (non-zero: moving) against the prediction.
MaskCounts CountPixels(const cv::Mat& truth, const cv::Mat& predicted) {
  MaskCounts counts;
  for (int y = 0; y < truth.rows; ++y) {
    const uint8_t* t = truth.ptr<uint8_t>(y);
    const uint8_t* p = predicted.ptr<uint8_t>(y);
    for (int x = 0; x < truth.cols; ++x) Count(t[x] != 0, p[x] != 0, &counts);
  }
  return counts;
}

// One class's moving pixels (`mask`), and the mistakes inside its objects' boxes grown by a
// tenth on each side: the class's own score, not the whole image's.
MaskCounts CountInGrownBoxes(const cv::Mat& mask, const cv::Mat& truth, const cv::Mat& predicted) {
  cv::Mat region(truth.size(), CV_8U, cv::Scalar(0));
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  for (const auto& c : contours) {
    cv::Rect r = cv::boundingRect(c);
    const int gx = r.width / 10, gy = r.height / 10;
    r = cv::Rect(r.x - gx, r.y - gy, r.width + 2 * gx, r.height + 2 * gy) &
        cv::Rect(0, 0, truth.cols, truth.rows);
    region(r).setTo(255);
  }
  MaskCounts c;
  for (int y = 0; y < truth.rows; ++y) {
    const uint8_t* m = mask.ptr<uint8_t>(y);
    const uint8_t* r = region.ptr<uint8_t>(y);
    const uint8_t* t = truth.ptr<uint8_t>(y);
    const uint8_t* p = predicted.ptr<uint8_t>(y);
    for (int x = 0; x < truth.cols; ++x) {
      if (m[x]) {
        (p[x] ? c.true_positive : c.false_negative) += 1;
      } else if (r[x] && !t[x]) {
        (p[x] ? c.false_positive : c.true_negative) += 1;
      }
    }
  }
  return c;
}

// The features at their nearest pixel: ground truth against their labels (non-zero: dynamic).
MaskCounts CountFeatures(const cv::Mat& truth, const std::vector<cv::Point2f>& features,
                         const std::vector<uint8_t>& feature_labels) {
  MaskCounts counts;
  for (size_t i = 0; i < features.size(); ++i) {
    const int x = std::clamp(static_cast<int>(std::lround(features[i].x)), 0, truth.cols - 1);
    const int y = std::clamp(static_cast<int>(std::lround(features[i].y)), 0, truth.rows - 1);
    Count(truth.at<uint8_t>(y, x) != 0, feature_labels[i] != 0, &counts);
  }
  return counts;
}

}  // namespace

void MaskEvaluator::AddFrame(const std::filesystem::path& rgb_path, const cv::Mat& predicted,
                             const std::vector<cv::Point2f>& features,
                             const std::vector<uint8_t>& feature_labels) {
  const std::string name = rgb_path.filename().string();
  const auto dynamic_path = sequence_ / "dynamic" / name,
             instance_path = sequence_ / "instance" / name;
  const cv::Mat truth = ReadImage(dynamic_path, cv::IMREAD_UNCHANGED);
  const cv::Mat instance = ReadImage(instance_path, cv::IMREAD_UNCHANGED);
  if (truth.empty()) throw Error(dynamic_path.string() + ": cannot read the ground-truth mask");
  if (instance.empty()) throw Error(instance_path.string() + ": cannot read the instance mask");
  if (truth.size() != predicted.size() || instance.size() != predicted.size())
    throw Error(dynamic_path.string() + ": ground truth and prediction differ in size");
  cv::Mat instance32;
  instance.convertTo(instance32, CV_32S);

  result_.pixels += CountPixels(truth, predicted);

  // Per class: moving pixels of the class, and mistakes inside its objects' grown boxes.
  std::vector<cv::Mat> class_truth(class_names_.size());
  for (int y = 0; y < truth.rows; ++y) {
    const uint8_t* t = truth.ptr<uint8_t>(y);
    const int* id = instance32.ptr<int>(y);
    for (int x = 0; x < truth.cols; ++x) {
      if (!t[x]) continue;
      const size_t slot = id[x] >= 0 && static_cast<size_t>(id[x]) < slot_of_instance_.size()
                              ? static_cast<size_t>(slot_of_instance_[static_cast<size_t>(id[x])])
                              : static_cast<size_t>(unknown_slot_);
      cv::Mat& m = class_truth[slot];
      if (m.empty()) m = cv::Mat(truth.size(), CV_8U, cv::Scalar(0));
      m.ptr<uint8_t>(y)[x] = 255;
    }
  }
  for (size_t slot = 0; slot < class_truth.size(); ++slot) {
    const cv::Mat& mask = class_truth[slot];
    if (mask.empty()) continue;
    const MaskCounts counts = CountInGrownBoxes(mask, truth, predicted);
    result_.per_class[class_names_[slot]] += counts;
    result_.per_frame.push_back({result_.frames, name, class_names_[slot], counts});
  }

  if (features.size() != feature_labels.size())
    throw Error("mask evaluation: feature positions and labels differ in number");
  result_.features += CountFeatures(truth, features, feature_labels);
  ++result_.frames;
}

std::string FormatMaskEvaluation(const MaskEvaluation& e, const std::string& label) {
  std::string s = fmt::format("{}: {} frames\n", label, e.frames);
  s += fmt::format("  pixels:   precision {:.3f}  recall {:.3f}  IoU {:.3f}\n",
                   e.pixels.Precision(), e.pixels.Recall(), e.pixels.Iou());
  s += fmt::format("  features: precision {:.3f}  recall {:.3f}  ({} dynamic of {})\n",
                   e.features.Precision(), e.features.Recall(),
                   e.features.true_positive + e.features.false_negative,
                   e.features.true_positive + e.features.false_negative +
                       e.features.false_positive + e.features.true_negative);
  for (const auto& [cls, c] : e.per_class) {
    std::vector<double> iou;
    for (const MaskEvaluation::FrameScore& f : e.per_frame) {
      if (f.class_name == cls) iou.push_back(f.counts.Iou());
    }
    std::sort(iou.begin(), iou.end());
    s += fmt::format("  {:<9} precision {:.3f}  recall {:.3f}  IoU {:.3f}", cls + ":",
                     c.Precision(), c.Recall(), c.Iou());
    if (!iou.empty()) {
      const size_t n = iou.size();
      const double median = n % 2 == 1 ? iou[n / 2] : 0.5 * (iou[n / 2 - 1] + iou[n / 2]);
      s += fmt::format("  (in {} frames: median {:.3f}, lowest {:.3f})", n, median, iou.front());
    }
    s += "\n";
  }
  return s;
}

void WritePerFrameScores(const MaskEvaluation& e, const std::string& run, std::ostream& out) {
  for (const MaskEvaluation::FrameScore& f : e.per_frame) {
    out << fmt::format("{},{},{},{},{:.4f},{},{},{}\n", run, f.frame, f.file, f.class_name,
                       f.counts.Iou(), f.counts.true_positive, f.counts.false_positive,
                       f.counts.false_negative);
  }
}

}  // namespace sdoslam
