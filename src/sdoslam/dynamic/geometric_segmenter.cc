#include "sdoslam/dynamic/geometric_segmenter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd/depth.hpp>
#include <vector>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

constexpr uint8_t kDepthStep = 1;
constexpr uint8_t kConcave = 2;

bool Finite(const cv::Vec3f& v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

}  // namespace

void GeometricSegmenterOptions::Check() const {
  if (work_width < 16) throw Error("segmenter.work_width must be at least 16");
  if (depth_step <= 0 || depth_step_min_m < 0)
    throw Error("segmenter: depth_step > 0 and depth_step_min_m ≥ 0 are required");
  if (concave_angle_deg <= 0 || concave_angle_deg >= 90)
    throw Error("segmenter.concave_angle_deg must lie in (0, 90)");
  if (normal_window != 1 && normal_window != 3 && normal_window != 5 && normal_window != 7)
    throw Error("segmenter.normal_window must be 1, 3, 5 or 7");
  if (concave_span_px < 1) throw Error("segmenter.concave_span_px must be at least 1");
  if (min_size < 1 || grow_passes < 0 || max_grow_depth_ratio <= 0)
    throw Error("segmenter: min_size ≥ 1, grow_passes ≥ 0 and max_grow_depth_ratio > 0");
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
  const int W = work_size_.width, H = work_size_.height;
  Segmentation s;
  s.labels = cv::Mat(work_size_, CV_32S, cv::Scalar(-1));
  last_edges_ = cv::Mat(work_size_, CV_8U, cv::Scalar(0));
  if (frame.depth.empty()) return s;  // no geometry, no segments

  cv::Mat z;
  cv::resize(frame.depth, z, work_size_, 0, 0, cv::INTER_NEAREST);
  cv::Mat colour;
  cv::resize(frame.bgr, colour, work_size_, 0, 0, cv::INTER_AREA);
  colour.convertTo(colour, CV_32F, 1.0 / 255.0);
  cv::cvtColor(colour, colour, cv::COLOR_BGR2Lab);

  cv::Mat points, normals;
  cv::rgbd::depthTo3d(z, cv::Mat(K_work_), points);
  (*normals_)(points, normals);

  // Edges: depth steps between neighbours (a row, a column and both diagonals), and concave
  // creases where the normals differ by more than concave_angle_deg and each side lies on the
  // other's front side (a convex fold puts each behind the other's tangent plane).
  const float cos_concave = static_cast<float>(std::cos(options_.concave_angle_deg * CV_PI / 180));
  const int span = options_.concave_span_px;
  cv::Mat& edges = last_edges_;
  for (int y = 0; y < H; ++y) {
    const float* zr = z.ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      const float zi = zr[x];
      if (!(zi > 0)) continue;
      for (const auto& [dx, dy] :
           {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{-1, 1}}) {
        const int xj = x + dx, yj = y + dy;
        if (xj < 0 || xj >= W || yj >= H) continue;
        const float zj = z.at<float>(yj, xj);
        if (!(zj > 0)) continue;
        const double step =
            std::max(options_.depth_step * std::min(zi, zj), options_.depth_step_min_m);
        if (std::abs(zi - zj) > step) {
          edges.at<uint8_t>(y, x) = kDepthStep;
          edges.at<uint8_t>(yj, xj) = kDepthStep;
        }
      }
    }
  }
  // Creases: the pixels on either side of each pixel, concave_span_px away along a row, a column
  // or a diagonal, are compared, and the pixel is an edge when the fold between them is concave
  // and sharp. Looking across the pixel (not from it) gives a band of edge pixels that closes
  // the crease line; normals next to a crease are blends of both planes (the normal window
  // straddles it), the pixels span away are on the planes themselves.
  for (int y = 0; y < H; ++y) {
    for (int x = 0; x < W; ++x) {
      if (!(z.at<float>(y, x) > 0) || edges.at<uint8_t>(y, x) != 0) continue;
      for (const auto& [dx, dy] :
           {std::pair{1, 0}, std::pair{0, 1}, std::pair{1, 1}, std::pair{1, -1}}) {
        const int xa = x - dx * span, ya = y - dy * span, xb = x + dx * span, yb = y + dy * span;
        // Near the border only the directions that fit are used (a crease must reach it).
        if (xa < 0 || xb >= W || std::min(ya, yb) < 0 || std::max(ya, yb) >= H) continue;
        if (!(z.at<float>(ya, xa) > 0) || !(z.at<float>(yb, xb) > 0)) continue;
        cv::Vec3f na = normals.at<cv::Vec3f>(ya, xa), nb = normals.at<cv::Vec3f>(yb, xb);
        if (!Finite(na) || !Finite(nb)) continue;
        const cv::Vec3f pa = points.at<cv::Vec3f>(ya, xa), pb = points.at<cv::Vec3f>(yb, xb);
        if (na.dot(pa) > 0) na = -na;  // normals face the camera (the origin)
        if (nb.dot(pb) > 0) nb = -nb;
        if (na.dot(nb) >= cos_concave) continue;
        // Concave: each lies on the front side of the other's tangent plane.
        const cv::Vec3f d = pb - pa;
        if (d.dot(na) > 0 && -d.dot(nb) > 0) {
          edges.at<uint8_t>(y, x) = kConcave;
          break;
        }
      }
    }
  }

  // Regions: connected pixels with depth and no edge; the small ones are dissolved.
  cv::Mat inside = (z > 0) & (edges == 0);
  cv::Mat components, stats, centroids;
  const int n = cv::connectedComponentsWithStats(inside, components, stats, centroids, 4, CV_32S);
  std::vector<int> renumber(n, -1);
  int count = 0;
  for (int c = 1; c < n; ++c) {
    if (stats.at<int>(c, cv::CC_STAT_AREA) >= options_.min_size) renumber[c] = count++;
  }
  cv::Mat labels(work_size_, CV_32S);
  for (int y = 0; y < H; ++y) {
    const int* in = components.ptr<int>(y);
    int* out = labels.ptr<int>(y);
    for (int x = 0; x < W; ++x) out[x] = renumber[in[x]];
  }

  // Growth: an unlabelled pixel takes the label of the 4-neighbour nearest in depth (within
  // max_grow_depth_ratio), or, where either has no depth, nearest in colour. Each pass reads the
  // previous one's labels, so the result does not depend on the scan order.
  for (int pass = 0; pass < options_.grow_passes; ++pass) {
    cv::Mat next = labels.clone();
    bool changed = false;
    for (int y = 0; y < H; ++y) {
      for (int x = 0; x < W; ++x) {
        if (labels.at<int>(y, x) >= 0) continue;
        const float zi = z.at<float>(y, x);
        const cv::Vec3f ci = colour.at<cv::Vec3f>(y, x);
        double best_cost = std::numeric_limits<double>::infinity();
        int best = -1;
        for (const auto& [dx, dy] :
             {std::pair{-1, 0}, std::pair{1, 0}, std::pair{0, -1}, std::pair{0, 1}}) {
          const int xn = x + dx, yn = y + dy;
          if (xn < 0 || yn < 0 || xn >= W || yn >= H) continue;
          const int ln = labels.at<int>(yn, xn);
          if (ln < 0) continue;
          const float zn = z.at<float>(yn, xn);
          double cost;
          if (zi > 0 && zn > 0) {
            cost = std::abs(zi - zn) / zi;
            if (cost > options_.max_grow_depth_ratio) continue;
          } else {
            cost = 1.0 + cv::norm(ci - colour.at<cv::Vec3f>(yn, xn));  // after any depth match
          }
          if (cost < best_cost) best_cost = cost, best = ln;
        }
        if (best >= 0) {
          next.at<int>(y, x) = best;
          changed = true;
        }
      }
    }
    labels = next;
    if (!changed) break;
  }
  s.labels = labels;
  s.count = count;
  edges *= 255 / 2;  // 1 → 127 (depth step), 2 → 254 (concave crease)
  return s;
}

}  // namespace sdoslam
