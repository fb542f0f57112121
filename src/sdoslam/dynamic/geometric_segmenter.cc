#include "sdoslam/dynamic/geometric_segmenter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd/depth.hpp>
#include <vector>

#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/lab.h"

namespace sdoslam {
namespace {

// Edge values as last_edges() shows them.
constexpr uint8_t kDepthStep = 127;
constexpr uint8_t kConcave = 254;

bool Finite(const cv::Vec3f& v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

}  // namespace

void GeometricSegmenterOptions::Check(const std::string& path) const {
  if (work_width < 16) throw Error(path + "work_width must be at least 16");
  if (depth_step <= 0 || depth_step_min_m < 0)
    throw Error(path + "depth_step > 0 and " + path + "depth_step_min_m ≥ 0 are required");
  if (concave_angle_deg <= 0 || concave_angle_deg >= 90)
    throw Error(path + "concave_angle_deg must lie in (0, 90)");
  if (normal_window != 1 && normal_window != 3 && normal_window != 5 && normal_window != 7)
    throw Error(path + "normal_window must be 1, 3, 5 or 7");
  if (concave_span_px < 1) throw Error(path + "concave_span_px must be at least 1");
  if (min_size < 1 || grow_passes < 0 || max_grow_depth_ratio <= 0)
    throw Error(path + "min_size ≥ 1, " + path + "grow_passes ≥ 0 and " + path +
                "max_grow_depth_ratio > 0");
}

GeometricSegmenter::GeometricSegmenter(const GeometricSegmenterOptions& options,
                                       const cv::Matx33d& K, cv::Size image_size)
    : options_(options) {
  options_.Check();
  if (image_size.width <= 0 || image_size.height <= 0 || K(0, 0) <= 0 || K(1, 1) <= 0)
    throw Error("geometric segmenter: needs the image size and a camera matrix");
  const double scale = static_cast<double>(options_.work_width) / image_size.width;
  work_size_ = cv::Size(options_.work_width,
                        std::max(1, static_cast<int>(std::lround(image_size.height * scale))));
  // Pixel centres: x_work + 0.5 = (x + 0.5) · scale.
  K_work_ = cv::Matx33d(K(0, 0) * scale, 0, (K(0, 2) + 0.5) * scale - 0.5,  //
                        0, K(1, 1) * scale, (K(1, 2) + 0.5) * scale - 0.5,  //
                        0, 0, 1);
  normals_ = cv::rgbd::RgbdNormals::create(work_size_.height, work_size_.width, CV_32F,
                                           cv::Mat(K_work_), options_.normal_window,
                                           cv::rgbd::RgbdNormals::RGBD_NORMALS_METHOD_FALS);
}

Segmentation GeometricSegmenter::Segment(const FrontEndFrame& frame) {
  Segmentation s;
  // Fresh images each frame: the labels travel on with the result and callers may keep
  // last_edges(), so neither may be overwritten by the next frame.
  last_edges_ = cv::Mat(work_size_, CV_8U, cv::Scalar(0));
  if (frame.depth.empty()) {  // no geometry, no segments
    s.labels = cv::Mat(work_size_, CV_32S, cv::Scalar(-1));
    return s;
  }
  // The work images are members: same size every frame, so OpenCV reuses their buffers.
  cv::resize(frame.depth, z_, work_size_, 0, 0, cv::INTER_NEAREST);
  cv::resize(frame.bgr, bgr_, work_size_, 0, 0, cv::INTER_AREA);
  cv::rgbd::depthTo3d(z_, cv::Mat(K_work_), points_);
  (*normals_)(points_, normals_out_);

  MarkDepthSteps();
  OrientNormals();
  MarkCreases();
  cv::Mat labels_image(work_size_, CV_32S);
  s.count = LabelRegions(&labels_image);
  GrowRegions(labels_image.ptr<int>());
  s.labels = labels_image;
  return s;
}

void GeometricSegmenter::MarkDepthSteps() {
  const int W = work_size_.width, H = work_size_.height;
  const cv::Mat& z = z_;
  // Edges: depth steps between neighbours (a row, a column and both diagonals), and concave
  // creases where the normals differ by more than concave_angle_deg and each side lies on the
  // other's front side (a convex fold puts each behind the other's tangent plane).
  const double depth_step = options_.depth_step, depth_step_min_m = options_.depth_step_min_m;
  const auto is_step = [&](float zi, float zj) {
    if (!(zj > 0)) return false;
    const double step = std::max(depth_step * std::min(zi, zj), depth_step_min_m);
    return std::abs(zi - zj) > step;
  };
  cv::Mat& edges = last_edges_;
  for (int y = 0; y < H; ++y) {
    const float* zr = z.ptr<float>(y);
    uint8_t* er = edges.ptr<uint8_t>(y);
    const bool below = y + 1 < H;
    const float* zb = below ? z.ptr<float>(y + 1) : nullptr;
    uint8_t* eb = below ? edges.ptr<uint8_t>(y + 1) : nullptr;
    for (int x = 0; x < W; ++x) {
      const float zi = zr[x];
      if (!(zi > 0)) continue;
      if (x + 1 < W && is_step(zi, zr[x + 1])) er[x] = er[x + 1] = kDepthStep;
      if (!below) continue;
      if (is_step(zi, zb[x])) er[x] = eb[x] = kDepthStep;
      if (x + 1 < W && is_step(zi, zb[x + 1])) er[x] = eb[x + 1] = kDepthStep;
      if (x > 0 && is_step(zi, zb[x - 1])) er[x] = eb[x - 1] = kDepthStep;
    }
  }
}

void GeometricSegmenter::OrientNormals() {
  // The crease test below looks at every pixel's normal from several centres: each normal is
  // turned towards the camera (the origin) once, and the normal of a pixel without depth or
  // without a finite normal is made unusable once. The work images are continuous (allocated by
  // create()), so the loops below index them as flat arrays.
  CV_Assert(z_.isContinuous() && points_.isContinuous() && normals_out_.isContinuous() &&
            last_edges_.isContinuous());
  const int size = work_size_.area();
  const float* zf = z_.ptr<float>();
  const cv::Vec3f* points = points_.ptr<cv::Vec3f>();
  cv::Vec3f* normals = normals_out_.ptr<cv::Vec3f>();
  // Unusable: NaN, which fails every comparison of the crease test below, so that one
  // comparison says both "usable" and "sharp" and a flat surface (the common case) is decided by
  // a dot product alone (a look-up table of usable pixels before: perf had the test at a third
  // of the segmenter's own time on real frames, most of it mispredicted branches).
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int i = 0; i < size; ++i) {
    if (!(zf[i] > 0 && Finite(normals[i]))) {
      normals[i] = cv::Vec3f(nan, nan, nan);
    } else if (normals[i].dot(points[i]) > 0) {
      normals[i] = -normals[i];
    }
  }
}

void GeometricSegmenter::MarkCreases() {
  const int W = work_size_.width, H = work_size_.height;
  const float* zf = z_.ptr<float>();
  const cv::Vec3f* points = points_.ptr<cv::Vec3f>();
  const cv::Vec3f* normals = normals_out_.ptr<cv::Vec3f>();
  uint8_t* edge = last_edges_.ptr<uint8_t>();
  // Creases: the pixels on either side of each pixel, concave_span_px away along a row, a column
  // or a diagonal, are compared, and the pixel is an edge when the fold between them is concave
  // and sharp. Looking across the pixel (not from it) gives a band of edge pixels that closes
  // the crease line; normals next to a crease are blends of both planes (the normal window
  // straddles it), the pixels span away are on the planes themselves.
  // The same pass marks the region pixels (depth and no edge) for the connected components.
  const float cos_concave = static_cast<float>(std::cos(options_.concave_angle_deg * CV_PI / 180));
  const int span = options_.concave_span_px;
  // The pixels compared across pixel i along a direction are i − offset and i + offset.
  const int along_row = span, along_column = span * W;
  const int down_right = along_column + along_row, up_right = along_row - along_column;
  const auto concave = [&](int i, int offset) {
    const int a = i - offset, b = i + offset;
    const cv::Vec3f &na = normals[a], &nb = normals[b];
    // Not sharp, or either normal NaN (unusable).
    if (!(na.dot(nb) < cos_concave)) return false;
    // Concave: each lies on the front side of the other's tangent plane.
    const cv::Vec3f d = points[b] - points[a];
    return d.dot(na) > 0 && -d.dot(nb) > 0;
  };
  inside_.create(work_size_, CV_8U);
  uint8_t* inside = inside_.ptr<uint8_t>();
  for (int y = 0; y < H; ++y) {
    const bool rows_fit = y - span >= 0 && y + span < H;
    for (int x = 0, i = y * W; x < W; ++x, ++i) {
      inside[i] = 0;
      if (!(zf[i] > 0) || edge[i] != 0) continue;
      // Near the border only the directions that fit are used (a crease must reach it).
      const bool columns_fit = x - span >= 0 && x + span < W;
      if ((columns_fit && concave(i, along_row)) || (rows_fit && concave(i, along_column)) ||
          (columns_fit && rows_fit && (concave(i, down_right) || concave(i, up_right)))) {
        edge[i] = kConcave;
        continue;
      }
      inside[i] = 1;
    }
  }
}

int GeometricSegmenter::LabelRegions(cv::Mat* labels_image) {
  const int size = work_size_.area();
  // Regions: connected pixels with depth and no edge; the small ones are dissolved.
  const int n =
      cv::connectedComponentsWithStats(inside_, components_, stats_, centroids_, 4, CV_32S);
  std::vector<int> renumber(n, -1);
  int count = 0;
  for (int c = 1; c < n; ++c) {
    if (stats_.at<int>(c, cv::CC_STAT_AREA) >= options_.min_size) renumber[c] = count++;
  }
  CV_Assert(components_.isContinuous() && bgr_.isContinuous());
  int* labels = labels_image->ptr<int>();
  const int* components = components_.ptr<int>();
  candidates_.clear();
  for (int i = 0; i < size; ++i) {
    labels[i] = renumber[components[i]];
    if (labels[i] < 0) candidates_.push_back(i);
  }
  return count;
}

void GeometricSegmenter::GrowRegions(int* labels) {
  const int W = work_size_.width, H = work_size_.height, size = W * H;
  const float* zf = z_.ptr<float>();
  // Growth: an unlabelled pixel takes the label of the 4-neighbour nearest in depth (within
  // max_grow_depth_ratio), or, where either has no depth, nearest in colour. Each pass reads the
  // previous one's labels, so the result does not depend on the scan order: a pass collects its
  // new labels and writes them at its end. A pixel's choice depends only on its neighbours'
  // labels, so after the first pass only the unlabelled neighbours of the pixels the previous
  // pass labelled can change; the others (inside large holes, or next to segments too far away
  // in depth) are not looked at again.
  // Colours (L*a*b*) are compared only where a pixel or its neighbour has no depth, a few
  // pixels a frame: each is converted when first needed (converting the whole image was 1.3 %
  // of sdo's instructions on fr2_desk_50).
  const cv::Vec3b* bgr = bgr_.ptr<cv::Vec3b>();
  colour_.resize(size);
  has_colour_.assign(size, 0);
  const auto colour = [&](int i) -> const cv::Vec3f& {
    if (!has_colour_[i]) {
      colour_[i] = BgrPixelToLab(bgr[i]);
      has_colour_[i] = 1;
    }
    return colour_[i];
  };
  const double max_ratio = options_.max_grow_depth_ratio;
  visited_.assign(size, -1);
  for (int pass = 0; pass < options_.grow_passes && !candidates_.empty(); ++pass) {
    grown_.clear();
    for (const int i : candidates_) {
      const int x = i % W, y = i / W;
      const float zi = zf[i];
      double best_cost = std::numeric_limits<double>::infinity();
      int best = -1;
      // The neighbours in the order left, right, up, down (the first of equal costs wins).
      const int neighbours[4] = {x > 0 ? i - 1 : -1, x + 1 < W ? i + 1 : -1, y > 0 ? i - W : -1,
                                 y + 1 < H ? i + W : -1};
      for (const int j : neighbours) {
        if (j < 0 || labels[j] < 0) continue;
        const float zn = zf[j];
        double cost;
        if (zi > 0 && zn > 0) {
          cost = std::abs(zi - zn) / zi;
          if (cost > max_ratio) continue;
        } else {
          cost = 1.0 + cv::norm(colour(i) - colour(j));  // after any depth match
        }
        if (cost < best_cost) best_cost = cost, best = labels[j];
      }
      if (best >= 0) grown_.push_back({i, best});
    }
    if (grown_.empty()) break;
    for (const auto& [i, label] : grown_) labels[i] = label;
    candidates_.clear();
    for (const auto& [i, label] : grown_) {
      const int x = i % W;
      for (const int j : {x > 0 ? i - 1 : -1, x + 1 < W ? i + 1 : -1, i - W, i + W}) {
        if (j < 0 || j >= size || labels[j] >= 0 || visited_[j] == pass) continue;
        visited_[j] = pass;
        candidates_.push_back(j);
      }
    }
  }
}

}  // namespace sdoslam
