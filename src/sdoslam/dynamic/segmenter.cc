#include "sdoslam/dynamic/segmenter.h"

#include <fmt/format.h>

#include <array>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/segmentation.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/lab.h"
#include "sdoslam/io/image_header.h"
#include "sdoslam/io/png_reader.h"

namespace sdoslam {

const char* ToString(DynamicLabel label) {
  switch (label) {
    case kStatic:
      return "static";
    case kKnownMovable:
      return "known-movable";
    case kMovingUnknown:
      return "moving-unknown";
    case kSceneFlow:
      return "scene-flow";
  }
  return "?";
}

void RgbdSegmenterOptions::Check(const std::string& path) const {
  if (work_width < 16) throw Error(path + "work_width must be at least 16");
  if (sigma < 0 || k <= 0 || min_size < 1)
    throw Error(path + "sigma ≥ 0, " + path + "k > 0 and " + path + "min_size ≥ 1 are required");
  if (colour_weight < 0 || depth_weight < 0 || colour_weight + depth_weight <= 0)
    throw Error(path + "colour_weight and " + path + "depth_weight must be ≥ 0, not both 0");
}

struct RgbdSegmenter::Impl {
  cv::Ptr<cv::ximgproc::segmentation::GraphSegmentation> graph;
};

RgbdSegmenter::RgbdSegmenter(const RgbdSegmenterOptions& options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  options_.Check();
  impl_->graph = cv::ximgproc::segmentation::createGraphSegmentation(options_.sigma, options_.k,
                                                                     options_.min_size);
}

RgbdSegmenter::~RgbdSegmenter() = default;

Segmentation RgbdSegmenter::Segment(const FrontEndFrame& frame) {
  const double scale = static_cast<double>(options_.work_width) / frame.bgr.cols;
  const cv::Size work(options_.work_width,
                      std::max(1, static_cast<int>(std::lround(frame.bgr.rows * scale))));
  cv::Mat small_bgr, small;
  cv::resize(frame.bgr, small_bgr, work, 0, 0, cv::INTER_AREA);
  BgrToLab(small_bgr, &small);
  std::vector<cv::Mat> channels;
  cv::split(small, channels);
  for (cv::Mat& c : channels) c *= options_.colour_weight;
  cv::Mat log_depth(work, CV_32F, cv::Scalar(0));
  if (!frame.depth.empty()) {
    cv::Mat depth;
    cv::resize(frame.depth, depth, work, 0, 0, cv::INTER_NEAREST);
    // Fill small holes (silhouette dropout) with the farther neighbour: a hole at an object's
    // outline then joins the background, not the object.
    for (int i = 0; i < 3; ++i) {
      cv::Mat grown;
      cv::dilate(depth, grown, cv::Mat());
      grown.copyTo(depth, depth <= 0);
    }
    cv::log(cv::max(depth, 0.1), log_depth);
    log_depth *= options_.depth_weight;
  }
  channels.push_back(log_depth);
  cv::Mat features;
  cv::merge(channels, features);
  Segmentation s;
  impl_->graph->processImage(features, s.labels);
  double max_label = -1;
  cv::minMaxLoc(s.labels, nullptr, &max_label);
  s.count = static_cast<int>(max_label) + 1;
  return s;
}

Segmentation SegmentationFromInstanceIds(const cv::Mat& ids) {
  cv::Mat ids32;
  ids.convertTo(ids32, CV_32S);
  Segmentation s;
  s.labels.create(ids.size(), CV_32S);
  std::map<int, int> renumber;
  for (int y = 0; y < ids32.rows; ++y) {
    const int* in = ids32.ptr<int>(y);
    int* out = s.labels.ptr<int>(y);
    for (int x = 0; x < ids32.cols; ++x) {
      if (in[x] <= 0) {
        out[x] = -1;
        continue;
      }
      auto [it, inserted] = renumber.try_emplace(in[x], static_cast<int>(renumber.size()));
      out[x] = it->second;
    }
  }
  s.count = static_cast<int>(renumber.size());
  return s;
}

FileSegmenter::FileSegmenter(std::filesystem::path folder, cv::Size image_size)
    : folder_(std::move(folder)), image_size_(image_size) {
  if (!std::filesystem::is_directory(folder_))
    throw Error(folder_.string() + ": the instance-mask folder does not exist");
}

void FileSegmenter::Validate(const std::vector<std::filesystem::path>& rgb_paths) const {
  for (const auto& rgb : rgb_paths) {
    const auto path = folder_ / rgb.filename();
    if (!std::filesystem::exists(path))
      throw Error(path.string() + ": no instance mask for " + rgb.filename().string());
    const PngHeader h = ReadPngHeader(path);
    if (h.width != image_size_.width || h.height != image_size_.height) {
      throw Error(fmt::format("{}: instance mask is {}x{}, the images are {}x{}", path.string(),
                              h.width, h.height, image_size_.width, image_size_.height));
    }
    if (h.colour_type != 0)  // 0 = greyscale
      throw Error(path.string() + ": an instance mask must be a single-channel PNG");
  }
}

Segmentation FileSegmenter::Segment(const FrontEndFrame& frame) {
  const auto path = folder_ / frame.rgb_path.filename();
  const cv::Mat ids = ReadImage(path, cv::IMREAD_UNCHANGED);
  if (ids.empty()) throw Error(path.string() + ": cannot read the instance mask");
  if (ids.size() != image_size_ || ids.channels() != 1)
    throw Error(path.string() + ": instance mask of the wrong size or channel count");
  return SegmentationFromInstanceIds(ids);
}

}  // namespace sdoslam
