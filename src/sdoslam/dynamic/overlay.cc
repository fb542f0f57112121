#include "sdoslam/dynamic/overlay.h"

#include <fmt/format.h>

#include <opencv2/imgproc.hpp>

namespace sdoslam {

cv::Mat DrawOverlay(const cv::Mat& bgr, const cv::Mat& labels, const SdoResult* result,
                    const std::vector<cv::Point2f>& features,
                    const std::vector<uint8_t>& feature_labels) {
  cv::Mat out = bgr.clone();
  const cv::Vec3b known(0, 140, 255), unknown(255, 0, 255), scene_flow(255, 80, 0);
  for (int y = 0; y < out.rows; ++y) {
    const uint8_t* l = labels.ptr<uint8_t>(y);
    cv::Vec3b* p = out.ptr<cv::Vec3b>(y);
    for (int x = 0; x < out.cols; ++x) {
      if (l[x] == kStatic) continue;
      const cv::Vec3b& tint = l[x] == kKnownMovable ? known
                              : l[x] == kSceneFlow  ? scene_flow
                                                    : unknown;
      for (int c = 0; c < 3; ++c) p[x][c] = static_cast<uint8_t>((p[x][c] + tint[c]) / 2);
    }
  }
  if (result != nullptr) {
    const cv::Mat& seg = result->segments.labels;
    cv::Mat outline(seg.size(), CV_8U, cv::Scalar(0));
    for (int y = 0; y + 1 < seg.rows; ++y) {
      for (int x = 0; x + 1 < seg.cols; ++x) {
        const int s = seg.at<int>(y, x);
        if (s != seg.at<int>(y, x + 1) || s != seg.at<int>(y + 1, x))
          outline.at<uint8_t>(y, x) = 255;
      }
    }
    cv::Mat outline_full, boundary_full;
    cv::resize(outline, outline_full, out.size(), 0, 0, cv::INTER_NEAREST);
    cv::resize(result->boundary_mask, boundary_full, out.size(), 0, 0, cv::INTER_NEAREST);
    out.setTo(cv::Scalar(160, 160, 160), outline_full);
    out.setTo(cv::Scalar(255, 255, 0), boundary_full);
    for (const Detection& d : result->detections) {
      cv::rectangle(out, d.box, cv::Scalar(0, 255, 255), 2);
      cv::putText(out, fmt::format("{} {:.2f}", d.class_name, d.score),
                  cv::Point(static_cast<int>(d.box.x), std::max(12, static_cast<int>(d.box.y) - 4)),
                  cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
    }
  }
  for (size_t i = 0; i < features.size(); ++i) {
    const bool dynamic = i < feature_labels.size() && feature_labels[i] != kStatic;
    cv::circle(out, features[i], 2, dynamic ? cv::Scalar(0, 0, 255) : cv::Scalar(0, 220, 0), -1,
               cv::LINE_AA);
  }
  return out;
}

}  // namespace sdoslam
