#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "sdoslam/dynamic/classifier.h"

namespace sdoslam {

// The picture a user tunes the front end with: dynamic regions tinted (known-movable orange,
// moving-unknown magenta), segment outlines in grey, motion boundaries in cyan, detection boxes
// with their class, and features (static green, dynamic red). `result` may be null (oracle mode:
// only the label image is drawn).
cv::Mat DrawOverlay(const cv::Mat& bgr, const cv::Mat& labels, const SdoResult* result,
                    const std::vector<cv::Point2f>& features,
                    const std::vector<uint8_t>& feature_labels);

}  // namespace sdoslam
