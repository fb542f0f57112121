#include "sdoslam/dynamic/front_end.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/options_test_util.h"
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

// A frame's grey image (the caller's, shared with feature extraction) must be the colour
// image's size and single-channel 8-bit; one that is not is named, not handed to the flow.
TEST(FrontEndInput, AGreyImageThatDoesNotFitIsNamed) {
  FrontEnd front_end(FrontEndOptions{}, {}, {640, 480}, {},
                     cv::Matx33d(525, 0, 319.5, 0, 525, 239.5, 0, 0, 1));
  FrontEndFrame frame;
  frame.bgr = cv::Mat(480, 640, CV_8UC3, cv::Scalar(40, 80, 120));
  frame.depth = cv::Mat(480, 640, CV_32F, cv::Scalar(2.0f));
  for (const cv::Mat& gray : {cv::Mat(240, 320, CV_8UC1), cv::Mat(480, 640, CV_8UC3)}) {
    frame.gray = gray;
    const std::string message = testing::MessageOf([&] { front_end.Process(frame); });
    EXPECT_NE(message.find("frame 0: the grey image is not 8-bit single-channel 640x480"),
              std::string::npos)
        << message;
  }
  cv::cvtColor(frame.bgr, frame.gray, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(front_end.Process(frame).labels.size(), cv::Size(640, 480));
}

std::string WrittenFrontEndOptions(const FrontEndOptions& options) {
  return testing::WrittenYaml(options, WriteFrontEndOptions);
}

std::string FrontEndErrorOf(const std::string& yaml) {
  return testing::ReadErrorOf(yaml, ReadFrontEndOptions);
}

// A smooth random texture of 12 px blobs, for the moving-block tests: the front end computes
// flow at 256 px wide.
cv::Mat SmoothTexture(cv::Size size, cv::RNG& rng) {
  cv::Mat coarse(size.height / 12, size.width / 12, CV_8UC3), texture;
  rng.fill(coarse, cv::RNG::UNIFORM, 0, 255);
  cv::resize(coarse, texture, size, 0, 0, cv::INTER_CUBIC);
  return texture;
}

// Writes `dir`/detections.json for `frames` frames named <k>.png: a person boxed at box_of(k)
// where `boxed(k)`. Returns the frames' image paths.
std::vector<std::filesystem::path> WritePersonBoxes(const std::filesystem::path& dir, int frames,
                                                    const std::function<cv::Rect(int)>& box_of,
                                                    const std::function<bool(int)>& boxed) {
  std::vector<std::filesystem::path> rgb_paths;
  nlohmann::json detections = {{"frames", nlohmann::json::array()}};
  for (int k = 0; k < frames; ++k) {
    rgb_paths.push_back(dir / fmt::format("{}.png", k));
    const cv::Rect b = box_of(k);
    nlohmann::json boxes = nlohmann::json::array();
    if (boxed(k)) boxes.push_back({{"class", "person"}, {"box", {b.x, b.y, b.width, b.height}}});
    detections["frames"].push_back(
        {{"rgb", rgb_paths.back().filename().string()}, {"detections", boxes}});
  }
  std::ofstream(dir / "detections.json") << detections.dump();
  return rgb_paths;
}

// Frame k of a textured `block` at `box` (1.5 m) before a textured `wall` (3 m); the wall alone
// where `box` is empty.
FrontEndFrame BlockOnWall(int k, const std::filesystem::path& rgb_path, const cv::Mat& wall,
                          const cv::Mat& block, const cv::Rect& box) {
  FrontEndFrame f;
  f.index = static_cast<size_t>(k);
  f.rgb_path = rgb_path;
  f.bgr = wall.clone();
  f.depth = cv::Mat(wall.size(), CV_32F, cv::Scalar(3.0f));
  if (box.area() > 0) {
    block.copyTo(f.bgr(box));
    f.depth(box).setTo(1.5f);
  }
  return f;
}

// detector.every: on the frames between detections, a box follows its object by the flow of one
// frame, though the flow spans flow.frame_gap frames. A textured block moves 6 px a frame over a
// textured wall; the detections file boxes it exactly on every frame, and the detector runs on
// frames 0, 3, 6 and 9 only. Moved by the whole span's flow, the box of frame 4 ran 12 px ahead.
TEST(FrontEndDetectEvery, CarriedBoxesFollowTheirObjectFrameByFrame) {
  testing::TempDir dir;
  const cv::Size size(640, 480);
  cv::RNG rng(5);
  const cv::Mat wall = SmoothTexture(size, rng), block = SmoothTexture({100, 160}, rng);
  auto box_of = [](int k) { return cv::Rect(120 + 6 * k, 150, 100, 160); };
  const int frames = 10;
  const std::vector<std::filesystem::path> rgb_paths =
      WritePersonBoxes(dir.path(), frames, box_of, [](int) { return true; });
  FrontEndOptions o;
  o.detector = "file";
  o.detections_file = dir / "detections.json";
  o.detect_every = 3;
  FrontEnd front_end(o, dir.path(), size, rgb_paths,
                     cv::Matx33d(525, 0, 320, 0, 525, 240, 0, 0, 1));
  for (int k = 0; k < frames; ++k) {
    const SdoResult r = front_end.Process(
        BlockOnWall(k, rgb_paths[static_cast<size_t>(k)], wall, block, box_of(k)));
    ASSERT_EQ(r.detections.size(), 1u) << "frame " << k;
    const cv::Rect2f& got = r.detections[0].box;
    // Within half a frame's motion (3 px; a pixel of the 256 px flow is 2.5): a box left where
    // it was detected is 6 px behind a frame later, the old shift put it 12 px ahead.
    EXPECT_NEAR(got.x, box_of(k).x, 3.0) << "frame " << k;
    EXPECT_NEAR(got.y, box_of(k).y, 3.0) << "frame " << k;
  }
  // A depth image that does not fit the colour image is refused, naming the frame.
  FrontEndFrame bad;
  bad.index = 10;
  bad.bgr = wall.clone();
  bad.depth = cv::Mat(240, 320, CV_32F, cv::Scalar(3.0f));
  try {
    front_end.Process(bad);
    ADD_FAILURE() << "a 320x240 depth image was taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("frame 10: depth is 320x240"), std::string::npos)
        << e.what();
  }
}

// detector.hold_frames: a person walks in (boxed by the detector on frames 0-5), stops and
// stands still with the detector missing it (frames 6-29), then is gone (30-33). The held box
// keeps the person labelled through the stand and ends when the person has left; without the
// hold the still person is static from the first missed detector frame on.
TEST(FrontEndDetectionHold, AStillPersonTheDetectorMissesStaysLabelledUntilItLeaves) {
  testing::TempDir dir;
  const cv::Size size(640, 480);
  cv::RNG rng(7);
  const cv::Mat wall = SmoothTexture(size, rng), body = SmoothTexture({100, 200}, rng);
  auto box_of = [](int k) { return cv::Rect(150 + 8 * std::min(k, 6), 140, 100, 200); };
  const int frames = 34;
  const std::vector<std::filesystem::path> rgb_paths =
      WritePersonBoxes(dir.path(), frames, box_of, [](int k) { return k < 6; });
  for (const int hold_frames : {300, 0}) {
    FrontEndOptions o;
    o.detector = "file";
    o.detections_file = dir / "detections.json";
    o.hold.hold_frames = hold_frames;
    FrontEnd front_end(o, dir.path(), size, rgb_paths,
                       cv::Matx33d(525, 0, 320, 0, 525, 240, 0, 0, 1));
    for (int k = 0; k < frames; ++k) {
      const SdoResult r = front_end.Process(BlockOnWall(k, rgb_paths[static_cast<size_t>(k)], wall,
                                                        body, k < 30 ? box_of(k) : cv::Rect()));
      const int known = cv::countNonZero(r.labels == kKnownMovable);
      const int on_body = cv::countNonZero(r.labels(box_of(k)) == kKnownMovable);
      SCOPED_TRACE(fmt::format("hold_frames {}, frame {}", hold_frames, k));
      if (k < 6) {
        EXPECT_GE(on_body, box_of(k).area() * 9 / 10);
      } else if (k >= 8 && k < 30) {
        if (hold_frames > 0) {
          EXPECT_GE(on_body, box_of(k).area() * 9 / 10);
          EXPECT_LE(known, box_of(k).area() * 12 / 10) << "the label spread off the body";
        } else {
          EXPECT_EQ(known, 0);
        }
      } else if (k >= 31) {
        EXPECT_EQ(known, 0) << "held on after the person left";
      }
    }
  }
}

// segmenter.every: a uniform flow of (9, -6) flow pixels over 3 frames moves each label a third
// of it a frame, scaled from the flow's size to the labels' (here the labels are twice as wide).
TEST(CarrySegmentsAlongFlow, EachPixelTakesTheLabelOfWhereItWasAFrameBefore) {
  Segmentation last;
  last.count = 2;
  last.labels = cv::Mat(40, 60, CV_32S, cv::Scalar(0));
  last.labels(cv::Rect(20, 10, 10, 10)).setTo(1);
  const cv::Mat flow(20, 30, CV_32FC2, cv::Scalar(9.0f, -6.0f));
  const Segmentation carried = CarrySegmentsAlongFlow(last, flow, 3);
  EXPECT_EQ(carried.count, 2);
  ASSERT_EQ(carried.labels.size(), last.labels.size());
  // 3 and -2 flow pixels a frame: 6 and -4 label pixels. What came from outside is -1.
  cv::Mat expected(40, 60, CV_32S, cv::Scalar(0));
  expected(cv::Rect(26, 6, 10, 10)).setTo(1);
  expected(cv::Rect(0, 0, 6, 40)).setTo(-1);
  expected(cv::Rect(0, 36, 60, 4)).setTo(-1);
  EXPECT_EQ(cv::countNonZero(carried.labels != expected), 0);
  // A new image: the last frame's labels are not written.
  EXPECT_NE(carried.labels.data, last.labels.data);
  EXPECT_EQ(cv::countNonZero(last.labels == 1), 100);
  // Without flow (the first frame) the labels stay where they were.
  EXPECT_EQ(cv::countNonZero(CarrySegmentsAlongFlow(last, cv::Mat(), 0).labels != last.labels), 0);
}

// A block that moves over a still wall: the labels of the frames the segmenter skips follow it as
// the segmenter's own labels of those frames do. (Each pixel warped by the flow at it failed
// here: the flow lies on the older frame's grid, so the block's leading edge stayed behind.)
TEST(FrontEndSegmentEvery, CarriedSegmentsFollowAMovingBlock) {
  const cv::Size size(640, 480);
  cv::RNG rng(7);
  const cv::Mat wall = SmoothTexture(size, rng), block = SmoothTexture({100, 160}, rng);
  auto box_of = [](int k) { return cv::Rect(120 + 8 * k, 150, 100, 160); };
  const cv::Matx33d K(525, 0, 320, 0, 525, 240, 0, 0, 1);
  FrontEndOptions every_frame, every_third;
  every_frame.detector = every_third.detector = "none";
  every_third.segment_every = 3;
  FrontEnd fresh(every_frame, {}, size, {}, K), carrying(every_third, {}, size, {}, K);
  // The block's share of its own segment: the label most common inside its box.
  auto block_mask = [&](const cv::Mat& labels, int k) {
    cv::Mat full;
    cv::resize(labels, full, size, 0, 0, cv::INTER_NEAREST);
    const cv::Rect inner = box_of(k) - cv::Point(-20, -20) - cv::Size(40, 40);
    std::map<int, int> votes;
    for (int y = inner.y; y < inner.br().y; ++y)
      for (int x = inner.x; x < inner.br().x; ++x) ++votes[full.at<int>(y, x)];
    const int label = std::max_element(votes.begin(), votes.end(), [](auto& a, auto& b) {
                        return a.second < b.second;
                      })->first;
    return cv::Mat(full == label);
  };
  for (int k = 0; k < 9; ++k) {
    FrontEndFrame f;
    f.index = static_cast<size_t>(k);
    f.bgr = wall.clone();
    block.copyTo(f.bgr(box_of(k)));
    f.depth = cv::Mat(size, CV_32F, cv::Scalar(3.0f));
    f.depth(box_of(k)).setTo(1.5f);
    const cv::Mat want = block_mask(fresh.Process(f).segments.labels, k);
    const cv::Mat got = block_mask(carrying.Process(f).segments.labels, k);
    const double iou = static_cast<double>(cv::countNonZero(want & got)) /
                       std::max(1, cv::countNonZero(want | got));
    // Left where it was segmented, the block's segment would be 8 px (one frame) or 16 px behind:
    // IoU 0.85 or 0.74 with its 100 px width. Carried, it is within a label pixel (2 px) a frame:
    // measured 1.0 on frames carried once, 0.92 on those carried twice.
    EXPECT_GE(iou, 0.90) << "frame " << k;
  }
}

// Every setting changed, written and read back through the keys: each comes back as written.
// (ReadFields, not ReadFrontEndOptions: the changed values are not meant to pass the checks.)
TEST(FrontEndOptionsTest, EverySettingRoundTripsThroughTheWrittenConfig) {
  FrontEndOptions changed;
  testing::ChangeEveryField(&changed);
  const auto defaults = testing::FieldValues(FrontEndOptions());
  const auto expected = testing::FieldValues(changed);
  for (const auto& [path, value] : expected) EXPECT_NE(value, defaults.at(path)) << path;
  ConfigMap root = ConfigMap::LoadString(WrittenFrontEndOptions(changed), "written.yaml");
  FrontEndOptions read;
  std::optional<ConfigMap> section = root.Section("dynamic");
  ASSERT_TRUE(section);
  ReadFields(*section, &read);
  section->RejectUnknownKeys();
  root.RejectUnknownKeys();
  EXPECT_EQ(testing::FieldValues(read), expected);
}

TEST(FrontEndOptionsTest, TheWrittenConfigReadsBackToTheSameOptions) {
  FrontEndOptions o;
  o.segmenter = "rgbd";
  o.rgbd.work_width = 200;
  o.hog.hit_threshold = 0.25;
  o.flow_options.onnx_input_names = {"a", "b"};
  o.classifier.movable_classes = {"person", "cat"};
  const std::string text = WrittenFrontEndOptions(o);
  ConfigMap root = ConfigMap::LoadString(text, "written.yaml");
  EXPECT_EQ(testing::FieldValues(ReadFrontEndOptions(root)), testing::FieldValues(o));
  root.RejectUnknownKeys();
  EXPECT_EQ(text.find("hog_work_width"), std::string::npos) << text;
}

TEST(FrontEndOptionsTest, UnknownKeysAreErrorsNamingFileLineAndTheKnownKeys) {
  EXPECT_EQ(FrontEndErrorOf("dynamic:\n  segmenter:\n    rgbd:\n      work_widht: 200\n"),
            "c.yaml:4: unknown key 'dynamic.segmenter.rgbd.work_widht' (known here: colour_weight, "
            "depth_weight, k, min_size, sigma, work_width)");
  EXPECT_NE(FrontEndErrorOf("dynamic:\n  detector:\n    hog_scale: 1.2\n")
                .find("c.yaml:3: unknown key 'dynamic.detector.hog_scale'"),
            std::string::npos);
}

TEST(FrontEndOptionsTest, CheckMessagesNameTheConfigPath) {
  EXPECT_EQ(FrontEndErrorOf("dynamic:\n  segmenter:\n    rgbd:\n      work_width: 8\n"),
            "c.yaml: dynamic.segmenter.rgbd.work_width must be at least 16");
  EXPECT_EQ(FrontEndErrorOf("dynamic:\n  detector:\n    hog:\n      scale: 1\n"),
            "c.yaml: dynamic.detector.hog.scale must exceed 1");
  EXPECT_EQ(FrontEndErrorOf("dynamic:\n  detector:\n    every: 0\n"),
            "c.yaml: dynamic.detector.every must be at least 1");
  EXPECT_EQ(FrontEndErrorOf("dynamic:\n  segmenter:\n    every: 0\n"),
            "c.yaml: dynamic.segmenter.every must be at least 1");
  EXPECT_EQ(FrontEndErrorOf("dynamic:\n  boundaries:\n    strong: 2\n"),
            "c.yaml: dynamic.boundaries.strong must be in (0, 1)");
  EXPECT_EQ(FrontEndErrorOf("dynamic:\n  classifier:\n    min_box_iou: 2\n"),
            "c.yaml: dynamic.classifier.min_box_iou must be in [0, 1]");
}

}  // namespace
}  // namespace sdoslam
