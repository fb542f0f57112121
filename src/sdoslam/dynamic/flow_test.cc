#include "sdoslam/dynamic/flow.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

using testing::MessageOf;

cv::Mat Uniform(const cv::Scalar& bgr) { return cv::Mat(480, 640, CV_8UC3, bgr); }

// Mean (u, v) of a CV_32FC2 flow and its largest deviation from that mean.
cv::Vec2d MeanFlow(const cv::Mat& flow, double* spread) {
  const cv::Scalar mean = cv::mean(flow);
  std::vector<cv::Mat> uv;
  cv::split(flow, uv);
  double lo_u, hi_u, lo_v, hi_v;
  cv::minMaxLoc(uv[0], &lo_u, &hi_u);
  cv::minMaxLoc(uv[1], &lo_v, &hi_v);
  *spread = std::max({hi_u - mean[0], mean[0] - lo_u, hi_v - mean[1], mean[1] - lo_v});
  return {mean[0], mean[1]};
}

// testdata/onnx/flow_*_tiny.onnx (scripts/make_test_models.py): 48×64 "flow" models whose u is
// 10·(R_current − R_previous) and v is 10·(G_current − G_previous), with images in [0, 1]. The
// sign shows the order of the two images, the channel the RGB order, the size the model's.
enum Variant { kStacked, kPairNamed, kPairUnnamed };
std::string VariantName(const ::testing::TestParamInfo<Variant>& info) {
  const char* names[] = {"stacked", "pair_named", "pair_unnamed"};
  return names[info.param];
}
class TinyOnnxFlow : public ::testing::TestWithParam<Variant> {
 protected:
  std::unique_ptr<FlowEstimator> Make() {
    FlowOptions options;
    const bool pair = GetParam() != kStacked;
    // Named explicitly, or (the pair model without names) taken from the file in its order.
    if (GetParam() == kPairNamed) options.onnx_input_names = {"previous", "current"};
    return MakeOnnxFlow(testing::SourceDir() / "testdata/onnx" /
                            (pair ? "flow_pair_tiny.onnx" : "flow_stacked_tiny.onnx"),
                        options);
  }
};

TEST_P(TinyOnnxFlow, FeedsPreviousThenCurrentInRgbOrder) {
  auto flow = Make();
  double spread = 0;
  const cv::Mat to_red = flow->Compute(Uniform({0, 0, 0}), Uniform({0, 0, 255}));
  EXPECT_EQ(to_red.type(), CV_32FC2);
  EXPECT_EQ(to_red.size(), cv::Size(64, 48));
  cv::Vec2d mean = MeanFlow(to_red, &spread);
  EXPECT_NEAR(mean[0], 10, 1e-4);
  EXPECT_NEAR(mean[1], 0, 1e-4);
  EXPECT_LT(spread, 1e-4);
  const cv::Mat from_green = flow->Compute(Uniform({0, 255, 0}), Uniform({0, 0, 0}));
  mean = MeanFlow(from_green, &spread);
  EXPECT_NEAR(mean[0], 0, 1e-4);
  EXPECT_NEAR(mean[1], -10, 1e-4);
  EXPECT_LT(spread, 1e-4);
  // Blue changes neither: a BGR/RGB mix-up would show here.
  mean = MeanFlow(flow->Compute(Uniform({0, 0, 0}), Uniform({255, 0, 0})), &spread);
  EXPECT_NEAR(mean[0], 0, 1e-4);
  EXPECT_NEAR(mean[1], 0, 1e-4);
}

INSTANTIATE_TEST_SUITE_P(StackedAndPair, TinyOnnxFlow,
                         ::testing::Values(kStacked, kPairNamed, kPairUnnamed), VariantName);

TEST(OnnxFlow, ModelsThatDoNotFitAreRejectedNamingTheFile) {
  const auto onnx = testing::SourceDir() / "testdata/onnx";
  // Names the model does not have.
  FlowOptions wrong_names;
  wrong_names.onnx_input_names = {"image1", "image2"};
  const std::string wrong =
      MessageOf([&] { MakeOnnxFlow(onnx / "flow_pair_tiny.onnx", wrong_names); });
  EXPECT_NE(wrong.find("flow_pair_tiny.onnx: the flow model does not run on two 3-channel input"),
            std::string::npos)
      << wrong;
  // A detector: three channels in, 1×84×3 out.
  const std::string detector = MessageOf([&] { MakeOnnxFlow(onnx / "yolov8_tiny.onnx", {}); });
  EXPECT_NE(detector.find("yolov8_tiny.onnx"), std::string::npos) << detector;
  const std::string missing = MessageOf([&] { MakeOnnxFlow(onnx / "absent.onnx", {}); });
  EXPECT_NE(missing.find("absent.onnx: model file for 'onnx flow' does not exist"),
            std::string::npos)
      << missing;
  FlowOptions one_name;
  one_name.onnx_input_names = {"previous"};
  EXPECT_NE(MessageOf([&] {
              MakeOnnxFlow(onnx / "flow_pair_tiny.onnx", one_name);
            }).find("flow.onnx_input_names must name exactly two inputs"),
            std::string::npos);
}

// DIS and Farnebäck on a textured image shifted by a known amount: the flow (at the default
// work width, 256: 0.4 of the image) must be the shift, scaled by 0.4.
TEST(ClassicalFlow, RecoversAKnownShift) {
  cv::Mat texture(480 + 16, 640 + 16, CV_8UC3);
  cv::RNG rng(7);
  rng.fill(texture, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(texture, texture, {0, 0}, 3.0);
  const cv::Mat previous = texture(cv::Rect(8, 8, 640, 480)).clone();
  const cv::Mat current = texture(cv::Rect(4, 10, 640, 480)).clone();  // content moves +4, −2
  for (const auto& make : {MakeDisFlow, MakeFarnebackFlow}) {
    const cv::Mat flow = make({})->Compute(previous, current);
    ASSERT_EQ(flow.size(), cv::Size(256, 192));
    const cv::Scalar mean = cv::mean(flow(cv::Rect(32, 32, 192, 128)));
    EXPECT_NEAR(mean[0], 1.6, 0.15);
    EXPECT_NEAR(mean[1], -0.8, 0.15);
  }
}

// A grey image the caller has made already is what DIS and Farnebäck prepare from (the frame's
// grey image is made once, for the features, the check and the flow), and without one they
// convert the colour image themselves; either way the prepared image has memory of its own.
TEST(ClassicalFlow, PreparesFromTheCallersGreyImage) {
  cv::Mat bgr(480, 640, CV_8UC3);
  cv::RNG rng(3);
  rng.fill(bgr, cv::RNG::UNIFORM, 0, 255);
  cv::Mat own_gray;
  cv::cvtColor(bgr, own_gray, cv::COLOR_BGR2GRAY);
  cv::Mat other_gray(480, 640, CV_8UC1);
  rng.fill(other_gray, cv::RNG::UNIFORM, 0, 255);  // not bgr's grey: shows which one was used
  const auto same = [](const cv::Mat& a, const cv::Mat& b) {
    return a.size() == b.size() && a.type() == b.type() && cv::countNonZero(a != b) == 0;
  };
  for (const auto& make : {MakeDisFlow, MakeFarnebackFlow}) {
    for (const int width : {256, 640}) {
      FlowOptions options;
      options.work_width = width;
      const auto flow = make(options);
      const cv::Mat from_bgr = flow->Prepare(bgr);
      EXPECT_TRUE(same(flow->PrepareWithGray(bgr, cv::Mat()), from_bgr));
      EXPECT_TRUE(same(flow->PrepareWithGray(bgr, own_gray), from_bgr));
      const cv::Mat from_other = flow->PrepareWithGray(bgr, other_gray);
      cv::Mat expected = other_gray;
      if (width < 640) cv::resize(other_gray, expected, {256, 192}, 0, 0, cv::INTER_AREA);
      EXPECT_TRUE(same(from_other, expected)) << width;
      EXPECT_FALSE(same(from_other, from_bgr)) << width;
      EXPECT_NE(from_other.data, other_gray.data) << width;  // not the caller's buffer
    }
  }
}

}  // namespace
}  // namespace sdoslam
