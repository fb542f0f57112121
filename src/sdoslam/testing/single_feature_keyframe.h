#pragma once

// Keyframes with exactly one feature, for tests and benchmarks of a map point's many observers
// (descriptor choice, covisibility): ORB finds nothing on a blank image, so the keyframe holds
// only the feature given here. Header-only.

#include <memory>

#include "sdoslam/map/map.h"

namespace sdoslam::testing {

// Adds keyframe `index` (timestamp `index` s) of a blank 640×480 image at 2 m depth, with one
// feature at the image centre, 2 m deep, whose descriptor is `descriptor` (1×32 CV_8U), to `map`.
inline KeyFrame* AddSingleFeatureKeyFrame(Map& map, size_t index, const cv::Mat& descriptor,
                                          const std::shared_ptr<const FrameGeometry>& geometry,
                                          const OrbExtractor& extractor) {
  static const cv::Mat blank(480, 640, CV_8UC3, cv::Scalar::all(0));
  static const cv::Mat depth(480, 640, CV_32F, cv::Scalar(2.0f));
  Frame frame(index, static_cast<double>(index), blank, depth, geometry, extractor);
  frame.keypoints = {cv::KeyPoint(320, 240, 31)};
  frame.descriptors = descriptor;
  frame.undistorted = {cv::Point2f(320, 240)};
  frame.depth = {2.0f};
  frame.right_u = {-1.0f};
  frame.map_points = {nullptr};
  frame.outlier = {false};
  frame.label = {0};
  frame.colors = {cv::Vec3b(0, 0, 0)};
  return map.AddKeyFrame(std::move(frame));
}

}  // namespace sdoslam::testing
