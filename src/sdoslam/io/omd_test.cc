#include "sdoslam/io/omd.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/io/dataset.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

using Eigen::AngleAxisd;
using Eigen::Isometry3d;
using Eigen::Vector3d;

Isometry3d Make(const Vector3d& t, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Isometry3d T = Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

// The composition checked against a case worked out by hand: the apparatus turned 90° about
// world z and placed at (1, 2, 3); the left camera 10 cm along the apparatus x; the colour camera
// 5 cm along the left camera's y, turned 90° about its x.
TEST(OmdGroundTruth, ComposesApparatusCalibrationAndCameraChain) {
  const Isometry3d T_world_apparatus =
      Make({1, 2, 3}, AngleAxisd(M_PI / 2, Vector3d::UnitZ()).toRotationMatrix());
  const Isometry3d T_apparatus_left = Make({0.1, 0, 0});
  const Isometry3d T_left_rgb =
      Make({0, 0.05, 0}, AngleAxisd(M_PI / 2, Vector3d::UnitX()).toRotationMatrix());
  const Trajectory camera =
      ComposeCameraTrajectory({{7.5, T_world_apparatus}}, T_apparatus_left, T_left_rgb);
  ASSERT_EQ(camera.size(), 1u);
  EXPECT_EQ(camera[0].timestamp, 7.5);
  // The colour camera's centre is (0.1, 0.05, 0) in the apparatus; turned by 90° about z that is
  // (−0.05, 0.1, 0), plus (1, 2, 3).
  EXPECT_TRUE(camera[0].T_world_camera.translation().isApprox(Vector3d(0.95, 2.1, 3), 1e-12));
  // Its optical axis (z) is the left camera's −y, which the apparatus' turn takes to world +x.
  EXPECT_TRUE(
      (camera[0].T_world_camera.linear() * Vector3d::UnitZ()).isApprox(Vector3d(1, 0, 0), 1e-12));
}

const char* kKalibr = R"(cam0:
  camera_model: pinhole
  distortion_model: radtan
  distortion_coeffs: [0, 0, 0, 0]
  intrinsics: [400, 400, 320, 240]
  resolution: [640, 480]
  rostopic: /stereo/left/image_raw
cam1:
  T_cn_cnm1:
  - [1, 0, 0, -0.1]
  - [0, 1, 0, 0]
  - [0, 0, 1, 0]
  - [0, 0, 0, 1]
  distortion_model: radtan
  distortion_coeffs: [0, 0, 0, 0]
  intrinsics: [400, 400, 320, 240]
  resolution: [640, 480]
  rostopic: /stereo/right/image_raw
cam2:
  T_cn_cnm1:
  - [1, 0, 0, 0.05]
  - [0, 1, 0, 0.01]
  - [0, 0, 1, 0]
  - [0, 0, 0, 1]
  distortion_model: radtan
  distortion_coeffs: [0.1, -0.2, 0.001, 0.002]
  intrinsics: [615.5, 616.25, 322.5, 238.75]
  resolution: [640, 480]
  rostopic: /camera/color/image_raw
)";

TEST(OmdCalibration, ComposesTheKalibrChainIntoEachCameraInCam0) {
  testing::TempDir dir;
  testing::WriteText(dir / "kalibr.yaml", kKalibr);
  const std::vector<KalibrCamera> cameras = ReadKalibrCameras(dir / "kalibr.yaml");
  ASSERT_EQ(cameras.size(), 3u);
  EXPECT_TRUE(cameras[0].T_cam0_cam.isApprox(Isometry3d::Identity()));
  // T_cn_cnm1 maps cam n−1 points into cam n: cam1 sits 10 cm along cam0's x, and cam2 is 5 cm
  // back and 1 cm up from cam1, so cam2's centre is (0.05, −0.01, 0) in cam0.
  EXPECT_TRUE(cameras[1].T_cam0_cam.translation().isApprox(Vector3d(0.1, 0, 0), 1e-12));
  EXPECT_TRUE(cameras[2].T_cam0_cam.translation().isApprox(Vector3d(0.05, -0.01, 0), 1e-12));
  EXPECT_EQ(cameras[2].intrinsics.fx, 615.5);
  EXPECT_EQ(cameras[2].intrinsics.cy, 238.75);
  EXPECT_EQ(cameras[2].intrinsics.k2, -0.2);
  EXPECT_EQ(cameras[2].intrinsics.p2, 0.002);
  EXPECT_EQ(cameras[2].rostopic, "/camera/color/image_raw");
}

TEST(OmdCalibration, ACameraEntryThatIsNotAMapIsNamed) {
  testing::TempDir dir;
  testing::WriteText(dir / "kalibr.yaml", "cam0: 5\n");
  std::string message = testing::MessageOf([&] { ReadKalibrCameras(dir / "kalibr.yaml"); });
  EXPECT_NE(message.find("kalibr.yaml: cam0 must be a map of its settings"), std::string::npos)
      << message;
  testing::WriteText(dir / "vicon.yaml", "- 1\n- 2\n");
  message = testing::MessageOf([&] { ReadViconCalibration(dir / "vicon.yaml"); });
  EXPECT_NE(message.find("vicon.yaml: expected a YAML map"), std::string::npos) << message;
}

TEST(OmdCalibration, RefusesAChainLinkThatIsNotRigid) {
  testing::TempDir dir;
  std::string bad = kKalibr;
  bad.replace(bad.find("[1, 0, 0, 0.05]"), 15, "[2, 0, 0, 0.05]");
  testing::WriteText(dir / "kalibr.yaml", bad);
  const std::string message = testing::MessageOf([&] { ReadKalibrCameras(dir / "kalibr.yaml"); });
  EXPECT_NE(message.find("cam2.T_cn_cnm1 is not a rigid transform"), std::string::npos) << message;
}

TEST(OmdVicon, ReadsBodiesAndNamesTheLineOfABadRow) {
  testing::TempDir dir;
  const std::string header = "time_sec,time_nsec,object,rot_x,rot_y,rot_z,rot_w,x,y,z\n";
  testing::WriteText(dir / "vicon.csv", header +
                                            "10,500000000,sensor_payload,0,0,0,1,1,2,3\n"
                                            "10,500000000,box1,0,0,0.7071067811865476,"
                                            "0.7071067811865476,0,0,1\n"
                                            "10,505000000,sensor_payload,0,0,0,1,1.5,2,3\n");
  const auto bodies = ReadViconBodies(dir / "vicon.csv");
  ASSERT_EQ(bodies.size(), 2u);
  ASSERT_EQ(bodies.at("sensor_payload").size(), 2u);
  EXPECT_NEAR(bodies.at("sensor_payload")[1].timestamp, 10.505, 1e-9);
  EXPECT_TRUE(
      bodies.at("sensor_payload")[1].T_world_camera.translation().isApprox(Vector3d(1.5, 2, 3)));
  EXPECT_TRUE((bodies.at("box1")[0].T_world_camera.linear() * Vector3d::UnitX())
                  .isApprox(Vector3d::UnitY(), 1e-9));

  auto error_of = [&](const std::string& row) {
    testing::WriteText(dir / "bad.csv",
                       header + "10,0,sensor_payload,0,0,0,1,1,2,3\n" + row + "\n");
    return testing::MessageOf([&] { ReadViconBodies(dir / "bad.csv"); });
  };
  EXPECT_NE(error_of("11,0,sensor_payload,0,0,0.5,1,1,2,3").find("bad.csv:3: quaternion norm"),
            std::string::npos);
  EXPECT_NE(error_of("9,0,sensor_payload,0,0,0,1,1,2,3")
                .find("bad.csv:3: rows of "
                      "'sensor_payload' out of time order"),
            std::string::npos);
  EXPECT_NE(error_of("11,0,sensor_payload,0,0,0,1").find("bad.csv:3: expected"), std::string::npos);
  EXPECT_NE(error_of("11,0,sensor_payload,0,0,0,1,x,2,3").find("bad.csv:3: field 8"),
            std::string::npos);
}

// A tiny TUM-layout sequence with ground truth and objects: what sdoslam synth writes.
void WriteTumSequence(const std::filesystem::path& dir, int frames) {
  std::filesystem::create_directories(dir / "rgb");
  std::filesystem::create_directories(dir / "depth");
  std::string rgb = "# rgb\n", depth = "# depth\n", gt = "# gt\n", objects = "# objects\n";
  for (int k = 0; k < frames; ++k) {
    const double t = 100.0 + k / 30.0;
    char name[64];
    std::snprintf(name, sizeof(name), "%.6f.png", t);
    cv::imwrite((dir / "rgb" / name).string(), cv::Mat(24, 32, CV_8UC3, cv::Scalar(k, 9, 3)));
    cv::imwrite((dir / "depth" / name).string(), cv::Mat(24, 32, CV_16UC1, cv::Scalar(6000 + k)));
    rgb += fmt::format("{:.6f} rgb/{}\n", t, name);
    depth += fmt::format("{:.6f} depth/{}\n", t, name);
    const Eigen::Quaterniond q(AngleAxisd(0.03 * k, Vector3d(0.2, 1, 0.1).normalized()));
    gt += fmt::format("{:.6f} {} {} {} {} {} {} {}\n", t, 0.01 * k, 0.0005 * k * k, -0.005 * k,
                      q.x(), q.y(), q.z(), q.w());
    objects += fmt::format("{:.6f} 4 {} 1 2 0 0 0 1\n", t, 0.3 * k);
  }
  testing::WriteText(dir / "rgb.txt", rgb);
  testing::WriteText(dir / "depth.txt", depth);
  testing::WriteText(dir / "groundtruth.txt", gt);
  testing::WriteText(dir / "object_poses.txt", objects);
  testing::WriteText(dir / "camera.yaml",
                     "camera:\n  width: 32\n  height: 24\n  fx: 30\n  fy: 31\n  cx: 16\n  cy: "
                     "12\n  k1: 0.01\n  depth_factor: 5000\n");
}

OmdWriteOptions Extrinsics() {
  OmdWriteOptions o;
  o.T_apparatus_left =
      Make({0.02, -0.05, 0.1}, AngleAxisd(M_PI / 2, Vector3d::UnitX()).toRotationMatrix());
  o.T_cam1_cam0 = Make({-0.11, 0, 0});
  o.T_cam2_cam1 =
      Make({0.06, 0.015, -0.01}, AngleAxisd(0.03, Vector3d::UnitY()).toRotationMatrix());
  return o;
}

TEST(OmdSequence, WrittenFromTumAndReadBackGivesTheCameraTrajectoryAndImages) {
  testing::TempDir dir;
  WriteTumSequence(dir / "tum", 6);
  WriteOmdFromTum(dir / "tum", dir / "omd", Extrinsics());
  const OmdSequence omd = ReadOmdSequence(dir / "omd");
  ASSERT_EQ(omd.entries.size(), 6u);
  EXPECT_EQ(omd.entries[2].rgb_path.filename(), "000003_color.png");
  EXPECT_EQ(omd.camera.fy, 31);
  EXPECT_EQ(omd.camera.k1, 0.01);
  EXPECT_EQ(omd.camera.depth_factor, 1000);
  // Depth re-quantised to millimetres: 6000 + k units of 1/5000 m.
  const cv::Mat depth = cv::imread(omd.entries[4].depth_path.string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(depth.at<uint16_t>(3, 3), 1201);
  // The ground truth comes back at every frame, through Vicon at 200 Hz and the camera chain.
  // Between Vicon samples it is the apparatus that is interpolated, not the camera: at 1 rad/s
  // and a 12 cm lever that differs by some 30 micrometres.
  const Trajectory tum = ReadTumTrajectory(dir / "tum" / "groundtruth.txt");
  ASSERT_EQ(omd.ground_truth.size(), tum.size());
  for (size_t k = 0; k < tum.size(); ++k) {
    EXPECT_NEAR(omd.ground_truth[k].timestamp, tum[k].timestamp, 1e-9);
    EXPECT_LT(
        (omd.ground_truth[k].T_world_camera.translation() - tum[k].T_world_camera.translation())
            .norm(),
        1e-4)
        << k;
    EXPECT_TRUE(
        omd.ground_truth[k].T_world_camera.linear().isApprox(tum[k].T_world_camera.linear(), 1e-5));
  }
  ASSERT_EQ(omd.bodies.count("object_4"), 1u);
  EXPECT_GT(omd.bodies.at("object_4").size(), 6u * 5);  // sampled between the frames
  // Without the extrinsics, the apparatus is not the camera: the chain matters.
  const auto bodies = ReadViconBodies(dir / "omd" / "vicon.csv");
  EXPECT_GT((bodies.at("sensor_payload")[0].T_world_camera.translation() -
             tum[0].T_world_camera.translation())
                .norm(),
            0.05);
}

TEST(OmdSequence, ConvertedToTumKeepsTheFramesTheCameraAndTheGroundTruth) {
  testing::TempDir dir;
  WriteTumSequence(dir / "tum", 4);
  WriteOmdFromTum(dir / "tum", dir / "omd", Extrinsics());
  CameraOptions camera;
  camera.from_dataset = true;
  camera.depth_factor = 1000;
  const RgbdDataset omd(dir / "omd", camera);
  WriteTumCopy(omd, dir / "back");
  const RgbdDataset back(dir / "back", LoadCameraConfig(dir / "back" / "camera.yaml"));
  ASSERT_EQ(back.size(), 4u);
  EXPECT_EQ(back.camera().fy, 31);
  EXPECT_EQ(back.camera().depth_factor, 1000);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_NEAR(back.entries()[k].timestamp, omd.entries()[k].timestamp, 1e-6);
    const RgbdFrame a = omd.Load(k), b = back.Load(k);
    EXPECT_EQ(cv::norm(a.bgr, b.bgr, cv::NORM_INF), 0);
    EXPECT_EQ(cv::norm(a.depth, b.depth, cv::NORM_INF), 0);
  }
  ASSERT_TRUE(back.ground_truth().has_value());
  const Trajectory original = ReadTumTrajectory(dir / "tum" / "groundtruth.txt");
  ASSERT_EQ(back.ground_truth()->size(), original.size());
  for (size_t k = 0; k < original.size(); ++k) {
    EXPECT_LT((back.ground_truth()->at(k).T_world_camera.translation() -
               original[k].T_world_camera.translation())
                  .norm(),
              1e-4);
  }
  EXPECT_TRUE(std::filesystem::exists(dir / "back" / "bodies" / "object_4.txt"));
}

TEST(OmdSequence, BadFoldersAreClearErrors) {
  testing::TempDir dir;
  WriteTumSequence(dir / "tum", 3);
  WriteOmdFromTum(dir / "tum", dir / "omd", Extrinsics());
  std::filesystem::remove(dir / "omd" / "rgbd" / "000002_aligned_depth.png");
  std::string message = testing::MessageOf([&] { ReadOmdSequence(dir / "omd"); });
  EXPECT_NE(message.find("rgbd.csv:3: frame 000002 lists 000002_aligned_depth.png, which does "
                         "not exist"),
            std::string::npos)
      << message;

  WriteOmdFromTum(dir / "tum", dir / "omd2", Extrinsics());
  OmdOptions options;
  options.apparatus_body = "payload";
  message = testing::MessageOf([&] { ReadOmdSequence(dir / "omd2", options); });
  EXPECT_NE(message.find("no body 'payload' (bodies: object_4, sensor_payload)"), std::string::npos)
      << message;
  options = {};
  options.rgb_camera = "cam7";
  message = testing::MessageOf([&] { ReadOmdSequence(dir / "omd2", options); });
  EXPECT_NE(message.find("no camera named 'cam7' (cameras: cam0 (/stereo/left/image_raw)"),
            std::string::npos)
      << message;
  // An existing segment is kept unless replacing is asked for, and then replaced whole; a file
  // the user put into it makes it theirs, and it is not replaced.
  message = testing::MessageOf([&] { WriteOmdFromTum(dir / "tum", dir / "omd2", Extrinsics()); });
  EXPECT_NE(message.find("omd2 exists and is not empty (pass --overwrite"), std::string::npos)
      << message;
  testing::WriteText(dir / "omd2" / "notes.txt", "the user's");
  message = testing::MessageOf(
      [&] { WriteOmdFromTum(dir / "tum", dir / "omd2", Extrinsics(), /*overwrite=*/true); });
  EXPECT_NE(message.find("notes.txt, which sdoslam did not write"), std::string::npos) << message;
  EXPECT_EQ(testing::ReadText(dir / "omd2" / "notes.txt"), "the user's");
  std::filesystem::remove(dir / "omd2" / "notes.txt");
  std::filesystem::remove(dir / "omd2" / "vicon.csv");  // a segment missing a file of its own
  WriteOmdFromTum(dir / "tum", dir / "omd2", Extrinsics(), /*overwrite=*/true);
  EXPECT_TRUE(std::filesystem::exists(dir / "omd2" / "vicon.csv"));
  EXPECT_EQ(ReadOmdSequence(dir / "omd2").entries.size(), 3u);
  std::filesystem::remove(dir / "omd2" / "vicon.yaml");
  message = testing::MessageOf([&] { ReadOmdSequence(dir / "omd2"); });
  EXPECT_NE(message.find("needs vicon.yaml"), std::string::npos) << message;
}

}  // namespace
}  // namespace sdoslam
