#include "sdoslam/features/orb_extractor.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

constexpr int kPatchSize = 31;
constexpr int kHalfPatch = 15;
// cv::ORB's pyramid step, which decides the scale coarse levels are described at (DescribeLevel).
constexpr float kOpenCvPyramidStep = 1.2f;
constexpr int kBorder = 19;  // descriptors need the rotated 31-px patch plus smoothing

bool Stronger(const cv::KeyPoint& a, const cv::KeyPoint& b) {
  if (a.response != b.response) return a.response > b.response;
  if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;  // ties broken by position: deterministic
  return a.pt.x < b.pt.x;
}

// The `count` strongest of `keypoints`, strongest first.
std::vector<cv::KeyPoint> Strongest(std::vector<cv::KeyPoint> keypoints, int count) {
  std::sort(keypoints.begin(), keypoints.end(), Stronger);
  if (static_cast<int>(keypoints.size()) > count) keypoints.resize(static_cast<size_t>(count));
  return keypoints;
}

}  // namespace

void OrbOptions::Check(const std::string& path) const {
  if (num_features < 10 || num_features > 100000)
    throw Error(path + "num_features must be in 10..100000");
  if (!(scale_factor > 1.0 && scale_factor < 2.0))
    throw Error(path + "scale_factor must be in (1, 2)");
  if (num_levels < 1 || num_levels > 16) throw Error(path + "num_levels must be in 1..16");
  if (fast_threshold < 1 || min_fast_threshold < 1 || min_fast_threshold > fast_threshold) {
    throw Error(path + "fast_threshold and " + path +
                "min_fast_threshold must satisfy 1 <= min <= initial");
  }
  if (detection_cell < 10) throw Error(path + "detection_cell must be >= 10 pixels");
  if (budget_margin_px < 0 || budget_margin_px > 100)
    throw Error(path + "budget_margin_px must be in 0..100 pixels");
}

std::vector<cv::KeyPoint> DistributeEvenly(const std::vector<cv::KeyPoint>& keypoints,
                                           const cv::Rect& area, int count) {
  if (count <= 0 || keypoints.empty()) return {};
  if (static_cast<int>(keypoints.size()) <= count) return keypoints;
  struct Grid {
    int cols, rows;
  };
  const auto grid_of = [&](double cell) {
    return Grid{std::max(1, static_cast<int>(std::ceil(area.width / cell))),
                std::max(1, static_cast<int>(std::ceil(area.height / cell)))};
  };
  const auto cell_of = [&](const cv::KeyPoint& k, double cell, const Grid& grid) {
    const int c = std::clamp(static_cast<int>((k.pt.x - area.x) / cell), 0, grid.cols - 1);
    const int r = std::clamp(static_cast<int>((k.pt.y - area.y) / cell), 0, grid.rows - 1);
    return static_cast<size_t>(r * grid.cols + c);
  };
  // The number of occupied cells grows as cells shrink: find the coarsest grid that has
  // enough of them (bisection on the cell size). The bisection needs only their number: each
  // grid's cells are marked with the try's number in one array, which is allocated once (a
  // selection per try, with its own array, was 2 % of an sdo run's time).
  // One-pixel cells are the fallback when no coarser grid has enough; their grid is the image's
  // size (a 640 x 480 level: 300,000 cells).
  std::vector<int> marked;  // the try that last found a keypoint in the cell
  const auto occupied_cells = [&](double cell, int attempt) {
    const Grid grid = grid_of(cell);
    const size_t cells = static_cast<size_t>(grid.cols) * static_cast<size_t>(grid.rows);
    if (marked.size() < cells) marked.resize(cells, -1);
    int occupied = 0;
    for (const cv::KeyPoint& k : keypoints) {
      int& mark = marked[cell_of(k, cell, grid)];
      if (mark != attempt) mark = attempt, ++occupied;
    }
    return occupied;
  };
  double lo = 1.0, hi = std::max(area.width, area.height), chosen = 1.0;
  for (int attempt = 0; attempt < 20; ++attempt) {
    const double mid = 0.5 * (lo + hi);
    if (occupied_cells(mid, attempt) >= count) {
      lo = chosen = mid;
    } else {
      hi = mid;
    }
  }
  // The strongest keypoint of each occupied cell of the chosen grid, in cell order.
  const Grid grid = grid_of(chosen);
  std::vector<int> best(static_cast<size_t>(grid.cols) * static_cast<size_t>(grid.rows), -1);
  for (int k = 0; k < static_cast<int>(keypoints.size()); ++k) {
    int& slot = best[cell_of(keypoints[k], chosen, grid)];
    if (slot < 0 || Stronger(keypoints[k], keypoints[slot])) slot = k;
  }
  std::vector<cv::KeyPoint> selected;
  for (int k : best)
    if (k >= 0) selected.push_back(keypoints[k]);
  return Strongest(std::move(selected), count);
}

OrbExtractor::OrbExtractor(const OrbOptions& options) : options_(options) {
  options_.Check();
  const int levels = options_.num_levels;
  for (int l = 0; l < levels; ++l) {
    scale_.push_back(std::pow(options_.scale_factor, l));
    sigma2_.push_back(scale_.back() * scale_.back());
    inv_sigma2_.push_back(1.0 / sigma2_.back());
  }
  // Features per level in geometric progression: each level gets as many per area as level 0.
  const double f = 1.0 / options_.scale_factor;
  double per_level = options_.num_features * (1 - f) / (1 - std::pow(f, levels));
  int total = 0;
  for (int l = 0; l < levels - 1; ++l) {
    features_per_level_.push_back(static_cast<int>(std::lround(per_level)));
    total += features_per_level_.back();
    per_level *= f;
  }
  features_per_level_.push_back(std::max(options_.num_features - total, 0));
  for (int v = 0; v <= kHalfPatch; ++v) {
    circle_half_width_.push_back(
        static_cast<int>(std::lround(std::sqrt(kHalfPatch * kHalfPatch - v * v))));
  }
  descriptor_ = cv::ORB::create(1 << 20, kOpenCvPyramidStep, 1, /*edgeThreshold=*/0, 0, 2,
                                cv::ORB::HARRIS_SCORE, kPatchSize, options_.fast_threshold);
}

std::vector<cv::KeyPoint> OrbExtractor::DetectLevel(const cv::Mat& image, int level, int quota,
                                                    const ExtractionAreas& areas) const {
  const cv::Rect area(kBorder, kBorder, image.cols - 2 * kBorder, image.rows - 2 * kBorder);
  std::vector<cv::KeyPoint> all;
  if (area.width < 8 || area.height < 8) return all;
  const int cell = options_.detection_cell;
  std::vector<cv::KeyPoint> found;
  for (int y = area.y; y < area.y + area.height; y += cell) {
    for (int x = area.x; x < area.x + area.width; x += cell) {
      // 3 extra pixels on each side: FAST needs a 7x7 neighbourhood around a corner.
      const cv::Rect inner(x, y, std::min(cell, area.x + area.width - x),
                           std::min(cell, area.y + area.height - y));
      const cv::Rect outer = cv::Rect(inner.x - 3, inner.y - 3, inner.width + 6, inner.height + 6) &
                             cv::Rect(0, 0, image.cols, image.rows);
      for (int threshold : {options_.fast_threshold, options_.min_fast_threshold}) {
        found.clear();
        cv::FAST(image(outer), found, threshold, true);
        bool any = false;
        for (cv::KeyPoint k : found) {
          k.pt.x += static_cast<float>(outer.x);
          k.pt.y += static_cast<float>(outer.y);
          if (!inner.contains(cv::Point(static_cast<int>(k.pt.x), static_cast<int>(k.pt.y))))
            continue;
          all.push_back(k);
          any = true;
        }
        if (any) break;
      }
    }
  }
  if (areas.budget.empty()) return DistributeEvenly(all, area, quota);
  const auto on = [&](const cv::Mat& mask, const cv::KeyPoint& k) {
    const double s = scale_[static_cast<size_t>(level)];
    const int x = std::clamp(static_cast<int>(std::lround(k.pt.x * s)), 0, mask.cols - 1);
    const int y = std::clamp(static_cast<int>(std::lround(k.pt.y * s)), 0, mask.rows - 1);
    return mask.at<uint8_t>(y, x) != 0;
  };
  std::vector<cv::KeyPoint> in_budget;
  for (const cv::KeyPoint& k : all)
    if (on(areas.budget, k)) in_budget.push_back(k);
  std::vector<cv::KeyPoint> kept = DistributeEvenly(in_budget, area, quota);
  if (!areas.extra.empty()) {
    for (const cv::KeyPoint& k : DistributeEvenly(all, area, quota))
      if (on(areas.extra, k) && !on(areas.budget, k)) kept.push_back(k);
  }
  return kept;
}

cv::Mat OrbExtractor::DescribeLevel(const cv::Mat& level_image, int level,
                                    std::vector<cv::KeyPoint> keypoints) const {
  if (keypoints.empty()) return {};  // vconcat in Extract leaves such levels out
  // The L-th image of cv::ORB's pyramid over the level image, made as cv::ORB makes it (each
  // from the one before, 1.2 smaller, sizes rounded from the level image's), and the
  // keypoints moved onto it as cv::ORB moves them (float products); for the first level, the
  // level image itself. Described there as octave 0, cv::ORB smooths and borders that one
  // image alone; its border is the same 23 pixels (the rotated patch's, larger than any edge
  // threshold here), and edge threshold 0 keeps it from dropping keypoints that are near this
  // small image's edge but were not near the level image's (DetectLevel keeps every keypoint
  // kBorder pixels inside the level image).
  const auto opencv_scale = [](int j) {
    return static_cast<float>(std::pow(static_cast<double>(kOpenCvPyramidStep), j));
  };
  cv::Mat layer = level_image;
  for (int j = 1; j <= level; ++j) {
    const float s = opencv_scale(j);
    cv::Mat smaller;
    cv::resize(layer, smaller,
               cv::Size(cvRound(static_cast<float>(level_image.cols) / s),
                        cvRound(static_cast<float>(level_image.rows) / s)),
               0, 0, cv::INTER_LINEAR_EXACT);
    layer = smaller;
  }
  const float to_layer = 1.f / opencv_scale(level);
  for (cv::KeyPoint& k : keypoints) k.pt *= to_layer;
  const size_t count = keypoints.size();
  cv::Mat descriptors;
  descriptor_->compute(layer, keypoints, descriptors);
  CV_Assert(keypoints.size() == count);
  return descriptors;
}

void OrbExtractor::Extract(const cv::Mat& gray, std::vector<cv::KeyPoint>* keypoints,
                           cv::Mat* descriptors, const ExtractionAreas& areas) const {
  CV_Assert(gray.type() == CV_8UC1);
  for (const cv::Mat* mask : {&areas.budget, &areas.extra})
    CV_Assert(mask->empty() || (mask->type() == CV_8UC1 && mask->size() == gray.size()));
  keypoints->clear();
  std::vector<cv::Mat> level_descriptors;
  cv::Mat level_image = gray;
  for (int level = 0; level < options_.num_levels; ++level) {
    if (level > 0) {
      const cv::Size size(static_cast<int>(std::lround(gray.cols / scale_[level])),
                          static_cast<int>(std::lround(gray.rows / scale_[level])));
      if (size.width < 2 * kBorder + 8 || size.height < 2 * kBorder + 8) break;
      cv::resize(gray, level_image, size, 0, 0, cv::INTER_LINEAR);
    }
    std::vector<cv::KeyPoint> kps =
        DetectLevel(level_image, level, features_per_level_[level], areas);
    // Orientation by intensity centroid over a circular patch.
    for (cv::KeyPoint& k : kps) {
      const int cx = static_cast<int>(std::lround(k.pt.x)),
                cy = static_cast<int>(std::lround(k.pt.y));
      int m01 = 0, m10 = 0;
      for (int v = -kHalfPatch; v <= kHalfPatch; ++v) {
        const uint8_t* row = level_image.ptr<uint8_t>(cy + v);
        const int w = circle_half_width_[static_cast<size_t>(std::abs(v))];
        for (int u = -w; u <= w; ++u) {
          const int value = row[cx + u];
          m10 += u * value;
          m01 += v * value;
        }
      }
      float angle = static_cast<float>(
          std::atan2(static_cast<double>(m01), static_cast<double>(m10)) * 180.0 / CV_PI);
      if (angle < 0) angle += 360.0f;
      k.angle = angle;
    }
    // OpenCV smooths the image before sampling the descriptor pairs, as the ORB paper does.
    const cv::Mat desc = DescribeLevel(level_image, level, kps);
    for (cv::KeyPoint& k : kps) {
      k.pt *= static_cast<float>(scale_[level]);
      k.octave = level;
      k.size = static_cast<float>(kPatchSize * scale_[level]);
    }
    keypoints->insert(keypoints->end(), kps.begin(), kps.end());
    // A level without corners (a plain wall, a covered lens) gives an empty matrix, which
    // vconcat refuses: leave it out.
    if (!kps.empty()) level_descriptors.push_back(desc);
  }
  if (level_descriptors.empty()) {
    *descriptors = cv::Mat(0, 32, CV_8U);
  } else {
    cv::vconcat(level_descriptors, *descriptors);
  }
  CV_Assert(descriptors->rows == static_cast<int>(keypoints->size()));
}

}  // namespace sdoslam
