#pragma once

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "sdoslam/dynamic/frame_input.h"

namespace sdoslam {

// Class-agnostic instance segments covering (part of) the image.
struct Segmentation {
  // CV_32S segment index in [0, count), −1 = no segment; at image size or a reduced size of
  // the same aspect (consumers resize with nearest neighbour).
  cv::Mat labels;
  int count = 0;
};

class Segmenter {
 public:
  virtual ~Segmenter() = default;
  virtual Segmentation Segment(const FrontEndFrame& frame) = 0;
};

// The default, needs no files: Felzenszwalb–Huttenlocher graph segmentation (OpenCV ximgproc) of
// a reduced-resolution image whose pixel vectors are (weighted Lab colour, weighted log depth).
// The log-depth channel makes a 10 % depth step cost as much as a large colour step, so objects
// separate from what is behind them by depth even when textured like it; the small colour weight
// keeps texture blocks of one surface together.
struct RgbdSegmenterOptions {
  int work_width = 160;         // px; segmentation runs at this width (aspect kept)
  double sigma = 0.5;           // Gaussian pre-smoothing of the graph segmentation
  double k = 300;               // merge threshold: larger = larger segments
  int min_size = 50;            // px at work resolution; smaller segments are merged
  double colour_weight = 0.5;   // per Lab unit
  double depth_weight = 200.0;  // per unit of log(depth): 0.1 ≈ a 10 % step
  void Check(
      const std::string& path = "dynamic.segmenter.rgbd.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("work_width", o.work_width);
    visit("sigma", o.sigma);
    visit("k", o.k);
    visit("min_size", o.min_size);
    visit("colour_weight", o.colour_weight);
    visit("depth_weight", o.depth_weight);
  }
};

class RgbdSegmenter : public Segmenter {
 public:
  explicit RgbdSegmenter(const RgbdSegmenterOptions& options = {});
  ~RgbdSegmenter() override;
  Segmentation Segment(const FrontEndFrame& frame) override;  // at work resolution

 private:
  struct Impl;
  RgbdSegmenterOptions options_;
  std::unique_ptr<Impl> impl_;
};

// Per-frame instance-mask PNGs computed elsewhere: `folder`/<rgb file name>, 8- or 16-bit,
// one value per instance, 0 = no instance. Validate() checks every file before a run starts.
class FileSegmenter : public Segmenter {
 public:
  FileSegmenter(std::filesystem::path folder, cv::Size image_size);
  // Throws Error naming the first missing file or the first PNG of the wrong size or format.
  void Validate(const std::vector<std::filesystem::path>& rgb_paths) const;
  Segmentation Segment(const FrontEndFrame& frame) override;

 private:
  std::filesystem::path folder_;
  cv::Size image_size_;
};

// Renumbers arbitrary non-negative instance ids (0 = none) to segments 0..count-1.
Segmentation SegmentationFromInstanceIds(const cv::Mat& ids);

}  // namespace sdoslam
