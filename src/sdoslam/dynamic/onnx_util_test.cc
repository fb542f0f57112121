#include "sdoslam/dynamic/onnx_util.h"

#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

using Dims = std::vector<int64_t>;

std::filesystem::path TinyModel(const std::string& name) {
  return testing::SourceDir() / "testdata" / "onnx" / name;
}

TEST(ReadOnnxInputs, ReadsNamesAndDeclaredShapes) {
  const auto detector = ReadOnnxInputs(TinyModel("yolov8_tiny.onnx"));
  ASSERT_EQ(detector.size(), 1u);
  EXPECT_EQ(detector[0].name, "images");
  EXPECT_EQ(detector[0].dims, (Dims{1, 3, 64, 64}));
  const auto pair = ReadOnnxInputs(TinyModel("flow_pair_tiny.onnx"));
  ASSERT_EQ(pair.size(), 2u);
  EXPECT_EQ(pair[0].name, "previous");
  EXPECT_EQ(pair[1].name, "current");
  EXPECT_EQ(pair[1].dims, (Dims{1, 3, 48, 64}));
}

TEST(ReadOnnxInputs, SymbolicDimensionsAreUnknownAndWeightsAreNotInputs) {
  const auto inputs = ReadOnnxInputs(TinyModel("yolov8_dynamic_tiny.onnx"));
  ASSERT_EQ(inputs.size(), 1u);  // the file lists the three weights among its inputs as well
  EXPECT_EQ(inputs[0].dims, (Dims{1, 3, -1, -1}));
  EXPECT_EQ(ModelInputSize(TinyModel("yolov8_dynamic_tiny.onnx"), {640, 480}), cv::Size(640, 480));
  EXPECT_EQ(ModelInputSize(TinyModel("flow_stacked_tiny.onnx"), {640, 480}), cv::Size(64, 48));
}

TEST(ReadOnnxInputs, ReadsARealExport) {
  const auto nanodet = testing::SharedDir() / "models" / "nanodet-m-320" / "nanodet-m-320.onnx";
  if (!std::filesystem::exists(nanodet)) GTEST_SKIP() << nanodet << " absent";
  const auto inputs = ReadOnnxInputs(nanodet);
  ASSERT_EQ(inputs.size(), 1u);
  EXPECT_EQ(inputs[0].dims, (Dims{1, 3, 320, 320}));
}

TEST(ReadOnnxInputs, FilesThatAreNotOnnxAreErrorsNamingThem) {
  testing::TempDir dir;
  testing::WriteText(dir / "text.onnx", "this is not a protobuf message at all");
  EXPECT_NE(testing::MessageOf([&] {
              ReadOnnxInputs(dir / "text.onnx");
            }).find("text.onnx: not an ONNX model"),
            std::string::npos);
  // A length that runs past the end of the file.
  testing::WriteText(dir / "cut.onnx", std::string("\x3a\x7f\x0a\x02", 4));
  EXPECT_NE(testing::MessageOf([&] {
              ReadOnnxInputs(dir / "cut.onnx");
            }).find("cut.onnx: not an ONNX model"),
            std::string::npos);
  EXPECT_NE(testing::MessageOf([&] {
              ReadOnnxInputs(dir / "absent.onnx");
            }).find("absent.onnx: cannot open"),
            std::string::npos);
}

// The reader walks bytes from a user's file: every truncation and every single-byte corruption
// of a real model must end in a result or an Error, never out-of-bounds reads (run under ASan).
TEST(ReadOnnxInputs, TruncatedOrCorruptedFilesNeverReadOutOfBounds) {
  const std::string bytes = testing::ReadText(TinyModel("yoloseg_tiny.onnx"));
  ASSERT_GT(bytes.size(), 500u);
  testing::TempDir dir;
  const auto path = dir / "m.onnx";
  int parsed = 0, rejected = 0;
  auto attempt = [&](const std::string& content) {
    std::ofstream(path, std::ios::binary) << content;
    try {
      ReadOnnxInputs(path);
      ++parsed;
    } catch (const Error&) {
      ++rejected;
    }
  };
  for (size_t n = 0; n < bytes.size(); n += 3) attempt(bytes.substr(0, n));
  for (size_t i = 0; i < bytes.size(); i += 2) {
    std::string corrupt = bytes;
    corrupt[i] = static_cast<char>(corrupt[i] ^ 0xA5);
    attempt(corrupt);
  }
  EXPECT_GT(rejected, 0);
  EXPECT_GT(parsed, 0);
}

TEST(Letterbox, KeepsTheAspectAndPadsBottomRightWithGrey) {
  const cv::Mat image(480, 640, CV_8UC3, cv::Scalar(10, 20, 30));
  cv::Mat boxed;
  EXPECT_DOUBLE_EQ(Letterbox(image, {64, 64}, &boxed), 0.1);
  ASSERT_EQ(boxed.size(), cv::Size(64, 64));
  EXPECT_EQ(boxed.at<cv::Vec3b>(47, 63), cv::Vec3b(10, 20, 30));
  EXPECT_EQ(boxed.at<cv::Vec3b>(48, 0), cv::Vec3b(114, 114, 114));
}

}  // namespace
}  // namespace sdoslam
