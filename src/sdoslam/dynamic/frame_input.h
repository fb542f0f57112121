#pragma once

#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>

#include "sdoslam/io/tum_dataset.h"

namespace sdoslam {

// What the dynamic-object front end sees of one frame: the frame (its depth may be empty for
// a front end used alone), and its grey image where the caller has it.
struct FrontEndFrame : RgbdFrame {
  cv::Mat gray;  // CV_8UC1, bgr in grey; may be empty
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
