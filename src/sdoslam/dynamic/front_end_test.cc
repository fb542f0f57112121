#include "sdoslam/dynamic/front_end.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

// The whole front end on the three tiny ONNX backends (testdata/onnx, see
// scripts/make_test_models.py): the segmenter masks red on the left and green on the right, the
// detector boxes a 'person' exactly where the red block stands, and the "flow" is the change of
// red and green. So: the red block is a known movable object; the green block, which moves, is
// caught by the motion boundaries of the flow as an unknown moving object; black stays static.
class OnnxFrontEnd : public ::testing::Test {
 protected:
  static FrontEndOptions Options() {
    const auto onnx = testing::SourceDir() / "testdata" / "onnx";
    FrontEndOptions o;
    o.segmenter = "onnx-yoloseg";
    o.segmenter_model = onnx / "yoloseg_tiny.onnx";
    o.detector = "yolov8";
    o.detector_model = onnx / "yolov8_tiny.onnx";
    // The detector's score is the image's mean red: a 160×200 block on black scores 0.19.
    o.detection.score_threshold = 0.15;
    o.flow = "onnx";
    o.flow_model = onnx / "flow_stacked_tiny.onnx";
    return o;
  }

  static FrontEndFrame Frame(int k) {
    FrontEndFrame f;
    f.index = k;
    f.bgr = cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));
    f.depth = cv::Mat(480, 640, CV_32F, cv::Scalar(3.0f));
    f.bgr(kPerson).setTo(cv::Scalar(0, 0, 255));
    f.depth(kPerson).setTo(1.5f);
    const cv::Rect green = Green(k);
    f.bgr(green).setTo(cv::Scalar(0, 255, 0));
    f.depth(green).setTo(1.0f);
    return f;
  }
  static cv::Rect Green(int k) { return {360 + 40 * k, 80, 120, 200}; }

  static double Fraction(const cv::Mat& labels, const cv::Rect& r, DynamicLabel label) {
    return cv::countNonZero(labels(r) == label) / static_cast<double>(r.area());
  }

  static inline const cv::Rect kPerson{120, 160, 160, 200};
};

TEST_F(OnnxFrontEnd, LabelsTheDetectedPersonAndTheMovingUnknownBlock) {
  FrontEnd front_end(Options(), {}, {640, 480});
  SdoResult result;
  for (int k = 0; k < 4; ++k) result = front_end.Process(Frame(k));
  ASSERT_EQ(result.labels.size(), cv::Size(640, 480));
  ASSERT_EQ(result.detections.size(), 1u);
  EXPECT_EQ(result.detections[0].class_name, "person");
  EXPECT_GT(Fraction(result.labels, kPerson, kKnownMovable), 0.9);
  EXPECT_GT(Fraction(result.labels, Green(3), kMovingUnknown), 0.8);
  EXPECT_GT(Fraction(result.labels, {0, 0, 100, 480}, kStatic), 0.99);
}

TEST_F(OnnxFrontEnd, AStillUnknownBlockStaysStatic) {
  // The same block not moving: no flow, no boundary, nothing but the person is dynamic.
  FrontEnd front_end(Options(), {}, {640, 480});
  SdoResult result;
  for (int k = 0; k < 4; ++k) result = front_end.Process(Frame(0));
  EXPECT_GT(Fraction(result.labels, kPerson, kKnownMovable), 0.9);
  EXPECT_GT(Fraction(result.labels, Green(0), kStatic), 0.99);
}

TEST_F(OnnxFrontEnd, AMissingOrMismatchedModelFailsBeforeTheFirstFrame) {
  FrontEndOptions o = Options();
  o.flow_model = testing::SourceDir() / "testdata" / "onnx" / "yoloseg_tiny.onnx";
  const std::string flow = testing::MessageOf([&] { FrontEnd f(o, {}, {640, 480}); });
  EXPECT_NE(flow.find("yoloseg_tiny.onnx"), std::string::npos) << flow;
  o = Options();
  o.segmenter_model = "nowhere/seg.onnx";
  const std::string segmenter = testing::MessageOf([&] { FrontEnd f(o, {}, {640, 480}); });
  EXPECT_NE(segmenter.find("nowhere/seg.onnx: model file for 'onnx-yoloseg' does not exist"),
            std::string::npos)
      << segmenter;
}

}  // namespace
}  // namespace sdoslam
