#include "sdoslam/dynamic/classifier.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

// A 160×120 scene: background wall (segment 0, 3 m), object A (segment 1, 1 m) and object B
// (segment 2, 1.5 m). Work resolution = image resolution, no margin, to check exact pixels.
struct Scene {
  Segmentation segments;
  cv::Mat depth;
  cv::Rect a{20, 30, 30, 60}, b{100, 40, 36, 36};
  Scene() {
    segments.labels = cv::Mat(120, 160, CV_32S, cv::Scalar(0));
    segments.labels(a).setTo(1);
    segments.labels(b).setTo(2);
    segments.count = 3;
    depth = cv::Mat(120, 160, CV_32F, cv::Scalar(3.0f));
    depth(a).setTo(1.0f);
    depth(b).setTo(1.5f);
  }
  cv::Mat OutlineOf(const cv::Rect& r) const {
    cv::Mat m(120, 160, CV_8U, cv::Scalar(0));
    cv::rectangle(m, r, cv::Scalar(255), 1);
    return m;
  }
};

SdoClassifierOptions ExactOptions() {
  SdoClassifierOptions o;
  o.work_width = 160;
  o.margin_px = 0;
  return o;
}

int Count(const cv::Mat& labels, DynamicLabel l) { return cv::countNonZero(labels == l); }

TEST(SdoClassifier, MovableKnownClassMarksItsSegmentAndOtherClassesDoNot) {
  Scene s;
  SdoClassifier classifier(ExactOptions());
  const std::vector<Detection> detections = {
      {0, "person", 0.9f, cv::Rect2f(18, 28, 34, 64)},   // around A
      {56, "chair", 0.9f, cv::Rect2f(98, 38, 40, 40)}};  // around B: not movable
  const SdoResult r =
      classifier.Classify(s.segments, detections, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(r.segment_labels, (std::vector<uint8_t>{kStatic, kKnownMovable, kStatic}));
  EXPECT_EQ(Count(r.labels, kKnownMovable), s.a.area());
  EXPECT_EQ(cv::countNonZero(r.labels(s.a) == kKnownMovable), s.a.area());
  EXPECT_EQ(Count(r.labels, kMovingUnknown), 0);
}

TEST(SdoClassifier, PersonSplitIntoPartsIsWholeButTheWallInsideTheBoxIsNot) {
  Scene s;
  // A split in a head (segment 3) and a body (segment 1); a wall patch (segment 4, 3 m) inside
  // the box beside A.
  s.segments.labels(cv::Rect(20, 30, 30, 15)).setTo(3);
  s.segments.labels(cv::Rect(52, 30, 6, 20)).setTo(4);
  s.segments.count = 5;
  SdoClassifier classifier(ExactOptions());
  const SdoResult r =
      classifier.Classify(s.segments, {{0, "person", 0.9f, cv::Rect2f(18, 28, 42, 64)}}, cv::Mat(),
                          cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(r.segment_labels[1], kKnownMovable);
  EXPECT_EQ(r.segment_labels[3], kKnownMovable);
  EXPECT_EQ(r.segment_labels[4], kStatic);
  EXPECT_EQ(r.segment_labels[0], kStatic);
}

TEST(SdoClassifier, CloseUpAnArmJoinsItsBodyThoughItsDepthDiffersByMoreThanFifteenPercent) {
  Scene s;
  // An arm (segment 3) held 0.3 m in front of A's body (1 m), a wall patch (segment 4, 3 m),
  // both inside the person's box.
  const cv::Rect arm(22, 60, 10, 25);
  s.segments.labels(arm).setTo(3);
  s.depth(arm).setTo(0.7f);
  s.segments.labels(cv::Rect(52, 30, 6, 20)).setTo(4);
  s.segments.count = 5;
  const std::vector<Detection> person = {{0, "person", 0.9f, cv::Rect2f(18, 28, 42, 64)}};
  SdoClassifier classifier(ExactOptions());  // default band: max(15 %, 0.4 m)
  SdoResult r = classifier.Classify(s.segments, person, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(r.segment_labels,
            (std::vector<uint8_t>{kStatic, kKnownMovable, kStatic, kKnownMovable, kStatic}));
  // A relative band alone (15 % of 1 m) leaves the arm out.
  SdoClassifierOptions relative_only = ExactOptions();
  relative_only.same_depth_min_m = 0;
  r = SdoClassifier(relative_only)
          .Classify(s.segments, person, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(r.segment_labels[3], kStatic);
}

// A false detection as large as the image (FastestDet on blurred hand-held frames): its best
// match is the wall, which lies behind everything it borders. Nothing is labelled, where the
// wall used to be taken for a person; a person in front inside the same box still is.
TEST(SdoClassifier, ABoxWhoseBestMatchLiesBehindEverythingLabelsNothing) {
  Scene s;
  const std::vector<Detection> whole = {{0, "person", 0.45f, cv::Rect2f(0, 0, 160, 120)}};
  const SdoResult r = SdoClassifier(ExactOptions())
                          .Classify(s.segments, whole, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(r.segment_labels, (std::vector<uint8_t>{kStatic, kStatic, kStatic}));
  EXPECT_EQ(Count(r.labels, kKnownMovable), 0);
  SdoClassifierOptions off = ExactOptions();
  off.known_min_in_front = 0;
  EXPECT_EQ(SdoClassifier(off)
                .Classify(s.segments, whole, cv::Mat(), cv::Mat(), s.depth, {160, 120})
                .segment_labels[0],
            kKnownMovable)
      << "without the rule the wall is the person";
  // A box around A and the wall left of it: A (in front) is the person, the wall is not.
  const std::vector<Detection> left = {{0, "person", 0.9f, cv::Rect2f(0, 0, 60, 120)}};
  const SdoResult a = SdoClassifier(ExactOptions())
                          .Classify(s.segments, left, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(a.segment_labels, (std::vector<uint8_t>{kStatic, kKnownMovable, kStatic}));
  EXPECT_EQ(Count(a.labels, kKnownMovable), s.a.area());
}

TEST(SdoClassifier, BoxWithoutAMatchingSegmentIsLabelledItself) {
  Scene s;
  s.segments.labels.setTo(-1);  // a segmenter that found nothing
  SdoClassifier classifier(ExactOptions());
  const SdoResult r =
      classifier.Classify(s.segments, {{16, "dog", 0.8f, cv::Rect2f(60, 10, 20, 30)}}, cv::Mat(),
                          cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(Count(r.labels, kKnownMovable), 20 * 30);
}

// A held box (the detector stopped reporting it; DetectionHold carries it on): placed by the
// flow frames ago, it covers only part of a person who has walked up. Its best match is
// labelled whole, and its extent is reported for the box to follow; a fresh box stays clipped.
// A held box with no segment in front labels nothing, not the bare box.
TEST(SdoClassifier, AHeldBoxLabelsItsWholeSegmentAndNeverTheBareBox) {
  Scene s;
  Detection part{0, "person", 0.9f, cv::Rect2f(20, 30, 30, 40)};  // the top two thirds of A
  const SdoResult fresh =
      SdoClassifier(ExactOptions())
          .Classify(s.segments, {part}, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(Count(fresh.labels, kKnownMovable), 30 * 40);
  part.held = true;
  const SdoResult held =
      SdoClassifier(ExactOptions())
          .Classify(s.segments, {part}, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(Count(held.labels, kKnownMovable), s.a.area());
  ASSERT_EQ(held.detection_extents.size(), 1u);
  EXPECT_EQ(cv::Rect(held.detection_extents[0]), s.a);
  // A held box far smaller than its best match (over twice its area) labels only what it covers.
  Detection speck{0, "person", 0.9f, cv::Rect2f(20, 30, 15, 20), true};
  const SdoResult small =
      SdoClassifier(ExactOptions())
          .Classify(s.segments, {speck}, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(Count(small.labels, kKnownMovable), 15 * 20);
  // No segment found: a fresh box is labelled itself, a held one labels nothing and reports no
  // extent (its hold ends).
  s.segments.labels.setTo(-1);
  Detection empty{16, "dog", 0.8f, cv::Rect2f(60, 10, 20, 30), true};
  const SdoResult none =
      SdoClassifier(ExactOptions())
          .Classify(s.segments, {empty}, cv::Mat(), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(Count(none.labels, kKnownMovable), 0);
  EXPECT_EQ(none.detection_extents[0].area(), 0.0f);
}

TEST(SdoClassifier, MotionBoundaryOnAnOutlineSelectsTheObjectNotTheWallBehindIt) {
  Scene s;
  SdoClassifier classifier(ExactOptions());
  const SdoResult r =
      classifier.Classify(s.segments, {}, s.OutlineOf(s.b), cv::Mat(), s.depth, {160, 120});
  // The wall's outline (around the hole of B) is on the boundary too, but the wall is behind.
  EXPECT_EQ(r.segment_labels, (std::vector<uint8_t>{kStatic, kStatic, kMovingUnknown}));
  EXPECT_EQ(Count(r.labels, kMovingUnknown), s.b.area());
}

TEST(SdoClassifier, WithoutDepthOrderTheWallWouldBeTakenToo) {
  // The same as above with the in-front rule off: shows the rule is what protects the wall.
  Scene s;
  SdoClassifierOptions o = ExactOptions();
  o.min_in_front = 0.0;
  o.min_in_front_of_outline = 0.0;
  o.max_segment_area = 1.0;
  SdoClassifier classifier(o);
  const SdoResult r =
      classifier.Classify(s.segments, {}, s.OutlineOf(s.b), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(r.segment_labels[2], kMovingUnknown);
  // The wall's outline rings A and B (image borders are not outline); B's ring is ~45 % of it.
  EXPECT_EQ(r.segment_labels[0], kMovingUnknown);
  EXPECT_EQ(r.segment_labels[1], kStatic);
}

// B cut into three parts at one depth (creases, as the geometric segmenter cuts a body at the
// neck and waist): the middle part (segment 2, 24 of B's 36 rows) occludes the wall along its
// sides only, 40 % of its outline with depth; the rest is the cuts. All three are taken;
// demanding the nearer side along half of all the outline (min_in_front_of_outline =
// min_in_front, the rule before the geometric segmenter) leaves the middle out.
TEST(SdoClassifier, AnObjectCutIntoPartsAtOneDepthIsTakenWhole) {
  Scene s;
  s.segments.labels(cv::Rect(s.b.x, s.b.y, s.b.width, 6)).setTo(3);
  s.segments.labels(cv::Rect(s.b.x, s.b.y + 30, s.b.width, 6)).setTo(4);
  s.segments.count = 5;
  SdoClassifier classifier(ExactOptions());
  const SdoResult r =
      classifier.Classify(s.segments, {}, s.OutlineOf(s.b), cv::Mat(), s.depth, {160, 120});
  EXPECT_EQ(r.segment_labels, (std::vector<uint8_t>{kStatic, kStatic, kMovingUnknown,
                                                    kMovingUnknown, kMovingUnknown}));
  SdoClassifierOptions strict = ExactOptions();
  strict.min_in_front_of_outline = strict.min_in_front;
  const SdoResult t = SdoClassifier(strict).Classify(s.segments, {}, s.OutlineOf(s.b), cv::Mat(),
                                                     s.depth, {160, 120});
  EXPECT_EQ(t.segment_labels,
            (std::vector<uint8_t>{kStatic, kStatic, kStatic, kMovingUnknown, kMovingUnknown}));
}

TEST(SdoClassifier, SelectedObjectPersistsForTheConfiguredFramesThenLapses) {
  Scene s;
  SdoClassifierOptions o = ExactOptions();
  o.persistence_frames = 3;
  SdoClassifier classifier(o);
  const cv::Mat zero_flow(120, 160, CV_32FC2, cv::Scalar(0, 0));
  const cv::Mat no_boundary(120, 160, CV_8U, cv::Scalar(0));
  ASSERT_EQ(classifier.Classify(s.segments, {}, s.OutlineOf(s.b), zero_flow, s.depth, {160, 120})
                .segment_labels[2],
            kMovingUnknown);
  std::vector<uint8_t> seen;
  for (int k = 0; k < 5; ++k) {
    seen.push_back(classifier.Classify(s.segments, {}, no_boundary, zero_flow, s.depth, {160, 120})
                       .segment_labels[2]);
  }
  // Memory 3 carried and decremented each frame: dynamic for 3 more frames, then static.
  EXPECT_EQ(seen, (std::vector<uint8_t>{kMovingUnknown, kMovingUnknown, kMovingUnknown, kStatic,
                                        kStatic}));
}

// B seen moving on clear boundaries (all of its outline) in two frames, then still: labelled
// dynamic while the memory lasts (3 frames), then static but still unmapped until 6 frames after
// it was last seen moving. A selection on weaker boundaries (39 % of the outline: above
// min_outline_on_boundary, below unmapped_min_outline_on_boundary) leaves nothing unmapped, and
// so does a selection in one frame alone (first_selection_is_tentative), unless the option is
// off.
TEST(SdoClassifier, AThingSeenMovingStaysUnmappedAfterItsLabelLapses) {
  Scene s;
  SdoClassifierOptions o = ExactOptions();
  o.persistence_frames = 3;
  o.unmapped_frames = 6;
  const cv::Mat zero_flow(120, 160, CV_32FC2, cv::Scalar(0, 0));
  const cv::Mat no_boundary(120, 160, CV_8U, cv::Scalar(0));
  cv::Mat weak_boundary(120, 160, CV_8U, cv::Scalar(0));
  cv::line(weak_boundary, s.b.tl(), {s.b.x, s.b.br().y - 1}, cv::Scalar(255));  // left side
  cv::line(weak_boundary, s.b.tl(), {s.b.x + 17, s.b.y}, cv::Scalar(255));      // half the top
  auto unmapped_on_b = [&](const SdoResult& r) {
    return r.unmapped.empty() ? -1 : cv::countNonZero(r.unmapped(s.b));
  };
  struct Case {
    const char* name;
    bool clear;
    int frames_moving;
    bool tentative;
    bool unmapped;  // expected: B is kept unmapped after its label lapses
  };
  for (const Case& c : {Case{"clear boundaries, twice", true, 2, true, true},
                        Case{"weak boundaries, twice", false, 2, true, false},
                        Case{"clear boundaries, once", true, 1, true, false},
                        Case{"clear boundaries, once, not tentative", true, 1, false, true}}) {
    SCOPED_TRACE(c.name);
    o.first_selection_is_tentative = c.tentative;
    SdoClassifier classifier(o);
    for (int k = 0; k < c.frames_moving; ++k) {
      const SdoResult r =
          classifier.Classify(s.segments, {}, c.clear ? s.OutlineOf(s.b) : weak_boundary, zero_flow,
                              s.depth, {160, 120});
      ASSERT_EQ(r.segment_labels[2], kMovingUnknown);
      EXPECT_EQ(unmapped_on_b(r), 0);  // dynamic now: nothing static to keep unmapped
      EXPECT_EQ(cv::countNonZero(r.unmapped), 0);
    }
    std::vector<int> unmapped, dynamic;
    for (int k = 0; k < 6; ++k) {
      const SdoResult r =
          classifier.Classify(s.segments, {}, no_boundary, zero_flow, s.depth, {160, 120});
      unmapped.push_back(unmapped_on_b(r));
      dynamic.push_back(r.segment_labels[2] != kStatic);
      EXPECT_EQ(cv::countNonZero(r.unmapped), unmapped.back());  // only B, never the wall or A
    }
    EXPECT_EQ(dynamic, (std::vector<int>{1, 1, 1, 0, 0, 0}));
    const int b = s.b.area();
    EXPECT_EQ(unmapped, c.unmapped ? (std::vector<int>{0, 0, 0, b, b, 0})
                                   : (std::vector<int>{0, 0, 0, 0, 0, 0}));
  }
  o.unmapped_frames = 0;
  EXPECT_TRUE(SdoClassifier(o)
                  .Classify(s.segments, {}, s.OutlineOf(s.b), zero_flow, s.depth, {160, 120})
                  .unmapped.empty());
}

// The ORB budget steers clear of a segment selected by motion only from its second selection
// on (first_selection_is_tentative); a known movable class, from the first frame. The labels
// themselves call B dynamic from the first frame.
TEST(SdoClassifier, TheBudgetLabelsLeaveOutAFirstSelection) {
  Scene s;
  const cv::Mat zero_flow(120, 160, CV_32FC2, cv::Scalar(0, 0));
  const std::vector<Detection> person_at_a = {{0, "person", 0.9f, cv::Rect2f(18, 28, 34, 64)}};
  for (const bool tentative : {true, false}) {
    SCOPED_TRACE(tentative ? "tentative" : "not tentative");
    SdoClassifierOptions o = ExactOptions();
    o.first_selection_is_tentative = tentative;
    SdoClassifier classifier(o);
    std::vector<int> labelled_b, budget_b, budget_a;
    for (int k = 0; k < 3; ++k) {
      const SdoResult r = classifier.Classify(s.segments, person_at_a, s.OutlineOf(s.b), zero_flow,
                                              s.depth, {160, 120});
      ASSERT_EQ(r.budget_labels.size(), r.labels.size());
      labelled_b.push_back(cv::countNonZero(r.labels(s.b) == kMovingUnknown));
      budget_b.push_back(cv::countNonZero(r.budget_labels(s.b) == kMovingUnknown));
      budget_a.push_back(cv::countNonZero(r.budget_labels(s.a) == kKnownMovable));
      EXPECT_EQ(cv::countNonZero(r.budget_labels != r.labels),
                labelled_b.back() - budget_b.back());  // nothing else differs
    }
    const int b = s.b.area(), a = s.a.area();
    EXPECT_EQ(labelled_b, (std::vector<int>{b, b, b}));
    EXPECT_EQ(budget_b, tentative ? (std::vector<int>{0, b, b}) : (std::vector<int>{b, b, b}));
    EXPECT_EQ(budget_a, (std::vector<int>{a, a, a}));
  }
}

// A mover that filled B walked on; the room seen there now is farther than the wall around it
// (B's pixels read 3.5 m inside a wall at 3 m). The memory still covers B, but B lies behind
// everything it borders, so it is not remembered; an object that paused (still 1.5 m) is.
TEST(SdoClassifier, MemoryDoesNotKeepWhatComesBackIntoViewBehindAMoverThatLeft) {
  auto second_frame = [](const SdoClassifierOptions& o, float depth_of_b) {
    Scene s;
    SdoClassifier classifier(o);
    const cv::Mat zero_flow(120, 160, CV_32FC2, cv::Scalar(0, 0));
    EXPECT_EQ(classifier.Classify(s.segments, {}, s.OutlineOf(s.b), zero_flow, s.depth, {160, 120})
                  .segment_labels[2],
              kMovingUnknown);
    s.depth(s.b).setTo(depth_of_b);
    return classifier
        .Classify(s.segments, {}, cv::Mat(120, 160, CV_8U, cv::Scalar(0)), zero_flow, s.depth,
                  {160, 120})
        .segment_labels[2];
  };
  EXPECT_EQ(second_frame(ExactOptions(), 3.5f), kStatic);
  EXPECT_EQ(second_frame(ExactOptions(), 1.5f), kMovingUnknown);
  SdoClassifierOptions without_rule = ExactOptions();
  without_rule.persistence_min_in_front = 0;
  EXPECT_EQ(second_frame(without_rule, 3.5f), kMovingUnknown);
}

TEST(SdoClassifier, MemoryFollowsTheFlow) {
  // B moved 40 px to the left since the last frame; the memory must follow it there.
  Scene s;
  SdoClassifier classifier(ExactOptions());
  classifier.Classify(s.segments, {}, s.OutlineOf(s.b), cv::Mat(), s.depth, {160, 120});
  Scene moved;
  moved.segments.labels(moved.b).setTo(0);
  moved.depth(moved.b).setTo(3.0f);
  const cv::Rect b2 = moved.b - cv::Point(40, 0);
  moved.segments.labels(b2).setTo(2);
  moved.depth(b2).setTo(1.5f);
  cv::Mat flow(120, 160, CV_32FC2, cv::Scalar(0, 0));
  flow(b2).setTo(cv::Scalar(-40, 0));
  const SdoResult r = classifier.Classify(
      moved.segments, {}, cv::Mat(120, 160, CV_8U, cv::Scalar(0)), flow, moved.depth, {160, 120});
  EXPECT_EQ(r.segment_labels[2], kMovingUnknown);
  const SdoResult without_flow_shift =
      SdoClassifier(ExactOptions())
          .Classify(moved.segments, {}, cv::Mat(), cv::Mat(), moved.depth, {160, 120});
  EXPECT_EQ(without_flow_shift.segment_labels[2], kStatic);
}

TEST(SdoClassifier, LabelImageIsScaledToTheFrame) {
  Scene s;
  SdoClassifierOptions o = ExactOptions();
  o.work_width = 80;
  SdoClassifier classifier(o);
  cv::Mat depth640;
  cv::resize(s.depth, depth640, {640, 480}, 0, 0, cv::INTER_NEAREST);
  const SdoResult r = classifier.Classify(
      s.segments, {{0, "person", 0.9f, cv::Rect2f(18 * 4, 28 * 4, 34 * 4, 64 * 4)}}, cv::Mat(),
      cv::Mat(), depth640, {640, 480});
  ASSERT_EQ(r.labels.size(), cv::Size(640, 480));
  EXPECT_EQ(r.work_labels.size(), cv::Size(80, 60));
  EXPECT_EQ(r.labels.at<uint8_t>(60 * 4, 35 * 4), kKnownMovable);  // inside A
  EXPECT_EQ(r.labels.at<uint8_t>(10, 10), kStatic);
}

TEST(SdoClassifierOptions, RejectsOutOfRangeValues) {
  SdoClassifierOptions o;
  o.min_outline_on_boundary = 1.5;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.persistence_frames = -1;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.same_depth_min_m = -0.1;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.unmapped_frames = 251;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.unmapped_min_outline_on_boundary = -0.1;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.known_min_in_front = 1.5;
  EXPECT_THROW(o.Check(), Error);
}

}  // namespace
}  // namespace sdoslam
