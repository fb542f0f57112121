#pragma once

#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <string>
#include <vector>

namespace sdoslam {

struct OrbOptions {
  int num_features = 1000;    // per frame, over all levels
  double scale_factor = 1.2;  // between pyramid levels
  int num_levels = 8;
  int fast_threshold = 20;     // FAST threshold tried first in each grid cell...
  int min_fast_threshold = 7;  // ...and this one where the first finds nothing (low texture)
  int detection_cell = 35;     // pixels: FAST runs per cell so that every cell gets a chance
  // Where a dynamic front end (or a caller's mask) has labelled the frame, num_features are
  // spread over the static part alone, `budget_margin_px` away from anything dynamic; the rest
  // of the image (the dynamic part and that ring around it) keeps the keypoints one budget over
  // the whole image would place there, on top. A textured mover otherwise takes the budget: a
  // box covering a quarter of blurred, fast-turning real frames (fr1_rpy) drew half of the 1000
  // features, and the static rest was too thin to track. The margin keeps the budget off the
  // mover's outline, where a corner of the static side is made by the mover's edge and moves
  // with it; the ring's own keypoints stay static features, as without the budget
  // (docs/method.md).
  bool budget_on_static = true;
  int budget_margin_px = 8;
  // Throws Error naming the setting by its config path, `path` its section's ("orb.").
  void Check(const std::string& path = "orb.") const;
  // Every setting, as its config key (core/config.h: ReadFields, WriteFields).
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("num_features", o.num_features);
    visit("scale_factor", o.scale_factor);
    visit("num_levels", o.num_levels);
    visit("fast_threshold", o.fast_threshold);
    visit("min_fast_threshold", o.min_fast_threshold);
    visit("detection_cell", o.detection_cell);
    visit("budget_on_static", o.budget_on_static);
    visit("budget_margin_px", o.budget_margin_px);
  }
};

// Where a frame's features go (OrbOptions::budget_on_static). Both CV_8U at the image's size, or
// empty.
struct ExtractionAreas {
  cv::Mat budget;  // non-zero: the pixels num_features are spread over (empty: the whole image)
  cv::Mat extra;   // non-zero: pixels whose keypoints, as a whole-image budget keeps them, come on
                   // top (outside `budget` only)
};

// ORB features as ORB-SLAM uses them: an image pyramid, FAST corners per grid cell with an
// adaptive threshold, an even spatial distribution per level, orientation by intensity
// centroid, 256-bit rBRIEF descriptors (OpenCV computes FAST and the descriptors; detection
// per cell, the distribution and the orientation are ours).
class OrbExtractor {
 public:
  explicit OrbExtractor(const OrbOptions& options);

  // Keypoints in level-0 pixel coordinates (octave = pyramid level, size = patch size at that
  // level, angle in degrees); descriptors: one CV_8U row of 32 bytes per keypoint.
  void Extract(const cv::Mat& gray, std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors,
               const ExtractionAreas& areas = {}) const;

  const OrbOptions& options() const { return options_; }
  const std::vector<double>& scale() const { return scale_; }    // per level
  const std::vector<double>& sigma2() const { return sigma2_; }  // scale²
  const std::vector<double>& inv_sigma2() const { return inv_sigma2_; }

 private:
  // The level's keypoints: its `quota` spread over areas.budget, and those on areas.extra.
  std::vector<cv::KeyPoint> DetectLevel(const cv::Mat& image, int level, int quota,
                                        const ExtractionAreas& areas) const;
  // Descriptors of the keypoints (level coordinates) of a pyramid level, in their order.
  // A feature of level L is described on the image at 1.2^(2L), a patch 1.2^L times larger than
  // the level's own, which is what cv::ORB does with keypoints of octave L on the level image
  // (it samples its own L-th pyramid image of what it is handed): sdoslam was built and tuned
  // with these. Sampling the level image itself, as ORB-SLAM does, matched worse on the real
  // fr2_desk clip: fewer matches and inliers a frame, and about 1 mm more ATE in both modes.
  // The same bits, without building and smoothing the L images below the one sampled.
  cv::Mat DescribeLevel(const cv::Mat& level_image, int level,
                        std::vector<cv::KeyPoint> keypoints) const;

  OrbOptions options_;
  std::vector<double> scale_, sigma2_, inv_sigma2_;
  std::vector<int> features_per_level_;
  std::vector<int> circle_half_width_;  // intensity-centroid patch
  cv::Ptr<cv::ORB> descriptor_;         // DescribeLevel
};

// Selects at most `count` keypoints spread evenly over `area`: the area is divided into the
// coarsest grid whose occupied cells number at least `count`, and the strongest corner of each
// cell is kept (the strongest cells first when there are more cells than `count`).
// An equivalent of ORB-SLAM's quadtree, simpler to reason about. Deterministic.
std::vector<cv::KeyPoint> DistributeEvenly(const std::vector<cv::KeyPoint>& keypoints,
                                           const cv::Rect& area, int count);

// Bits set in a 64-bit word. Written out (SWAR, Hacker's Delight 5-2) because the baseline
// x86-64 target has no POPCNT instruction: __builtin_popcountll and std::popcount become a
// call into libgcc there, which profiled at a tenth of a long run's time.
inline int PopCount64(uint64_t x) {
  x = x - ((x >> 1) & 0x5555555555555555ULL);
  x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
  x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0FULL;
  return static_cast<int>((x * 0x0101010101010101ULL) >> 56);
}

// Hamming distance of two 256-bit descriptors.
inline int DescriptorDistance(const uint8_t* a, const uint8_t* b) {
  int distance = 0;
  for (int w = 0; w < 4; ++w) {
    uint64_t x, y;  // memcpy: descriptor rows need not be 8-byte aligned
    std::memcpy(&x, a + 8 * w, 8);
    std::memcpy(&y, b + 8 * w, 8);
    distance += PopCount64(x ^ y);
  }
  return distance;
}

}  // namespace sdoslam
