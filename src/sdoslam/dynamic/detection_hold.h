#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "sdoslam/dynamic/detector.h"

namespace sdoslam {

// How long a detected object keeps its box after the detector stops seeing it (issue: a known
// class is dynamic whether it moves or not). Detectors miss people who come close, turn, sit
// or are cut by the image border (HOG finds upright full bodies only), and those are the
// moments a still person's features would be taken for the room's.
struct DetectionHoldOptions {
  // Frames at most a box is kept after the detector last reported it. Meanwhile it moves along
  // the flow and follows the segments it labels (Follow), and it ends as soon as it labels
  // none: where the thing has gone, what the box holds is the room behind, and the classifier
  // does not take a segment that lies behind its surroundings for a detected object.
  // 0: a box lives until the next detector frame, as without holding.
  int hold_frames = 300;
  // Detector frames that must report a box before it is held: a person is reported again and
  // again, a false detection on the room mostly once, and holding one would keep a piece of the
  // static scene out of tracking for hold_frames.
  int hold_min_hits = 2;
  // A fresh box continues a held one of the same class when their overlap covers at least this
  // share of the smaller box: a person walking up grows from frame to frame, so the boxes'
  // intersection over union falls while one still holds the other.
  double hold_match_overlap = 0.5;
  void Check(const std::string& path = "dynamic.detector.") const;  // Error names path + setting
  template <class Options, class Visitor>
  static void VisitFields(Options& o, Visitor&& visit) {
    visit("hold_frames", o.hold_frames);
    visit("hold_min_hits", o.hold_min_hits);
    visit("hold_match_overlap", o.hold_match_overlap);
  }
};

// The boxes the classifier uses each frame: the detector's on the frames it runs, and between
// them, and for hold_frames after a confirmed box was last reported, the boxes carried along
// (the caller moves them, Boxes() gives them out to be moved in place).
class DetectionHold {
 public:
  explicit DetectionHold(const DetectionHoldOptions& options = {}) : options_(options) {}

  // A detector frame: `fresh` continue the held boxes they overlap (same class), take their
  // place and count a hit; held boxes no fresh one continues age on (Detection::held) and are
  // dropped past hold_frames (or at once when not confirmed by hold_min_hits).
  void Observe(const std::vector<Detection>& fresh);
  // A frame the detector skips: every box ages by a frame.
  void Skip();
  // After the classifier: `extents[i]`, the pixels Boxes()[i] labelled (empty: none). A held
  // box that labelled nothing ends; one that did takes their extent, growing or shrinking by at
  // most max_step a frame in width and height (the segments of one frame may leak or split).
  void Follow(const std::vector<cv::Rect2f>& extents, double max_step = 1.25);
  // The boxes in force now, in a stable order; the caller may move them (ShiftByFlow).
  std::vector<Detection>& Boxes() { return boxes_; }
  // Frames since each box of Boxes() was reported (0: this frame).
  const std::vector<int>& Ages() const { return ages_; }

 private:
  // Drops the boxes whose `keep` is 0.
  void Keep(const std::vector<uint8_t>& keep);

  DetectionHoldOptions options_;
  std::vector<Detection> boxes_;
  std::vector<int> ages_;  // frames since reported
  std::vector<int> hits_;  // detector frames that reported it
  int since_observe_ = 0;  // frames since the last detector frame
};

}  // namespace sdoslam
