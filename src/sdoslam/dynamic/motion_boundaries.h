#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace sdoslam {

// Motion boundaries from the gradient of dense optical flow (paper §III-B, after Papazoglou &
// Ferrari 2013). Neighbouring pixels of one rigid surface share the camera-rotation part of
// their flow, so a large flow gradient marks an object's motion boundary (or a depth gap).
struct MotionBoundaryOptions {
  // k_I: M_I = 1 − exp(−k_I·‖∇φ‖), ‖∇φ‖ in px of flow per px. Tuned on DIS flow of the
  // synthetic scenes: DIS spreads a motion edge over several pixels, so its gradient there is
  // only ~0.2–0.5 px/px (k_I = 5: 16× more boundary on moving outlines than elsewhere).
  double k_magnitude = 5.0;
  double k_orientation = 2.0;  // k_O: M_O = 1 − exp(−k_O·max_j |δθ_ij|), δθ in radians
  double strong = 0.8;         // where M_I exceeds this, M = M_I; elsewhere M = M_I·M_O
  double threshold = 0.5;      // boundary where M exceeds this
  // Flow vectors shorter than this (px) have no reliable direction: δθ counts as 0 there.
  double min_flow_for_angle = 0.5;
  void Check(const std::string& path = "dynamic.boundaries.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("k_magnitude", o.k_magnitude);
    visit("k_orientation", o.k_orientation);
    visit("strong", o.strong);
    visit("threshold", o.threshold);
    visit("min_flow_for_angle", o.min_flow_for_angle);
  }
};

struct MotionBoundaries {
  cv::Mat magnitude_term;    // M_I, CV_32F in [0, 1)
  cv::Mat orientation_term;  // M_O, CV_32F in [0, 1)
  cv::Mat probability;       // M, CV_32F
  cv::Mat mask;              // CV_8U, 255 on boundaries (M > threshold)
};

// `flow`: CV_32FC2, pixel displacement from the previous to the current image.
MotionBoundaries ComputeMotionBoundaries(const cv::Mat& flow,
                                         const MotionBoundaryOptions& options = {});

// ComputeMotionBoundaries(flow, options).mask, the same pixels, at less cost: the angle between
// neighbouring flow vectors, the costly part, is only looked at where M_I alone does not decide
// (M_I in (threshold, strong]). Elsewhere it cannot: M = M_I above strong, and M = M_I·M_O ≤ M_I
// with M_O ≤ 1 below.
cv::Mat MotionBoundaryMask(const cv::Mat& flow, const MotionBoundaryOptions& options = {});

}  // namespace sdoslam
