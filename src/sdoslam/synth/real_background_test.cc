#include "sdoslam/synth/real_background.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/error.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/io/tum_dataset.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam::synth {
namespace {

std::filesystem::path Desk() { return testing::SharedDir() / "data" / "tum_fr2_desk_50"; }

BackgroundSynthOptions DeskOptions(const std::string& scenario, int frames) {
  BackgroundSynthOptions o;
  o.background = Desk();
  o.camera = LoadCameraConfig(testing::SourceDir() / "configs" / "tum_fr2.yaml");
  o.scenario = scenario;
  o.max_frames = frames;
  o.forward_backward = true;
  return o;
}

// The rows of a written object_poses.txt (after its header): each object's id and world pose.
struct ObjectPose {
  int id;
  Eigen::Isometry3d T_world_object;
};
std::vector<ObjectPose> ReadObjectPoses(const std::filesystem::path& file) {
  std::istringstream lines(testing::ReadText(file));
  std::string line;
  std::getline(lines, line);  // header
  std::vector<ObjectPose> poses;
  double stamp, id, x, y, z, qx, qy, qz, qw;
  while (lines >> stamp >> id >> x >> y >> z >> qx >> qy >> qz >> qw) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, z);
    poses.push_back({static_cast<int>(id), T});
  }
  return poses;
}

// Frame k's mask from a written sequence's `folder` (instance/ or dynamic/), as written.
cv::Mat ReadMask(const std::filesystem::path& out, const TumDataset& written,
                 const std::string& folder, size_t k) {
  return cv::imread((out / folder / written.entries()[k].rgb_path.filename()).string(),
                    cv::IMREAD_UNCHANGED);
}

class RealBackgroundTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(Desk())) GTEST_SKIP() << Desk() << " is absent";
  }
  testing::TempDir dir_;
};

// The carried box over six real frames played forward and back: recorded pixels stay as
// recorded, the box is drawn only where it is nearer than the recorded depth, its depth puts it
// where its ground-truth pose says, and the trajectory is the recording's, interpolated.
TEST_F(RealBackgroundTest, ObjectsAreZBufferedIntoTheRecordingAlongItsRealTrajectory) {
  const BackgroundSynthOptions options = DeskOptions("carried_box", 6);
  const auto out = dir_ / "seq";
  const SequenceSummary summary = WriteBackgroundSequence(options, out);
  ASSERT_EQ(summary.frames, 11);                  // 6 forward, 5 back
  EXPECT_GT(summary.dynamic_fraction_mean, 0.2);  // a quarter of the image, as promised
  EXPECT_LT(summary.dynamic_fraction_max, 0.35);

  const TumDataset recording(Desk(), options.camera);
  const TumDataset written(out, LoadCameraConfig(out / "camera.yaml"));
  ASSERT_EQ(written.size(), 11u);
  const Trajectory truth = ReadTumTrajectory(Desk() / "groundtruth.txt");
  const Trajectory gt = ReadTumTrajectory(out / "groundtruth.txt");
  ASSERT_EQ(gt.size(), 11u);
  const int played[11] = {0, 1, 2, 3, 4, 5, 4, 3, 2, 1, 0};
  for (int k = 0; k < 11; ++k) {
    if (k > 0) {
      EXPECT_GT(gt[k].timestamp, gt[k - 1].timestamp);
    }
    const auto expected = InterpolatePose(truth, recording.entries()[played[k]].timestamp, 0.05);
    ASSERT_TRUE(expected.has_value());
    EXPECT_LT((gt[k].T_world_camera.translation() - expected->translation()).norm(), 1e-5) << k;

    const RgbdFrame real = recording.Load(played[k]);
    const RgbdFrame made = written.Load(k);
    const cv::Mat instance = ReadMask(out, written, "instance", k);
    const cv::Mat dynamic = ReadMask(out, written, "dynamic", k);
    ASSERT_EQ(instance.type(), CV_16UC1);
    int object_pixels = 0, nearer = 0, mask_agrees = 0, untouched = 0, background = 0;
    for (int v = 0; v < instance.rows; ++v) {
      for (int u = 0; u < instance.cols; ++u) {
        const bool object = instance.at<uint16_t>(v, u) == 21;
        mask_agrees += object == (dynamic.at<uint8_t>(v, u) == 255);
        const float z_real = real.depth.at<float>(v, u), z_made = made.depth.at<float>(v, u);
        if (object) {
          ++object_pixels;
          // Noise is σ ≈ 2 mm at 0.6 m: nearer than the recording wherever it saw something.
          nearer += z_real <= 0 || (z_made > 0 && z_made < z_real);
        } else {
          ++background;
          untouched += real.bgr.at<cv::Vec3b>(v, u) == made.bgr.at<cv::Vec3b>(v, u);
        }
      }
    }
    EXPECT_EQ(mask_agrees, instance.rows * instance.cols) << k;
    EXPECT_GT(object_pixels, 0.2 * instance.total()) << k;
    EXPECT_GE(nearer, 0.99 * object_pixels) << k;
    EXPECT_EQ(untouched, background) << k;
  }

  // The box's depth at the image point of its centre matches its pose: 0.6 m ahead of the camera,
  // give or take the sway.
  const std::vector<ObjectPose> poses = ReadObjectPoses(out / "object_poses.txt");
  ASSERT_FALSE(poses.empty());
  const Eigen::Vector3d centre_camera =
      gt[0].T_world_camera.inverse() * poses[0].T_world_object.translation();
  EXPECT_NEAR(centre_camera.z(), 0.6, 0.05);
  const Camera camera(options.camera);
  Eigen::Vector2d uv = camera.Distort(camera.Project(centre_camera));
  const RgbdFrame first = written.Load(0);
  const float z_centre = first.depth.at<float>(static_cast<int>(uv.y()), static_cast<int>(uv.x()));
  // The front face is 6 cm before the centre.
  EXPECT_NEAR(z_centre, centre_camera.z() - 0.06, 0.02);
}

// biased_box: a box standing still, whose depth the sensor reads 4 % too far. Along the ray
// through its centre the depth is 1.04 times the distance to the box's near face (computed here
// from its pose and size, not from the renderer), and the ground truth never calls it dynamic.
TEST_F(RealBackgroundTest, TheBiasedBoxStandsStillAndReadsFourPercentTooFar) {
  const BackgroundSynthOptions options = DeskOptions("biased_box", 3);
  const auto out = dir_ / "biased";
  const SequenceSummary summary = WriteBackgroundSequence(options, out);
  EXPECT_EQ(summary.dynamic_fraction_max, 0.0);
  const TumDataset written(out, LoadCameraConfig(out / "camera.yaml"));
  const Trajectory gt = ReadTumTrajectory(out / "groundtruth.txt");
  const std::vector<ObjectPose> poses = ReadObjectPoses(out / "object_poses.txt");
  ASSERT_FALSE(poses.empty());
  EXPECT_EQ(poses[0].id, 31);
  const Eigen::Isometry3d T_world_box = poses[0].T_world_object;
  const Eigen::Isometry3d T_box_camera = T_world_box.inverse() * gt[0].T_world_camera;
  const Camera camera(options.camera);
  const Eigen::Vector3d centre_camera = T_box_camera.inverse().translation();
  const Eigen::Vector2d uv = camera.Distort(camera.Project(centre_camera));
  // The ray through that pixel (depth 1 along it), into the box's frame; the slab method gives
  // where it enters the box, which is the near face's depth.
  const Eigen::Vector2d undistorted = camera.Project(centre_camera);
  const Eigen::Vector3d origin = T_box_camera.translation();
  const Eigen::Vector3d direction = T_box_camera.linear() * camera.Unproject(undistorted, 1.0);
  const Eigen::Vector3d half(0.14, 0.1, 0.09);
  double enters = 0;
  for (int a = 0; a < 3; ++a) {
    const double t0 = (-half[a] - origin[a]) / direction[a],
                 t1 = (half[a] - origin[a]) / direction[a];
    enters = std::max(enters, std::min(t0, t1));
  }
  ASSERT_GT(enters, 0.3);
  const float sensed =
      written.Load(0).depth.at<float>(static_cast<int>(uv.y()), static_cast<int>(uv.x()));
  // Noise is a few mm at 1 m; the bias is 4 cm.
  EXPECT_NEAR(sensed, 1.04 * enters, 0.012) << enters;
  const cv::Mat instance = ReadMask(out, written, "instance", 0);
  EXPECT_EQ(instance.at<uint16_t>(static_cast<int>(uv.y()), static_cast<int>(uv.x())), 31);
}

// pushed_box: still for the first 0.35 of the play, pushed 0.3 m aside over 0.8 s, still again.
// The ground truth calls it dynamic only in the frames it moves into or out of (a thing of no
// known class).
TEST_F(RealBackgroundTest, TheCrateStandsIsPushedAsideAndStandsAgain) {
  const auto out = dir_ / "pushed";
  BackgroundSynthOptions options = DeskOptions("pushed_box", 0);
  options.forward_backward = false;
  WriteBackgroundSequence(options, out);
  const TumDataset written(out, LoadCameraConfig(out / "camera.yaml"));
  std::vector<Eigen::Vector3d> centre;
  for (const ObjectPose& pose : ReadObjectPoses(out / "object_poses.txt")) {
    EXPECT_EQ(pose.id, 32);
    centre.push_back(pose.T_world_object.translation());
  }
  ASSERT_EQ(centre.size(), 50u);
  // 50 frames, 1.7 s: still up to about frame 20, pushed until about frame 44, then still.
  EXPECT_LT((centre[15] - centre[0]).norm(), 1e-9);
  EXPECT_NEAR((centre.back() - centre[0]).norm(), 0.3, 1e-6);
  EXPECT_LT((centre.back() - centre[46]).norm(), 1e-9);
  size_t moving_frames = 0;
  for (size_t k = 0; k < centre.size(); ++k) {
    const cv::Mat dynamic = ReadMask(out, written, "dynamic", k);
    const cv::Mat instance = ReadMask(out, written, "instance", k);
    ASSERT_FALSE(dynamic.empty() || instance.empty());
    ASSERT_GT(cv::countNonZero(instance == 32), 5000) << "frame " << k << ": the crate in view";
    // Dynamic in a frame it moves into or out of.
    const bool moves = (k > 0 && (centre[k] - centre[k - 1]).norm() > 1e-9) ||
                       (k + 1 < centre.size() && (centre[k + 1] - centre[k]).norm() > 1e-9);
    moving_frames += moves;
    EXPECT_EQ(cv::countNonZero(dynamic), moves ? cv::countNonZero(instance == 32) : 0)
        << "frame " << k;
  }
  EXPECT_GE(moving_frames, 20u);
}

TEST_F(RealBackgroundTest, PeopleAreDetectedAsPersonsAndUnknownScenariosAreErrors) {
  const auto out = dir_ / "people";
  BackgroundSynthOptions options = DeskOptions("people", 30);
  options.forward_backward = false;
  WriteBackgroundSequence(options, out);
  const std::string detections = testing::ReadText(out / "detections.json");
  EXPECT_NE(detections.find("\"person\""), std::string::npos);

  options.scenario = "walking_xyz";
  EXPECT_NE(testing::MessageOf([&] {
              WriteBackgroundSequence(options, dir_ / "x");
            }).find("unknown real-background scenario 'walking_xyz' (known: static, carried_box"),
            std::string::npos);
  options.scenario = "mixed";
  options.background = dir_ / "nowhere";
  EXPECT_NE(
      testing::MessageOf([&] { WriteBackgroundSequence(options, dir_ / "y"); }).find("nowhere"),
      std::string::npos);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "y"));
}

// person_stops_close over the desk clip played forward only (50 frames, 1.7 s): the person
// walks up, stands still about 0.75 m ahead of the camera for 0.3 of the play (a second in the
// 3.3 s plays), its head above the view and about half the image covered, then walks on.
TEST_F(RealBackgroundTest, APersonWalksUpStandsStillCloseByThenWalksOn) {
  const auto out = dir_ / "stops";
  BackgroundSynthOptions options = DeskOptions("person_stops_close", 0);
  options.forward_backward = false;
  const SequenceSummary summary = WriteBackgroundSequence(options, out);
  ASSERT_EQ(summary.frames, 50);
  const Trajectory gt = ReadTumTrajectory(out / "groundtruth.txt");
  std::vector<Eigen::Vector3d> feet;
  for (const ObjectPose& pose : ReadObjectPoses(out / "object_poses.txt"))
    feet.push_back(pose.T_world_object.translation());
  ASSERT_EQ(feet.size(), 50u);
  // The stand: the longest run of frames at one pose.
  size_t first = 0, length = 1;
  for (size_t k = 1, start = 0; k < feet.size(); ++k) {
    if ((feet[k] - feet[k - 1]).norm() > 1e-9) start = k;
    if (k - start + 1 > length) first = start, length = k - start + 1;
  }
  EXPECT_GE(length, 13u);  // 0.3 × 1.7 s at 30 Hz, give or take the recording's frame times
  EXPECT_LE(length, 17u);
  EXPECT_GT((feet[first] - feet[0]).norm(), 1.2);      // walked up from 2.2 m ...
  EXPECT_GT((feet.back() - feet[first]).norm(), 0.5);  // ... and walks on after the stand
  // Feet 0.75 m ahead and 1.2 m below the camera: √(0.75² + 1.2²) = 1.42 m from it.
  EXPECT_NEAR((feet[first] - gt[first].T_world_camera.translation()).norm(), 1.42, 0.08);

  const TumDataset written(out, LoadCameraConfig(out / "camera.yaml"));
  const size_t middle = first + length / 2;
  const cv::Mat instance = ReadMask(out, written, "instance", middle);
  ASSERT_FALSE(instance.empty());
  const cv::Mat person = instance == 4;
  EXPECT_GT(cv::countNonZero(person), 0.4 * instance.total());
  EXPECT_LT(cv::countNonZero(person), 0.8 * instance.total());
  EXPECT_GT(cv::countNonZero(person.row(0)), 50);  // cut off by the top edge
  // A person is dynamic whether it moves or not: the ground truth marks it while it stands.
  const cv::Mat dynamic = ReadMask(out, written, "dynamic", middle);
  ASSERT_FALSE(dynamic.empty());
  EXPECT_EQ(cv::countNonZero(person & (dynamic == 255)), cv::countNonZero(person));
  EXPECT_EQ(cv::countNonZero(dynamic), cv::countNonZero(person));
}

// person_sits over the desk clip's first 30 frames played forward only (1 s): the person walks in
// behind the desk, sits down on the stool (its feet stay put while its head goes down), sits
// still, stands up and walks off. The ground truth marks the person dynamic in every frame it is
// in view, seated and still too, and the stool (hidden behind the desk) never.
TEST_F(RealBackgroundTest, APersonSitsDownSitsStillAndGetsUp) {
  const auto out = dir_ / "sits";
  BackgroundSynthOptions options = DeskOptions("person_sits", 30);
  options.forward_backward = false;
  WriteBackgroundSequence(options, out);
  const TumDataset written(out, LoadCameraConfig(out / "camera.yaml"));
  std::vector<Eigen::Isometry3d> body;
  for (const ObjectPose& pose : ReadObjectPoses(out / "object_poses.txt")) {
    ASSERT_TRUE(pose.id == 5 || pose.id == 33) << pose.id;
    if (pose.id == 5) body.push_back(pose.T_world_object);
  }
  ASSERT_EQ(body.size(), 30u);
  auto same = [](const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return a.isApprox(b, 1e-12);
  };
  // The feet stay put from the arrival to standing up (0.22 to 0.8 of the play: 17 frames,
  // give or take the recording's frame times); the body is wholly still while seated (0.4 to
  // 0.65: about 7 frames).
  size_t first = 0, length = 1;
  for (size_t k = 1, start = 0; k < body.size(); ++k) {
    if ((body[k].translation() - body[k - 1].translation()).norm() > 1e-9) start = k;
    if (k - start + 1 > length) first = start, length = k - start + 1;
  }
  EXPECT_GE(length, 16u);
  EXPECT_LE(length, 19u);
  size_t still = 0;
  for (size_t k = first + 1; k < first + length; ++k) still += same(body[k], body[k - 1]);
  EXPECT_GE(still, 6u);
  EXPECT_LE(still, 9u);
  EXPECT_GT((body.front().translation() - body[first].translation()).norm(), 0.8);
  EXPECT_GT((body.back().translation() - body[first].translation()).norm(), 0.8);

  // The person's top row in the image: standing (on arrival), the head is above the view;
  // seated (the middle of the stay), 0.45 m lower, the whole head is in it.
  auto top_row = [&](size_t k) {
    const cv::Mat person = ReadMask(out, written, "instance", k) == 5;
    return cv::boundingRect(person).y;
  };
  EXPECT_EQ(top_row(first), 0);
  EXPECT_GT(top_row(first + length / 2), 30);
  for (size_t k = 0; k < body.size(); ++k) {
    const cv::Mat instance = ReadMask(out, written, "instance", k);
    const cv::Mat dynamic = ReadMask(out, written, "dynamic", k);
    ASSERT_FALSE(instance.empty() || dynamic.empty());
    const cv::Mat person = instance == 5;
    EXPECT_EQ(cv::countNonZero(dynamic), cv::countNonZero(person)) << "frame " << k;
    EXPECT_EQ(cv::countNonZero(person & (dynamic == 255)), cv::countNonZero(person));
  }
}

}  // namespace
}  // namespace sdoslam::synth
