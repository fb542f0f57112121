#include "sdoslam/io/dataset.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

// A two-frame OMD segment with 16 × 12 images, written by hand.
void WriteOmd(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir / "rgbd");
  testing::WriteText(dir / "rgbd" / "rgbd.csv",
                     "frame_num, time_sec, time_nsec\n1, 20, 0\n2, 20, 33333333\n");
  for (const char* stem : {"000001", "000002"}) {
    cv::imwrite((dir / "rgbd" / (std::string(stem) + "_color.png")).string(),
                cv::Mat(12, 16, CV_8UC3, cv::Scalar(1, 2, 3)));
    cv::imwrite((dir / "rgbd" / (std::string(stem) + "_aligned_depth.png")).string(),
                cv::Mat(12, 16, CV_16UC1, cv::Scalar(1500)));
  }
  testing::WriteText(dir / "kalibr.yaml",
                     "cam0:\n  intrinsics: [20, 21, 8, 6]\n  resolution: [16, 12]\n"
                     "  rostopic: /camera/color/image_raw\n");
}

// A one-frame TUM folder with 16 x 12 images.
void WriteOneFrameTum(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir / "rgb");
  std::filesystem::create_directories(dir / "depth");
  cv::imwrite((dir / "rgb" / "1.png").string(), cv::Mat(12, 16, CV_8UC3, cv::Scalar(1, 2, 3)));
  cv::imwrite((dir / "depth" / "1.png").string(), cv::Mat(12, 16, CV_16UC1, cv::Scalar(9)));
  testing::WriteText(dir / "rgb.txt", "1.0 rgb/1.png\n");
  testing::WriteText(dir / "depth.txt", "1.0 depth/1.png\n");
}

CameraOptions Tiny16x12() {
  CameraOptions camera;
  camera.width = 16;
  camera.height = 12;
  camera.fx = camera.fy = 20;
  camera.cx = 8;
  camera.cy = 6;
  return camera;
}

CameraOptions FromDataset() {
  CameraOptions camera;
  camera.from_dataset = true;
  camera.depth_factor = 1000;
  return camera;
}

TEST(DatasetLayout, IsRecognisedByItsFilesAndAMixedFolderIsRefused) {
  testing::TempDir dir;
  WriteOmd(dir / "omd");
  EXPECT_EQ(DetectLayout(dir / "omd"), DatasetLayout::kOmd);
  std::filesystem::create_directories(dir / "tum");
  testing::WriteText(dir / "tum" / "rgb.txt", "");
  EXPECT_NE(testing::MessageOf([&] { DetectLayout(dir / "tum"); }).find("depth.txt is missing"),
            std::string::npos);
  testing::WriteText(dir / "tum" / "depth.txt", "");
  EXPECT_EQ(DetectLayout(dir / "tum"), DatasetLayout::kTum);
  std::filesystem::rename(dir / "tum", dir / "rgbd_bonn_crowd");
  EXPECT_EQ(DetectLayout(dir / "rgbd_bonn_crowd"), DatasetLayout::kBonn);
  EXPECT_EQ(DetectLayout(dir / "rgbd_bonn_crowd" / ""), DatasetLayout::kBonn);
  testing::WriteText(dir / "omd" / "rgb.txt", "");
  EXPECT_NE(testing::MessageOf([&] { DetectLayout(dir / "omd"); }).find("has both TUM lists"),
            std::string::npos);
  std::filesystem::create_directories(dir / "empty");
  EXPECT_NE(testing::MessageOf([&] { DetectLayout(dir / "empty"); })
                .find("expected rgb.txt and depth.txt (TUM, Bonn, sdoslam synth) or "
                      "rgbd/rgbd.csv (Oxford Multi-motion)"),
            std::string::npos);
  EXPECT_THROW(ParseDatasetLayout("kitti"), Error);
}

// A case worked by hand: the markers at (1, 2, 3), unrotated. T_ros · T_marker · T_ros is then
// a pure translation by R_ros·(1, 2, 3) = (−1, 3, 2), after which T_m adds its own offset.
TEST(BonnGroundTruth, BringsTheMarkersToTheCamera) {
  StampedPose marker;
  marker.timestamp = 3.0;
  marker.T_world_camera.translation() = Eigen::Vector3d(1, 2, 3);
  const Trajectory camera = BonnCameraTrajectory({marker});
  ASSERT_EQ(camera.size(), 1u);
  EXPECT_TRUE(camera[0].T_world_camera.translation().isApprox(
      Eigen::Vector3d(-1 + 0.0113, 3 - 0.0098, 2 + 0.0111), 1e-12));
  const Eigen::Matrix3d R = camera[0].T_world_camera.linear();
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-9);  // rigid
  // The optical axis: T_m's third column, without its 1.059 scale.
  EXPECT_TRUE((R * Eigen::Vector3d::UnitZ())
                  .isApprox(Eigen::Vector3d(-0.2389, -0.6413, -0.8085).normalized(), 1e-3));
}

TEST(Dataset, TakesTheIntrinsicsFromAnOmdCalibrationAndTheDepthScaleFromTheConfig) {
  testing::TempDir dir;
  WriteOmd(dir.path());
  const RgbdDataset dataset(dir.path(), FromDataset());
  EXPECT_EQ(dataset.layout(), DatasetLayout::kOmd);
  ASSERT_EQ(dataset.size(), 2u);
  EXPECT_EQ(dataset.camera().fy, 21);
  EXPECT_EQ(dataset.camera().width, 16);
  EXPECT_FALSE(dataset.camera().from_dataset);
  EXPECT_FALSE(dataset.ground_truth().has_value());  // no vicon.csv: frames only
  const RgbdFrame frame = dataset.Load(1);
  EXPECT_NEAR(frame.timestamp, 20.033333333, 1e-9);
  EXPECT_FLOAT_EQ(frame.depth.at<float>(5, 5), 1.5f);
}

TEST(Dataset, CameraFromATumFolderNeedsItsCameraYaml) {
  testing::TempDir dir;
  testing::WriteText(dir / "rgb.txt", "");
  testing::WriteText(dir / "depth.txt", "");
  EXPECT_NE(testing::MessageOf([&] {
              RgbdDataset(dir.path(), FromDataset());
            }).find("has no camera.yaml"),
            std::string::npos);
}

TEST(Dataset, AMalformedGroundTruthFailsWhenTheDatasetIsOpened) {
  testing::TempDir dir;
  WriteOneFrameTum(dir.path());
  testing::WriteText(dir / "groundtruth.txt", "1.0 0 0 0 0 0 0\n");
  const CameraOptions camera = Tiny16x12();
  EXPECT_NE(testing::MessageOf([&] { RgbdDataset(dir.path(), camera); }).find("groundtruth.txt:1"),
            std::string::npos);
}

TEST(Dataset, APngOfTheWrongSizeIsRefusedFromItsHeaderBeforeDecoding) {
  testing::TempDir dir;
  WriteOneFrameTum(dir.path());
  // A real PNG header declaring 16384 x 16384, then garbage: decoding would fail (or, for a
  // genuine file, take 853 MB); the header alone must decide.
  std::string png = "\x89PNG\r\n\x1a\n";
  png += std::string("\0\0\0\x0dIHDR", 8);
  png += std::string("\0\0\x40\0\0\0\x40\0", 8);
  png += "not image data";
  testing::WriteText(dir / "rgb" / "1.png", png);
  const CameraOptions camera = Tiny16x12();
  const RgbdDataset dataset(dir.path(), camera);
  EXPECT_EQ(
      testing::MessageOf([&] { dataset.Load(0); }),
      (dir / "rgb" / "1.png").string() + ": image is 16384x16384, the camera config says 16x12");
}

}  // namespace
}  // namespace sdoslam
