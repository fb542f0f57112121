#include "sdoslam/dynamic/motion_boundaries.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

namespace sdoslam {
namespace {

// A camera panning (uniform flow 3 px right) and a square moving down by 6 px.
cv::Mat PanWithMovingSquare(const cv::Rect& square) {
  cv::Mat flow(120, 160, CV_32FC2, cv::Scalar(3.0f, 0.0f));
  flow(square).setTo(cv::Scalar(0.0f, 6.0f));
  return flow;
}

TEST(MotionBoundaries, MarkTheMovingSquaresOutlineAndNothingElse) {
  const cv::Rect square(60, 40, 40, 30);
  const MotionBoundaries b = ComputeMotionBoundaries(PanWithMovingSquare(square));
  // Along the outline: boundary.
  EXPECT_EQ(b.mask.at<uint8_t>(40, 80), 255);  // top edge
  EXPECT_EQ(b.mask.at<uint8_t>(55, 60), 255);  // left edge
  EXPECT_EQ(b.mask.at<uint8_t>(69, 80), 255);  // bottom edge
  // The square's interior and the background (camera motion alone): no boundary at all.
  cv::Mat interior = b.mask(cv::Rect(63, 43, 34, 24));
  EXPECT_EQ(cv::countNonZero(interior), 0);
  cv::Mat background = b.mask.clone();
  background(cv::Rect(56, 36, 48, 38)).setTo(0);
  EXPECT_EQ(cv::countNonZero(background), 0);
}

TEST(MotionBoundaries, SmoothFlowFromCameraMotionIsNotABoundary) {
  // Zoom-like flow (forward motion): large but smooth, it grows 0.02 px per px.
  cv::Mat flow(120, 160, CV_32FC2);
  for (int y = 0; y < 120; ++y)
    for (int x = 0; x < 160; ++x)
      flow.at<cv::Vec2f>(y, x) = cv::Vec2f(0.02f * (x - 80), 0.02f * (y - 60));
  const MotionBoundaries b = ComputeMotionBoundaries(flow);
  EXPECT_EQ(cv::countNonZero(b.mask), 0);
}

TEST(MotionBoundaries, FollowThePapersCombinationRule) {
  const MotionBoundaries b = ComputeMotionBoundaries(PanWithMovingSquare({60, 40, 40, 30}));
  for (int y = 0; y < b.probability.rows; y += 3) {
    for (int x = 0; x < b.probability.cols; x += 3) {
      const float mi = b.magnitude_term.at<float>(y, x), mo = b.orientation_term.at<float>(y, x);
      const float expected = mi > 0.8f ? mi : mi * mo;
      EXPECT_FLOAT_EQ(b.probability.at<float>(y, x), expected);
    }
  }
  MotionBoundaryOptions bad;
  bad.threshold = 1.5;
  EXPECT_THROW(ComputeMotionBoundaries(PanWithMovingSquare({0, 0, 5, 5}), bad), std::exception);
}

}  // namespace
}  // namespace sdoslam

// With real dense flow (OpenCV DIS) between two renderings of swinging boxes seen by a moving
// camera, boundaries concentrate on the moving objects' outlines.
#include <opencv2/video/tracking.hpp>

#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"

namespace sdoslam {
namespace {

// DIS flow (medium preset) of the rendered moving boxes from t = 2 s to 2 s + dt; `instance`:
// the later view's object ids.
cv::Mat DisFlowOfRenderedBoxes(double dt, cv::Mat* instance = nullptr) {
  const Camera camera(synth::SyntheticCamera());
  const synth::Scenario scenario = synth::MakeScenario("boxes_translational", 10.0);
  cv::Mat gray[2];
  for (int k = 0; k < 2; ++k) {
    const double t = 2.0 + k * dt;
    const synth::RenderedView view =
        synth::Render(scenario.scene, t, synth::CameraPoseAt(scenario.motion, t, 10.0), camera);
    cv::Mat bgr;
    view.colour.convertTo(bgr, CV_8UC3, 255.0);
    cv::cvtColor(bgr, gray[k], cv::COLOR_BGR2GRAY);
    if (instance != nullptr) *instance = view.instance;
  }
  cv::Mat flow;
  cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM)->calc(gray[0], gray[1], flow);
  return flow;
}

TEST(MotionBoundaries, DisFlowOnRenderedBoxesFindsTheMovingOutlines) {
  cv::Mat instance;
  const MotionBoundaries b = ComputeMotionBoundaries(DisFlowOfRenderedBoxes(1 / 30.0, &instance));
  // Band of ±4 px around the outlines of the moving objects (every object here moves).
  cv::Mat moving = instance > 0, band;
  cv::Mat outline;
  cv::morphologyEx(moving, outline, cv::MORPH_GRADIENT, cv::Mat());
  cv::dilate(outline, band, cv::Mat(), cv::Point(-1, -1), 4);
  const double in_band =
      cv::countNonZero(b.mask & band) / std::max(1.0, double(cv::countNonZero(band)));
  const double elsewhere =
      cv::countNonZero(b.mask & ~band) / std::max(1.0, double(cv::countNonZero(~band)));
  EXPECT_GT(in_band, 0.08);  // DIS blurs edges over a few px: the band is only partly covered
  EXPECT_GT(in_band, 5.0 * elsewhere) << "in band " << in_band << ", elsewhere " << elsewhere;
}

// The front end's mask-only path skips the angle where M_I alone decides: on DIS flow of moving
// boxes and on noisy random flow, under several settings (strong above and below threshold), it
// gives the full computation's mask pixel for pixel, and the angle did decide pixels there.
TEST(MotionBoundaries, TheMaskAloneIsTheFullComputationsMask) {
  cv::Mat dis_flow = DisFlowOfRenderedBoxes(0.1);
  cv::Mat random_flow(97, 131, CV_32FC2);
  cv::RNG rng(7);
  rng.fill(random_flow, cv::RNG::NORMAL, cv::Scalar(1.0, -0.5), cv::Scalar(1.5, 1.5));
  cv::GaussianBlur(random_flow, random_flow, cv::Size(5, 5), 1.0);

  int decided_by_angle = 0;
  for (const cv::Mat* flow : {&dis_flow, &random_flow}) {
    for (const auto& [threshold, strong] : {std::pair{0.5, 0.8}, {0.3, 0.9}, {0.7, 0.6}}) {
      MotionBoundaryOptions o;
      o.threshold = threshold;
      o.strong = strong;
      const MotionBoundaries full = ComputeMotionBoundaries(*flow, o);
      const cv::Mat fast = MotionBoundaryMask(*flow, o);
      ASSERT_EQ(fast.size(), full.mask.size());
      ASSERT_EQ(fast.type(), full.mask.type());
      EXPECT_EQ(cv::countNonZero(fast != full.mask), 0)
          << "threshold " << threshold << ", strong " << strong;
      // Pixels whose M_I lies in (threshold, strong]: the angle said yes for some, no for others.
      const cv::Mat undecided = (full.magnitude_term > threshold) & (full.magnitude_term <= strong);
      decided_by_angle += cv::countNonZero(undecided & full.mask);
      if (threshold < strong) {
        EXPECT_GT(cv::countNonZero(undecided & ~full.mask), 0);
      }
    }
  }
  EXPECT_GT(decided_by_angle, 0);
}

}  // namespace
}  // namespace sdoslam
