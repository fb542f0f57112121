#include "sdoslam/dynamic/detection_hold.h"

#include <gtest/gtest.h>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

Detection Person(float x, float y, float w, float h) {
  Detection d;
  d.class_id = 0;
  d.class_name = "person";
  d.score = 0.9f;
  d.box = cv::Rect2f(x, y, w, h);
  return d;
}

// Frames as the front end runs them with the detector on every 2nd frame: Observe on even
// frames (with what the detector reports), Skip on odd ones.
void Step(DetectionHold& hold, int frame, const std::vector<Detection>& reported) {
  if (frame % 2 == 0) {
    hold.Observe(reported);
  } else {
    hold.Skip();
  }
}

TEST(DetectionHold, AConfirmedPersonTheDetectorLosesIsHeldForHoldFramesThenDropped) {
  DetectionHoldOptions options;
  options.hold_frames = 10;
  options.hold_min_hits = 2;
  DetectionHold hold(options);
  // Reported on frames 0 and 2 (two hits), missed from frame 4 on.
  for (int frame = 0; frame < 4; ++frame) Step(hold, frame, {Person(100, 50, 80, 200)});
  for (int frame = 4; frame <= 12; ++frame) {
    Step(hold, frame, {});
    ASSERT_EQ(hold.Boxes().size(), 1u) << "frame " << frame;
    EXPECT_EQ(hold.Ages()[0], frame - 2);
    EXPECT_EQ(hold.Boxes()[0].class_name, "person");
  }
  Step(hold, 13, {});  // 11 frames since frame 2's report
  EXPECT_TRUE(hold.Boxes().empty());
}

TEST(DetectionHold, ABoxReportedOnceIsNotHeld) {
  DetectionHold hold;  // hold_min_hits 2
  Step(hold, 0, {Person(100, 50, 80, 200)});
  Step(hold, 1, {});
  EXPECT_EQ(hold.Boxes().size(), 1u) << "kept until the next detector frame";
  Step(hold, 2, {});
  EXPECT_TRUE(hold.Boxes().empty());
}

TEST(DetectionHold, AGrowingPersonKeepsOneBox) {
  DetectionHoldOptions options;
  options.hold_frames = 30;
  DetectionHold hold(options);
  // A person walking up: each box holds the last (IoU about 0.4), and is one box all along.
  float w = 60, h = 160;
  for (int frame = 0; frame < 12; frame += 2) {
    Step(hold, frame, {Person(300 - w / 2, 100, w, h)});
    Step(hold, frame + 1, {});
    w *= 1.6f;
    h *= 1.6f;
  }
  ASSERT_EQ(hold.Boxes().size(), 1u);
  // Another class at the same place is another object.
  Detection dog = Person(280, 150, 40, 40);
  dog.class_id = 16;
  dog.class_name = "dog";
  Step(hold, 12, {Person(300 - w / 2, 100, w, h), dog});
  EXPECT_EQ(hold.Boxes().size(), 2u);
  // Two people side by side stay two boxes when one is missed.
  DetectionHold pair(options);
  for (int frame = 0; frame < 4; ++frame)
    Step(pair, frame, {Person(100, 100, 50, 150), Person(400, 100, 50, 150)});
  Step(pair, 4, {Person(400, 100, 50, 150)});
  ASSERT_EQ(pair.Boxes().size(), 2u);
  EXPECT_EQ(pair.Ages()[0], 0);
  EXPECT_FLOAT_EQ(pair.Boxes()[0].box.x, 400);
  EXPECT_EQ(pair.Ages()[1], 2);
  EXPECT_FLOAT_EQ(pair.Boxes()[1].box.x, 100);
}

TEST(DetectionHold, AHeldBoxFollowsWhatItLabelsAndEndsWhenItLabelsNothing) {
  DetectionHold hold;
  for (int frame = 0; frame < 4; ++frame) Step(hold, frame, {Person(100, 100, 40, 100)});
  // The detector's own box is not moved by what it labelled.
  hold.Follow({cv::Rect2f(0, 0, 10, 10)});
  EXPECT_FLOAT_EQ(hold.Boxes()[0].box.x, 100);
  EXPECT_FALSE(hold.Boxes()[0].held);
  Step(hold, 4, {});  // missed: held from here on
  ASSERT_EQ(hold.Boxes().size(), 1u);
  EXPECT_TRUE(hold.Boxes()[0].held);
  // The person it labels has grown to 80 x 200 around (140, 200): the box recentres there and
  // grows by at most 1.25 a frame.
  hold.Follow({cv::Rect2f(100, 100, 80, 200)});
  const cv::Rect2f b = hold.Boxes()[0].box;
  EXPECT_FLOAT_EQ(b.width, 50);
  EXPECT_FLOAT_EQ(b.height, 125);
  EXPECT_FLOAT_EQ(b.x + b.width / 2, 140);
  EXPECT_FLOAT_EQ(b.y + b.height / 2, 200);
  // Nothing labelled: the thing has gone from under the box, the hold ends.
  hold.Follow({cv::Rect2f()});
  EXPECT_TRUE(hold.Boxes().empty());
}

TEST(DetectionHold, HoldZeroKeepsBoxesOnlyUntilTheNextDetectorFrame) {
  DetectionHoldOptions options;
  options.hold_frames = 0;
  DetectionHold hold(options);
  for (int frame = 0; frame < 6; ++frame) Step(hold, frame, {Person(100, 50, 80, 200)});
  Step(hold, 6, {});
  EXPECT_TRUE(hold.Boxes().empty());
}

TEST(DetectionHold, OptionsAreChecked) {
  DetectionHoldOptions options;
  options.hold_frames = -1;
  EXPECT_THROW(options.Check(), Error);
  options = {};
  options.hold_min_hits = 0;
  EXPECT_THROW(options.Check(), Error);
  options = {};
  options.hold_match_overlap = 0;
  EXPECT_THROW(options.Check(), Error);
  options = {};
  EXPECT_NO_THROW(options.Check());
}

}  // namespace
}  // namespace sdoslam
