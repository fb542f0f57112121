#include "sdoslam/eval/mask_metrics.h"

#include <gtest/gtest.h>

#include <map>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

// A 40×30 sequence frame: a moving person (id 1, x 0–9) and a moving unknown box (id 11,
// x 20–29), both rows 0–9; everything else static.
void WriteTruth(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir / "dynamic");
  std::filesystem::create_directories(dir / "instance");
  cv::Mat dynamic(30, 40, CV_8U, cv::Scalar(0)), instance(30, 40, CV_16U, cv::Scalar(0));
  dynamic(cv::Rect(0, 0, 10, 10)).setTo(255);
  instance(cv::Rect(0, 0, 10, 10)).setTo(1);
  dynamic(cv::Rect(20, 0, 10, 10)).setTo(255);
  instance(cv::Rect(20, 0, 10, 10)).setTo(11);
  cv::imwrite((dir / "dynamic" / "f.png").string(), dynamic);
  cv::imwrite((dir / "instance" / "f.png").string(), instance);
  testing::WriteText(dir / "objects.json", R"({"objects": [
    {"id": 1, "class": "person", "known": true, "name": "p"},
    {"id": 11, "class": null, "known": false, "name": "b"}]})");
}

TEST(MaskEvaluator, CountsPixelsPerClassAndFeatures) {
  testing::TempDir dir;
  WriteTruth(dir.path());
  MaskEvaluator evaluator(dir.path());
  cv::Mat predicted(30, 40, CV_8U, cv::Scalar(0));
  predicted(cv::Rect(0, 0, 10, 10)).setTo(1);   // the whole person
  predicted(cv::Rect(20, 0, 5, 10)).setTo(2);   // half the box
  predicted(cv::Rect(0, 20, 10, 10)).setTo(2);  // 100 false pixels far from both
  evaluator.AddFrame("rgb/f.png", predicted, {{5, 5}, {27, 5}, {5, 25}, {35, 25}}, {1, 0, 2, 0});
  const MaskEvaluation& e = evaluator.result();
  EXPECT_EQ(e.frames, 1u);
  EXPECT_EQ(e.pixels.true_positive, 150u);
  EXPECT_EQ(e.pixels.false_negative, 50u);
  EXPECT_EQ(e.pixels.false_positive, 100u);
  EXPECT_DOUBLE_EQ(e.pixels.Iou(), 150.0 / 300.0);
  ASSERT_EQ(e.per_class.count("person"), 1u);
  ASSERT_EQ(e.per_class.count("unknown"), 1u);
  EXPECT_DOUBLE_EQ(e.per_class.at("person").Iou(), 1.0);  // far false positives are not its
  EXPECT_DOUBLE_EQ(e.per_class.at("unknown").Iou(), 0.5);
  EXPECT_EQ(e.features.true_positive, 1u);   // (5,5)
  EXPECT_EQ(e.features.false_negative, 1u);  // (27,5) on the box, said static
  EXPECT_EQ(e.features.false_positive, 1u);  // (5,25)
  EXPECT_EQ(e.features.true_negative, 1u);
  EXPECT_DOUBLE_EQ(e.features.Precision(), 0.5);
  EXPECT_DOUBLE_EQ(e.features.Recall(), 0.5);
}

TEST(MaskEvaluator, NeedsGroundTruthAndMatchingSizes) {
  testing::TempDir dir;
  EXPECT_THROW(MaskEvaluator{dir.path()}, Error);
  WriteTruth(dir.path());
  MaskEvaluator evaluator(dir.path());
  EXPECT_THROW(evaluator.AddFrame("f.png", cv::Mat(31, 40, CV_8U, cv::Scalar(0))), Error);
  EXPECT_THROW(evaluator.AddFrame("g.png", cv::Mat(30, 40, CV_8U, cv::Scalar(0))), Error);
}

// A person found whole in one frame and missed in the next: the summed IoU (0.5) hides the
// miss, the per-frame scores show it.
TEST(MaskEvaluator, ScoresEachClassFrameByFrame) {
  testing::TempDir dir;
  WriteTruth(dir.path());
  std::filesystem::copy_file(dir.path() / "dynamic" / "f.png", dir.path() / "dynamic" / "g.png");
  std::filesystem::copy_file(dir.path() / "instance" / "f.png", dir.path() / "instance" / "g.png");
  MaskEvaluator evaluator(dir.path());
  cv::Mat found(30, 40, CV_8U, cv::Scalar(0));
  found(cv::Rect(0, 0, 10, 10)).setTo(1);   // the person
  found(cv::Rect(20, 0, 10, 10)).setTo(2);  // the box
  evaluator.AddFrame("rgb/f.png", found);
  cv::Mat missed = found.clone();
  missed(cv::Rect(0, 0, 10, 10)).setTo(0);
  evaluator.AddFrame("rgb/g.png", missed);
  const MaskEvaluation& e = evaluator.result();
  EXPECT_DOUBLE_EQ(e.per_class.at("person").Iou(), 0.5);
  ASSERT_EQ(e.per_frame.size(), 4u);  // person and box in each frame
  std::map<std::pair<size_t, std::string>, double> iou;
  for (const auto& f : e.per_frame) iou[{f.frame, f.class_name}] = f.counts.Iou();
  EXPECT_DOUBLE_EQ((iou[{0, "person"}]), 1.0);
  EXPECT_DOUBLE_EQ((iou[{1, "person"}]), 0.0);
  EXPECT_DOUBLE_EQ((iou[{1, "unknown"}]), 1.0);
  const std::string summary = FormatMaskEvaluation(e, "run");
  EXPECT_NE(summary.find("person:   precision 1.000  recall 0.500  IoU 0.500  (in 2 frames: "
                         "median 0.500, lowest 0.000)"),
            std::string::npos)
      << summary;
  std::ostringstream csv;
  WritePerFrameScores(e, "out", csv);
  EXPECT_NE(csv.str().find("out,1,g.png,person,0.0000,0,0,100\n"), std::string::npos) << csv.str();
}

}  // namespace
}  // namespace sdoslam
