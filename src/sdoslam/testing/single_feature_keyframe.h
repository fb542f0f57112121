#pragma once

// Keyframes with exactly one feature, for tests and benchmarks of a map point's many observers
// (descriptor choice, covisibility): ORB finds nothing on a blank image, so the keyframe holds
// only the feature given here. Header-only.

#include <memory>
#include <vector>

#include "sdoslam/map/map.h"

namespace sdoslam::testing {

// Adds keyframe `index` (timestamp `index` s, pose `T_camera_world`) of a blank 640×480 image,
// whose only features are the given ones: feature i lies at `pixels[i]` (undistorted, level 0),
// `depths[i]` metres deep, with descriptor row i of `descriptors` (N×32 CV_8U).
inline KeyFrame* AddKeyFrameWithFeatures(
    Map& map, size_t index, const std::vector<cv::Point2f>& pixels,
    const std::vector<float>& depths, const cv::Mat& descriptors,
    const std::shared_ptr<const FrameGeometry>& geometry, const OrbExtractor& extractor,
    const Eigen::Isometry3d& T_camera_world = Eigen::Isometry3d::Identity()) {
  static const cv::Mat blank(480, 640, CV_8UC3, cv::Scalar::all(0));
  static const cv::Mat depth(480, 640, CV_32F, cv::Scalar(2.0f));
  Frame frame(index, static_cast<double>(index), blank, depth, geometry, extractor);
  const size_t n = pixels.size();
  frame.keypoints.clear();
  for (const cv::Point2f& pixel : pixels) frame.keypoints.emplace_back(pixel, 31.0f);
  frame.descriptors = descriptors;
  frame.undistorted = pixels;
  frame.depth = depths;
  frame.right_u.assign(n, -1.0f);
  frame.map_points.assign(n, nullptr);
  frame.outlier.assign(n, false);
  frame.label.assign(n, 0);
  frame.colors.assign(n, cv::Vec3b(0, 0, 0));
  frame.T_camera_world = T_camera_world;
  return map.AddKeyFrame(std::move(frame));
}

// One feature at the image centre, 2 m deep, whose descriptor is `descriptor` (1×32 CV_8U).
inline KeyFrame* AddSingleFeatureKeyFrame(Map& map, size_t index, const cv::Mat& descriptor,
                                          const std::shared_ptr<const FrameGeometry>& geometry,
                                          const OrbExtractor& extractor) {
  return AddKeyFrameWithFeatures(map, index, {cv::Point2f(320, 240)}, {2.0f}, descriptor, geometry,
                                 extractor);
}

}  // namespace sdoslam::testing
