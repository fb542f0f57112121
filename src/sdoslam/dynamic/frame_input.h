#pragma once

#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>

namespace sdoslam {

// What the dynamic-object front end sees of one frame.
struct FrontEndFrame {
  size_t index = 0;
  double timestamp = 0;
  std::filesystem::path rgb_path;  // file backends find their per-frame data by its file name
  cv::Mat bgr;                     // CV_8UC3
  cv::Mat depth;                   // CV_32F metres, 0 = none; may be empty
  cv::Mat gray;                    // CV_8UC1, bgr in grey where the caller has it; may be empty
};

// Per-pixel and per-feature classes of the front end (and of the consistency check, which runs
// in tracking). Tracking uses kStatic only.
enum DynamicLabel : uint8_t {
  kStatic = 0,
  kKnownMovable = 1,   // a movable known class (person, animal, vehicle), moving or not
  kMovingUnknown = 2,  // no known class, selected by motion
  kSceneFlow = 3,      // judged moving by tracking's scene-flow consistency check
};
const char* ToString(DynamicLabel label);

}  // namespace sdoslam
