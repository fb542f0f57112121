#pragma once
// Helpers of the segmenter tests (segmenter_test.cc, geometric_segmenter_test.cc).

#include <map>
#include <opencv2/core.hpp>
#include <string>
#include <utility>

#include "sdoslam/dynamic/frame_input.h"
#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"

namespace sdoslam::testing {

// Best IoU reachable for `object` from whole segments: the union of the segments lying mostly
// (> 50 %) on it.
inline double CoverIou(const cv::Mat& segments, const cv::Mat& object) {
  std::map<int, std::pair<int, int>> on_off;  // segment → (pixels on, pixels off the object)
  for (int y = 0; y < segments.rows; ++y) {
    for (int x = 0; x < segments.cols; ++x) {
      auto& c = on_off[segments.at<int>(y, x)];
      (object.at<uint8_t>(y, x) ? c.first : c.second) += 1;
    }
  }
  int inter = 0, extra = 0;
  for (const auto& [s, c] : on_off) {
    if (s >= 0 && c.first > c.second) {
      inter += c.first;
      extra += c.second;
    }
  }
  const int area = cv::countNonZero(object);
  return static_cast<double>(inter) / (area + extra);
}

inline FrontEndFrame RenderFrame(const std::string& scenario, double t, cv::Mat* instance) {
  const Camera camera(synth::SyntheticCamera());
  const synth::Scenario s = synth::MakeScenario(scenario, 10.0);
  const synth::RenderedView view =
      synth::Render(s.scene, t, synth::CameraPoseAt(s.motion, t, 10.0), camera);
  FrontEndFrame f;
  view.colour.convertTo(f.bgr, CV_8UC3, 255.0);
  f.depth = view.depth;
  *instance = view.instance;
  return f;
}

}  // namespace sdoslam::testing
