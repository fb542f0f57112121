#include "sdoslam/dynamic/detector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <functional>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

using testing::MessageOf;

TEST(FileDetector, ReadsDetectionsByRgbFileName) {
  testing::TempDir dir;
  testing::WriteText(dir / "d.json", R"({"frames": [
    {"rgb": "rgb/1.png", "detections": [{"class": "person", "score": 0.8, "box": [1, 2, 30, 40]}]},
    {"rgb": "rgb/2.png", "detections": []}]})");
  FileDetector detector(dir / "d.json");
  FrontEndFrame frame;
  frame.rgb_path = "/somewhere/else/rgb/1.png";
  const auto d = detector.Detect(frame);
  ASSERT_EQ(d.size(), 1u);
  EXPECT_EQ(d[0].class_name, "person");
  EXPECT_EQ(d[0].class_id, 0);
  EXPECT_FLOAT_EQ(d[0].score, 0.8f);
  EXPECT_EQ(d[0].box, cv::Rect2f(1, 2, 30, 40));
  frame.rgb_path = "rgb/3.png";
  EXPECT_TRUE(detector.Detect(frame).empty());
}

TEST(FileDetector, MalformedFilesNameTheFileAndTheEntry) {
  testing::TempDir dir;
  testing::WriteText(dir / "bad.json", "{\"frames\": [");
  EXPECT_NE(MessageOf([&] { FileDetector d(dir / "bad.json"); }).find("bad.json: not valid JSON"),
            std::string::npos);
  testing::WriteText(
      dir / "box.json",
      R"({"frames": [{"rgb": "a.png", "detections": [{"class": "cat", "box": [1, 2]}]}]})");
  EXPECT_NE(MessageOf([&] {
              FileDetector d(dir / "box.json");
            }).find("box.json: frames[0].detections[0]: \"box\" must be [x, y, w, h]"),
            std::string::npos);
  EXPECT_NE(
      MessageOf([&] { FileDetector d(dir / "absent.json"); }).find("absent.json: cannot open"),
      std::string::npos);
}

TEST(SuppressNonMaxima, KeepsTheBestOfOverlappingBoxesPerClass) {
  const std::vector<Detection> in = {{0, "person", 0.6f, cv::Rect2f(0, 0, 10, 10)},
                                     {0, "person", 0.9f, cv::Rect2f(1, 1, 10, 10)},
                                     {16, "dog", 0.5f, cv::Rect2f(1, 1, 10, 10)},
                                     {0, "person", 0.7f, cv::Rect2f(50, 50, 10, 10)}};
  const auto out = SuppressNonMaxima(in, 0.5);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_FLOAT_EQ(out[0].score, 0.9f);
  EXPECT_EQ(out[1].class_name, "person");
  EXPECT_FLOAT_EQ(out[1].score, 0.7f);
  EXPECT_EQ(out[2].class_name, "dog");
}

TEST(CocoClassNames, EightyInModelOrder) {
  ASSERT_EQ(CocoClassNames().size(), 80u);
  EXPECT_EQ(CocoClassNames()[0], "person");
  EXPECT_EQ(CocoClassNames()[62], "tv");
  EXPECT_EQ(CocoClassNames()[79], "toothbrush");
  // The shipped names file, when present, must agree line by line.
  const auto names = testing::SharedDir() / "models" / "coco.names";
  if (!std::filesystem::exists(names)) GTEST_SKIP() << names << " absent";
  std::ifstream in(names);
  std::string line;
  // Darknet spellings of the same classes.
  const std::map<std::string, std::string> alias = {
      {"motorbike", "motorcycle"},     {"aeroplane", "airplane"},       {"sofa", "couch"},
      {"pottedplant", "potted plant"}, {"diningtable", "dining table"}, {"tvmonitor", "tv"}};
  for (size_t i = 0; std::getline(in, line) && i < 80; ++i) {
    EXPECT_EQ(alias.count(line) ? alias.at(line) : line, CocoClassNames()[i]);
  }
}

// The shared ONNX models: real decoding on a real frame (skips without ../shared).
class OnnxDetectors : public ::testing::Test {
 protected:
  void SetUp() override {
    models_ = testing::SharedDir() / "models";
    const auto rgb_list = testing::SharedDir() / "data" / "tum_fr2_desk_50" / "rgb";
    if (!std::filesystem::exists(models_ / "nanodet-m-320" / "nanodet-m-320.onnx") ||
        !std::filesystem::is_directory(rgb_list))
      GTEST_SKIP() << "../shared models or data absent";
    std::vector<std::filesystem::path> images;
    for (const auto& e : std::filesystem::directory_iterator(rgb_list)) images.push_back(e.path());
    std::sort(images.begin(), images.end());
    frame_.rgb_path = images.front();
    frame_.bgr = cv::imread(images.front().string());
    ASSERT_FALSE(frame_.bgr.empty());
  }
  std::filesystem::path models_;
  FrontEndFrame frame_;
};

// fr2/desk: a desk with a monitor, keyboard and mouse, no person.
bool FindsDeskObjects(const std::vector<Detection>& d, cv::Size image, bool no_person = true) {
  bool desk_object = false;
  for (const Detection& x : d) {
    EXPECT_GE(x.box.x, 0);
    EXPECT_LE(x.box.br().x, image.width + 0.5f);
    EXPECT_GE(x.score, 0.3f);
    if (no_person) {
      EXPECT_NE(x.class_name, "person");
    }
    desk_object |= x.class_name == "tv" || x.class_name == "keyboard" || x.class_name == "laptop" ||
                   x.class_name == "mouse" || x.class_name == "cup";
  }
  return desk_object;
}

TEST_F(OnnxDetectors, NanoDetFindsTheDeskObjects) {
  DetectorOptions o;  // default threshold 0.4
  auto detector = MakeNanoDetDetector(models_ / "nanodet-m-320" / "nanodet-m-320.onnx", o);
  const auto d = detector->Detect(frame_);
  EXPECT_TRUE(FindsDeskObjects(d, frame_.bgr.size())) << d.size() << " detections";
}

TEST_F(OnnxDetectors, FastestDetRunsAndDecodesBoxesInsideTheImage) {
  const auto model = models_ / "fastestdet-352" / "fastestdet-352.onnx";
  if (!std::filesystem::exists(model)) GTEST_SKIP();
  DetectorOptions o;
  o.score_threshold = 0.3;
  const auto d = MakeFastestDetDetector(model, o)->Detect(frame_);
  // Box sanity only: FastestDet is too weak to require a find, and it sees a person at 0.3.
  FindsDeskObjects(d, frame_.bgr.size(), /*no_person=*/false);
}

TEST_F(OnnxDetectors, AModelOfAnotherFormatIsRejectedBeforeUse) {
  const auto nanodet = models_ / "nanodet-m-320" / "nanodet-m-320.onnx";
  const std::string as_fastest = MessageOf([&] { MakeFastestDetDetector(nanodet, {}); });
  EXPECT_NE(as_fastest.find("nanodet-m-320.onnx"), std::string::npos) << as_fastest;
  // Either it does not run on the backend's input or its outputs do not fit: both say so.
  EXPECT_NE(as_fastest.find("'fastestdet'"), std::string::npos) << as_fastest;
  const std::string as_yolo = MessageOf([&] { MakeYolov8Detector(nanodet, {}); });
  EXPECT_NE(as_yolo.find("'yolov8'"), std::string::npos) << as_yolo;
}

// testdata/onnx/yolov8_tiny.onnx (scripts/make_test_models.py): a 64×64 model of the YOLOv8
// signature whose 'person' score is the input's mean red and whose 'car' score is its mean
// blue, with constant boxes in input pixels. A 640×480 image letterboxes to 64×48 (scale 0.1)
// above 16 rows of grey padding, so a pure red image scores 0.75 + 0.25·114/255 for a person.
class TinyYolov8 : public ::testing::Test {
 protected:
  std::vector<Detection> DetectOn(const cv::Scalar& bgr) {
    FrontEndFrame frame;
    frame.bgr = cv::Mat(480, 640, CV_8UC3, bgr);
    return detector_->Detect(frame);
  }
  std::unique_ptr<Detector> detector_ =
      MakeYolov8Detector(testing::SourceDir() / "testdata/onnx/yolov8_tiny.onnx", {});
};

constexpr float kRedImageScore = 0.75f + 0.25f * 114.0f / 255.0f;

TEST_F(TinyYolov8, DecodesBoxesThroughTheLetterboxInRgbOrder) {
  const auto red = DetectOn(cv::Scalar(0, 0, 255));
  // Anchor 1 duplicates anchor 0 at 0.9 of its score: class-wise NMS keeps one.
  ASSERT_EQ(red.size(), 1u);
  EXPECT_EQ(red[0].class_name, "person");
  EXPECT_NEAR(red[0].score, kRedImageScore, 1e-4);
  // Box (cx 20, cy 26, w 16, h 20) in model pixels, divided by the letterbox scale 0.1.
  EXPECT_NEAR(red[0].box.x, 120, 0.01);
  EXPECT_NEAR(red[0].box.y, 160, 0.01);
  EXPECT_NEAR(red[0].box.width, 160, 0.01);
  EXPECT_NEAR(red[0].box.height, 200, 0.01);

  const auto blue = DetectOn(cv::Scalar(255, 0, 0));
  ASSERT_EQ(blue.size(), 1u);
  EXPECT_EQ(blue[0].class_name, "car");
  EXPECT_NEAR(blue[0].box.x, 120, 0.01);
  EXPECT_NEAR(blue[0].box.y, 360, 0.01);
  EXPECT_NEAR(blue[0].box.br().x, 200, 0.01);
  EXPECT_NEAR(blue[0].box.br().y, 440, 0.01);
}

TEST_F(TinyYolov8, ScoresBelowTheThresholdAreDropped) {
  // Black: only the padding (mean 0.11 in every channel) scores.
  EXPECT_TRUE(DetectOn(cv::Scalar(0, 0, 0)).empty());
  DetectorOptions strict;
  strict.score_threshold = 0.9;
  detector_ = MakeYolov8Detector(testing::SourceDir() / "testdata/onnx/yolov8_tiny.onnx", strict);
  EXPECT_TRUE(DetectOn(cv::Scalar(0, 0, 255)).empty());
}

TEST(TinyYolov8Dynamic, ADynamicInputSizeLetterboxesTo640) {
  // The same weights with symbolic height and width: the image goes in at 640×640 (scale 1),
  // so the boxes come back as the model's constants.
  auto detector =
      MakeYolov8Detector(testing::SourceDir() / "testdata/onnx/yolov8_dynamic_tiny.onnx", {});
  FrontEndFrame frame;
  frame.bgr = cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 255));
  const auto red = detector->Detect(frame);
  ASSERT_EQ(red.size(), 1u);
  // OpenCV's pooling sums 409 600 floats in single precision: the padding's 0.447 adds up as
  // 0.4375 once the sum passes 2^18.
  EXPECT_NEAR(red[0].score, kRedImageScore, 5e-3);
  EXPECT_NEAR(red[0].box.x, 12, 0.01);
  EXPECT_NEAR(red[0].box.y, 16, 0.01);
  EXPECT_NEAR(red[0].box.width, 16, 0.01);
}

TEST(TinyOnnxModels, AModelOfAnotherSignatureIsRejectedBeforeUse) {
  const auto onnx = testing::SourceDir() / "testdata/onnx";
  const std::string as_nanodet =
      MessageOf([&] { MakeNanoDetDetector(onnx / "yolov8_tiny.onnx", {}); });
  EXPECT_NE(as_nanodet.find("yolov8_tiny.onnx"), std::string::npos) << as_nanodet;
  EXPECT_NE(as_nanodet.find("'nanodet'"), std::string::npos) << as_nanodet;
  // The segmenter's two outputs are not YOLOv8's 1×84×N.
  const std::string as_yolo =
      MessageOf([&] { MakeYolov8Detector(onnx / "yoloseg_tiny.onnx", {}); });
  EXPECT_NE(as_yolo.find("do not match the 'yolov8' format"), std::string::npos) << as_yolo;
}

TEST(OnnxDetectorFiles, MissingOrNonOnnxFilesAreClearErrors) {
  testing::TempDir dir;
  EXPECT_NE(MessageOf([&] {
              MakeNanoDetDetector(dir / "absent.onnx", {});
            }).find("absent.onnx: model file for 'nanodet' does not exist"),
            std::string::npos);
  testing::WriteText(dir / "junk.onnx", "this is not a protobuf");
  EXPECT_NE(MessageOf([&] { MakeNanoDetDetector(dir / "junk.onnx", {}); }).find("junk.onnx"),
            std::string::npos);
}

}  // namespace
}  // namespace sdoslam
