#include "sdoslam/objects/object_tracker.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <random>
#include <sstream>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

CameraOptions TestCamera() {
  CameraOptions c;
  c.width = 640;
  c.height = 480;
  c.fx = c.fy = 525;
  c.cx = 319.5;
  c.cy = 239.5;
  return c;
}

// Smooth random texture (Lucas–Kanade needs gradients, corners need structure).
cv::Mat Texture(cv::Size size, unsigned seed) {
  cv::Mat noise(size, CV_8U);
  cv::RNG(seed).fill(noise, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.5);
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  return noise;
}

// A scene of a textured wall 3 m away and, in front of it, a fronto-parallel textured square
// 1.5 m away whose top-left corner is at (x, y) m in the camera's frame: moving parallel to the
// image, its image moves by f · shift / z, exactly.
struct Frame {
  cv::Mat gray, depth, labels;
};
Frame Render(const cv::Mat& wall, const cv::Mat& patch, double x, double y) {
  const CameraOptions c = TestCamera();
  Frame f;
  f.gray = wall.clone();
  f.depth = cv::Mat(wall.size(), CV_32F, cv::Scalar(3.0f));
  f.labels = cv::Mat(wall.size(), CV_8U, cv::Scalar(0));
  constexpr double z = 1.5;
  const double u = c.fx * x / z + c.cx, v = c.fy * y / z + c.cy;
  // The patch shifted by a sub-pixel amount into place.
  const cv::Matx23d shift(1, 0, u, 0, 1, v);
  cv::Mat placed, mask;
  cv::warpAffine(patch, placed, shift, wall.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  cv::warpAffine(cv::Mat(patch.size(), CV_8U, cv::Scalar(255)), mask, shift, wall.size(),
                 cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  placed.copyTo(f.gray, mask);
  f.depth.setTo(z, mask);
  f.labels.setTo(2, mask);
  return f;
}

TEST(ObjectTracker, FollowsAMovingSquareUnderOneIdAndMeasuresItsMotion) {
  const cv::Mat wall = Texture({640, 480}, 1), patch = Texture({150, 150}, 2);
  ObjectTracker tracker(TestCamera());
  const Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  // 2 cm right and 0.6 cm down a frame: 7 px and 2.1 px.
  const Eigen::Vector3d step(0.02, 0.006, 0);
  std::vector<ObjectObservation> all;
  Eigen::Vector3d first_centroid;
  for (size_t k = 0; k < 4; ++k) {
    const Frame f = Render(wall, patch, -0.2 + k * step.x(), -0.1 + k * step.y());
    const auto seen = tracker.Update(k, 0.1 * k, f.gray, f.depth, f.labels, {}, camera, true);
    ASSERT_EQ(seen.size(), 1u) << "frame " << k;
    EXPECT_EQ(seen[0].id, 1);
    EXPECT_EQ(seen[0].class_name, "unknown");
    EXPECT_NEAR(seen[0].pixels, 150 * 150, 1000);  // less a ring of its outline
    EXPECT_NEAR(seen[0].centroid_camera.z(), 1.5, 1e-6);
    if (k == 0) {
      EXPECT_FALSE(seen[0].motion_camera.has_value());
      first_centroid = seen[0].centroid_camera;
      continue;
    }
    ASSERT_TRUE(seen[0].motion_camera.has_value()) << "frame " << k;
    const Eigen::Isometry3d& G = *seen[0].motion_camera;
    // It moves the square's centre by the step, and turns it by next to nothing.
    const Eigen::Vector3d centre = all.empty() ? first_centroid : all.back().centroid_camera;
    EXPECT_LT((G * centre - centre - step).norm(), 0.001) << (G * centre - centre).transpose();
    EXPECT_LT(Eigen::AngleAxisd(G.linear()).angle(), 0.2 * M_PI / 180);
    EXPECT_GE(seen[0].motion_inliers, 10);
    EXPECT_EQ(seen[0].previous_frame, k - 1);
    all.push_back(seen[0]);
  }
  // In the world of a camera that stood 1 m up the x axis, turned 90° about it, the whole time:
  // H = T·G·T⁻¹ moves the square's world centre by the step turned into the world.
  Trajectory trajectory;
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
  T_world_camera.linear() =
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T_world_camera.translation() = Eigen::Vector3d(1, 0, 0);
  for (size_t k = 0; k < 4; ++k) trajectory.push_back({0.1 * k, T_world_camera});
  const std::string csv = ObjectsCsv(all, trajectory);
  std::istringstream rows(csv);
  std::string header, row;
  std::getline(rows, header);
  EXPECT_EQ(header, "timestamp,id,class,tx,ty,tz,qx,qy,qz,qw,cx,cy,cz,pixels");
  std::vector<Eigen::Vector3d> world_centres;
  std::vector<Eigen::Isometry3d> motions;
  while (std::getline(rows, row)) {
    double t, tx, ty, tz, qx, qy, qz, qw, cx, cy, cz;
    int id, pixels;
    char cls[16];
    ASSERT_EQ(std::sscanf(row.c_str(), "%lf,%d,%15[^,],%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%d",
                          &t, &id, cls, &tx, &ty, &tz, &qx, &qy, &qz, &qw, &cx, &cy, &cz, &pixels),
              14)
        << row;
    EXPECT_EQ(id, 1);
    Eigen::Isometry3d H = Eigen::Isometry3d::Identity();
    H.linear() = Eigen::Quaterniond(qw, qx, qy, qz).toRotationMatrix();
    H.translation() = Eigen::Vector3d(tx, ty, tz);
    motions.push_back(H);
    world_centres.emplace_back(cx, cy, cz);
  }
  ASSERT_EQ(motions.size(), 3u);
  const Eigen::Vector3d world_step = T_world_camera.linear() * step;
  for (size_t k = 1; k < 3; ++k) {
    EXPECT_LT((motions[k] * world_centres[k - 1] - world_centres[k - 1] - world_step).norm(),
              0.001);
    // The centroid is the mean over a region whose outline is cut at work_scale (4 px, 1 cm
    // here): it follows the step to a few millimetres.
    EXPECT_LT((world_centres[k] - world_centres[k - 1] - world_step).norm(), 0.005);
  }
  const auto tracks = ObjectCentroidTracks(all, trajectory);
  ASSERT_EQ(tracks.size(), 1u);
  EXPECT_EQ(tracks.at(1).size(), 3u);
}

TEST(ObjectTracker, KeepsTheIdThroughAShortOcclusionAndGivesAFarRegionANewOne) {
  const cv::Mat wall = Texture({640, 480}, 3), patch = Texture({150, 150}, 4);
  ObjectTrackerOptions options;
  options.max_missed_frames = 3;
  ObjectTracker tracker(TestCamera(), options);
  const Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  const Frame here = Render(wall, patch, -0.2, -0.1);
  const cv::Mat none(wall.size(), CV_8U, cv::Scalar(0));
  EXPECT_EQ(tracker.Update(0, 0.0, here.gray, here.depth, here.labels, {}, camera, true)[0].id, 1);
  // Two frames without it (hidden), then back: the same id, and no motion across the gap.
  EXPECT_TRUE(tracker.Update(1, 0.1, here.gray, here.depth, none, {}, camera, true).empty());
  EXPECT_TRUE(tracker.Update(2, 0.2, here.gray, here.depth, none, {}, camera, true).empty());
  auto back = tracker.Update(3, 0.3, here.gray, here.depth, here.labels, {}, camera, true);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].id, 1);
  EXPECT_FALSE(back[0].motion_camera.has_value());
  // 0.5 m away is another object; and after a gap longer than max_missed_frames, so is this one.
  const Frame there = Render(wall, patch, 0.3, -0.1);
  EXPECT_EQ(tracker.Update(4, 0.4, there.gray, there.depth, there.labels, {}, camera, true)[0].id,
            2);
  for (size_t k = 5; k <= 8; ++k)
    tracker.Update(k, 0.1 * k, here.gray, here.depth, none, {}, camera, true);
  EXPECT_EQ(tracker.Update(9, 0.9, here.gray, here.depth, here.labels, {}, camera, true)[0].id, 3);
}

TEST(ObjectTracker, AMoverLostForAWhileComesBackUnderItsIdWhereItWasLost) {
  // A square moves 6 cm a frame for four frames, then the labels lose it for ten frames while
  // it stands (a pendulum at the end of its swing), and it is labelled again where it stopped.
  // Carried on at its velocity for all eleven frames, its centroid would be predicted 0.5 m on,
  // beyond gate_m: only a prediction held to max_predicted_frames finds it again.
  const cv::Mat wall = Texture({640, 480}, 7), patch = Texture({120, 120}, 8);
  const cv::Mat none(wall.size(), CV_8U, cv::Scalar(0));
  const Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  for (const int predicted : {3, 1000}) {
    ObjectTrackerOptions options;
    options.max_missed_frames = 30;
    options.max_predicted_frames = predicted;
    ObjectTracker tracker(TestCamera(), options);
    Frame f;
    for (size_t k = 0; k < 4; ++k) {
      f = Render(wall, patch, -0.5 + 0.06 * static_cast<double>(k), -0.1);
      ASSERT_EQ(tracker.Update(k, 0.1 * k, f.gray, f.depth, f.labels, {}, camera, true)[0].id, 1);
    }
    for (size_t k = 4; k < 14; ++k)
      EXPECT_TRUE(tracker.Update(k, 0.1 * k, f.gray, f.depth, none, {}, camera, true).empty());
    const auto back = tracker.Update(14, 1.4, f.gray, f.depth, f.labels, {}, camera, true);
    ASSERT_EQ(back.size(), 1u);
    EXPECT_EQ(back[0].id, predicted == 3 ? 1 : 2) << "max_predicted_frames " << predicted;
  }
}

TEST(ObjectTracker, LeavesAStaticStripOfItsMaskOutOfItsMotion) {
  // The labels take in, beside the moving square, a strip of a static surface at its depth (a
  // table under a carried box): their corners move with the camera, here not at all, and a
  // rigid fit that counts them pulls the square's motion toward standing still.
  const cv::Mat wall = Texture({640, 480}, 9), patch = Texture({150, 150}, 10);
  const cv::Mat strip_texture = Texture({300, 70}, 11);
  const cv::Rect strip(150, 372, 300, 70);  // under the square, wider than its path
  const Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d step(0.02, 0, 0);
  for (const double static_px : {1.5, 0.0}) {
    ObjectTrackerOptions options;
    options.static_px = static_px;
    ObjectTracker tracker(TestCamera(), options);
    double worst = 0;
    for (size_t k = 0; k < 4; ++k) {
      // The square's bottom edge (v = 239.5 − 525·0.05/1.5 + 150) meets the strip's top.
      Frame f = Render(wall, patch, -0.2 + step.x() * static_cast<double>(k), -0.05);
      strip_texture.copyTo(f.gray(strip));
      f.depth(strip).setTo(1.5);
      f.labels(strip).setTo(2);
      const auto seen = tracker.Update(k, 0.1 * k, f.gray, f.depth, f.labels, {}, camera, true);
      ASSERT_EQ(seen.size(), 1u) << "frame " << k;
      if (k == 0) continue;
      ASSERT_TRUE(seen[0].motion_camera.has_value()) << "frame " << k;
      // The motion of a point of the square (its centre, 1.5 m away).
      const Eigen::Vector3d centre(-0.2 + step.x() * static_cast<double>(k - 1) + 0.75 * 1.5 / 5.25,
                                   -0.05 + 0.75 * 1.5 / 5.25, 1.5);
      const Eigen::Isometry3d& G = *seen[0].motion_camera;
      worst = std::max(worst, (G * centre - centre - step).norm());
    }
    if (static_px > 0) {
      EXPECT_LT(worst, 0.002) << "static_px " << static_px;
    } else {
      EXPECT_GT(worst, 0.004) << "without the static test the strip pulls the motion";
    }
  }
}

TEST(ObjectTracker, TakesTheClassOfTheBoxOverAKnownRegion) {
  const cv::Mat wall = Texture({640, 480}, 5), patch = Texture({150, 150}, 6);
  ObjectTracker tracker(TestCamera());
  const Eigen::Isometry3d camera = Eigen::Isometry3d::Identity();
  Frame f = Render(wall, patch, -0.2, -0.1);
  const cv::Rect bounds = cv::boundingRect(f.labels);
  const std::vector<ClassHint> hints = {{"car", cv::Rect2f(0, 0, 50, 50)},
                                        {"person", cv::Rect2f(bounds)}};
  // Labelled moving-unknown (2): no class, whatever the boxes say.
  EXPECT_EQ(tracker.Update(0, 0, f.gray, f.depth, f.labels, hints, camera, true)[0].class_name,
            "unknown");
  f.labels.setTo(1, f.labels == 2);  // known movable
  EXPECT_EQ(tracker.Update(1, 0.1, f.gray, f.depth, f.labels, hints, camera, true)[0].class_name,
            "person");
  // Lost frames place nothing.
  EXPECT_TRUE(tracker.Update(2, 0.2, f.gray, f.depth, f.labels, hints, camera, false).empty());
}

TEST(ObjectTrackerOptions, NamesTheBadSetting) {
  ObjectTrackerOptions o;
  o.min_motion_points = 2;
  try {
    o.Check();
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("objects.min_motion_points"), std::string::npos);
  }
}

}  // namespace
}  // namespace sdoslam
