#include "sdoslam/dynamic/motion_boundaries.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"

namespace sdoslam {

void MotionBoundaryOptions::Check(const std::string& path) const {
  if (!(k_magnitude > 0)) throw Error(path + "k_magnitude must be positive");
  if (!(k_orientation > 0)) throw Error(path + "k_orientation must be positive");
  if (!(strong > 0 && strong < 1)) throw Error(path + "strong must be in (0, 1)");
  if (!(threshold > 0 && threshold < 1)) throw Error(path + "threshold must be in (0, 1)");
  if (!(min_flow_for_angle >= 0)) throw Error(path + "min_flow_for_angle must be >= 0");
}

namespace {

// mask_only: the largest angle is only computed where it can decide the mask (see
// MotionBoundaryMask); elsewhere it counts as 0, so orientation_term and probability there are
// not the full function's.
MotionBoundaries Compute(const cv::Mat& flow, const MotionBoundaryOptions& options,
                         bool mask_only) {
  options.Check();
  CV_Assert(flow.type() == CV_32FC2);
  cv::Mat uv[2];
  cv::split(flow, uv);
  // Sobel derivatives of both flow components (scaled to px per px: the 3x3 kernel sums to 8).
  cv::Mat gradient_sq = cv::Mat::zeros(flow.size(), CV_32F);
  for (const cv::Mat& component : uv) {
    cv::Mat dx, dy;
    cv::Sobel(component, dx, CV_32F, 1, 0, 3, 1.0 / 8.0);
    cv::Sobel(component, dy, CV_32F, 0, 1, 3, 1.0 / 8.0);
    gradient_sq += dx.mul(dx) + dy.mul(dy);
  }
  cv::Mat gradient;
  cv::sqrt(gradient_sq, gradient);
  MotionBoundaries out;
  cv::exp(-options.k_magnitude * gradient, out.magnitude_term);
  out.magnitude_term = 1.0 - out.magnitude_term;

  // Largest angle between a pixel's flow vector and its 8 neighbours'. Directions are computed
  // once (cv::phase) and compared as wrapped differences: the same angle as acos of the
  // normalised dot product, at a fraction of the cost.
  const int rows = flow.rows, cols = flow.cols;
  cv::Mat direction, length;
  cv::phase(uv[0], uv[1], direction);
  cv::magnitude(uv[0], uv[1], length);
  cv::Mat max_angle = cv::Mat::zeros(flow.size(), CV_32F);
  const float min_flow = static_cast<float>(options.min_flow_for_angle);
  // The bounds as cv::compare applies them to a float image below (the scalar converted to float).
  const float strong = static_cast<float>(options.strong);
  const float threshold = static_cast<float>(options.threshold);
  constexpr float kTwoPi = static_cast<float>(2 * M_PI);
  for (int y = 0; y < rows; ++y) {
    const float* theta = direction.ptr<float>(y);
    const float* norm = length.ptr<float>(y);
    const float* magnitude_term = out.magnitude_term.ptr<float>(y);
    float* out_row = max_angle.ptr<float>(y);
    for (int x = 0; x < cols; ++x) {
      if (norm[x] < min_flow) continue;
      if (mask_only && !(magnitude_term[x] > threshold && !(magnitude_term[x] > strong))) continue;
      float largest = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        const int yy = y + dy;
        if (yy < 0 || yy >= rows) continue;
        const float* theta_n = direction.ptr<float>(yy);
        const float* norm_n = length.ptr<float>(yy);
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx;
          if ((dx == 0 && dy == 0) || xx < 0 || xx >= cols || norm_n[xx] < min_flow) continue;
          float d = std::abs(theta[x] - theta_n[xx]);
          if (d > kTwoPi - d) d = kTwoPi - d;
          largest = std::max(largest, d);
        }
      }
      out_row[x] = largest;
    }
  }
  cv::exp(-options.k_orientation * max_angle, out.orientation_term);
  out.orientation_term = 1.0 - out.orientation_term;

  out.probability = out.magnitude_term.mul(out.orientation_term);
  out.magnitude_term.copyTo(out.probability, out.magnitude_term > options.strong);
  out.mask = out.probability > options.threshold;
  return out;
}

}  // namespace

MotionBoundaries ComputeMotionBoundaries(const cv::Mat& flow,
                                         const MotionBoundaryOptions& options) {
  return Compute(flow, options, /*mask_only=*/false);
}

cv::Mat MotionBoundaryMask(const cv::Mat& flow, const MotionBoundaryOptions& options) {
  return Compute(flow, options, /*mask_only=*/true).mask;
}

}  // namespace sdoslam
