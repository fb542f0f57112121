#include "sdoslam/core/camera.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "sdoslam/testing/test_util.h"

namespace sdoslam {
namespace {

CameraOptions Freiburg2() {
  CameraOptions o;
  o.fx = 520.908620;
  o.fy = 521.007327;
  o.cx = 325.141442;
  o.cy = 249.701764;
  o.k1 = 0.231222;
  o.k2 = -0.784899;
  o.p1 = -0.003257;
  o.p2 = -0.000105;
  o.k3 = 0.917205;
  return o;
}

TEST(Camera, ProjectUnprojectRoundTrip) {
  const Camera camera(Freiburg2());
  const Eigen::Vector3d point(0.3, -0.2, 2.5);
  const Eigen::Vector2d pixel = camera.Project(point);
  EXPECT_NEAR(pixel.x(), 520.908620 * 0.3 / 2.5 + 325.141442, 1e-12);
  EXPECT_TRUE(camera.Unproject(pixel, 2.5).isApprox(point, 1e-12));
}

TEST(Camera, UndistortInvertsDistortAcrossTheImage) {
  const Camera camera(Freiburg2());
  ASSERT_TRUE(camera.HasDistortion());
  std::vector<cv::Point2f> distorted;
  std::vector<Eigen::Vector2d> truth;
  for (double v = 20; v <= 460; v += 40) {
    for (double u = 20; u <= 620; u += 40) {
      truth.emplace_back(u, v);
      const Eigen::Vector2d d = camera.Distort({u, v});
      distorted.emplace_back(static_cast<float>(d.x()), static_cast<float>(d.y()));
    }
  }
  const auto undistorted = camera.UndistortPoints(distorted);
  ASSERT_EQ(undistorted.size(), truth.size());
  double worst = 0;
  for (size_t k = 0; k < truth.size(); ++k) {
    worst = std::max(worst,
                     std::hypot(undistorted[k].x - truth[k].x(), undistorted[k].y - truth[k].y()));
  }
  EXPECT_LT(worst, 2e-3);  // float storage limits this, not the iteration
  // The distortion is real: near the corner it moves pixels by several pixels.
  EXPECT_GT((camera.Distort({20, 20}) - Eigen::Vector2d(20, 20)).norm(), 3.0);
}

TEST(Camera, CheckRejectsImpossibleIntrinsics) {
  auto expect_error = [](CameraOptions o, const std::string& field) {
    try {
      o.Check();
      FAIL() << "no error for " << field;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("camera." + field), std::string::npos) << e.what();
    }
  };
  CameraOptions o = Freiburg2();
  EXPECT_NO_THROW(o.Check());
  o.fx = -1;
  expect_error(o, "fx");
  o = Freiburg2();
  o.cx = 700;
  expect_error(o, "cx");
  o = Freiburg2();
  o.width = 0;
  expect_error(o, "width");
  o = Freiburg2();
  o.depth_max = 0.05;
  expect_error(o, "depth_max");
  o = Freiburg2();
  o.k1 = std::nan("");
  expect_error(o, "k1");
  // Finite but no lens: 1e30 once passed and acted as no distortion.
  o = Freiburg2();
  o.k1 = 1e30;
  expect_error(o, "k1");
  o = Freiburg2();
  o.p2 = -1.5;
  expect_error(o, "p2");
  o = Freiburg2();
  o.k3 = 101;
  expect_error(o, "k3");
  o = Freiburg2();
  o.k3 = 99;  // large, but within the documented bound
  EXPECT_NO_THROW(o.Check());
  o.fy = 0;
  expect_error(o, "fy");
  o = Freiburg2();
  o.cy = -1;
  expect_error(o, "cy");
}

// Finite but no camera: fx: 1e308 ran, exited 0 and wrote a trajectory that meant nothing. Every
// number has a range, and the message names its key; the values at the edges of each range pass.
TEST(Camera, CheckRejectsFiniteButAbsurdValues) {
  auto error_of = [](CameraOptions o) { return testing::MessageOf([&] { o.Check(); }); };
  const std::vector<std::pair<std::string, std::function<void(CameraOptions&)>>> absurd = {
      {"fx", [](CameraOptions& o) { o.fx = 1e308; }},
      {"fx", [](CameraOptions& o) { o.fx = 1e-300; }},
      {"fx", [](CameraOptions& o) { o.fx = 100 * 640 + 1; }},  // a field of view under 0.6 deg
      {"fy", [](CameraOptions& o) { o.fy = 1e308; }},
      {"fy", [](CameraOptions& o) { o.fy = 0.05 * 480 - 1; }},  // over 169 degrees
      {"fps", [](CameraOptions& o) { o.fps = 1e308; }},
      {"fps", [](CameraOptions& o) { o.fps = 1e-300; }},  // 1/fps paces --camera-rate
      {"depth_factor", [](CameraOptions& o) { o.depth_factor = 1e308; }},
      {"depth_factor", [](CameraOptions& o) { o.depth_factor = 1e-300; }},
      {"depth_min", [](CameraOptions& o) { o.depth_min = 1e308; }},
      {"depth_max", [](CameraOptions& o) { o.depth_max = 1e308; }},
      {"depth_max", [](CameraOptions& o) { o.depth_max = std::nan(""); }},
      {"cx", [](CameraOptions& o) { o.cx = 1e308; }},
      {"width", [](CameraOptions& o) { o.width = 1 << 30; }},
  };
  for (const auto& [key, change] : absurd) {
    CameraOptions o = Freiburg2();
    change(o);
    EXPECT_EQ(error_of(o).find("camera." + key + ": "), 0u) << key << ": " << error_of(o);
  }
  // The depth settings are checked also while the intrinsics are still to come from a dataset.
  CameraOptions from_dataset;
  from_dataset.from_dataset = true;
  from_dataset.depth_factor = 1e308;
  EXPECT_EQ(error_of(from_dataset).find("camera.depth_factor: "), 0u) << error_of(from_dataset);
  // The edges of each range.
  CameraOptions edges = Freiburg2();
  edges.fx = 0.05 * 640;
  edges.fy = 100 * 480;
  edges.fps = kMaxFps;
  edges.depth_factor = kMinDepthFactor;
  edges.depth_min = 0;
  edges.depth_max = kMaxDepth;
  EXPECT_EQ(error_of(edges), "(no error)");
  edges.fps = kMinFps;
  edges.depth_factor = kMaxDepthFactor;
  EXPECT_EQ(error_of(edges), "(no error)");
}

TEST(CameraConfig, ShippedTumConfigsLoadWithPublishedValues) {
  const auto dir = testing::SourceDir() / "configs";
  const CameraOptions fr1 = LoadCameraConfig(dir / "tum_fr1.yaml");
  const CameraOptions fr2 = LoadCameraConfig(dir / "tum_fr2.yaml");
  const CameraOptions fr3 = LoadCameraConfig(dir / "tum_fr3.yaml");
  EXPECT_DOUBLE_EQ(fr1.fx, 517.306408);
  EXPECT_DOUBLE_EQ(fr1.k3, 1.163314);
  EXPECT_DOUBLE_EQ(fr2.cy, 249.701764);
  EXPECT_DOUBLE_EQ(fr2.k2, -0.784899);
  EXPECT_DOUBLE_EQ(fr3.fy, 539.2);
  EXPECT_FALSE(Camera(fr3).HasDistortion());
  EXPECT_EQ(fr3.width, 640);
  EXPECT_DOUBLE_EQ(fr3.depth_factor, 5000.0);
}

TEST(CameraConfig, WrittenConfigReadsBackIdentically) {
  testing::TempDir dir;
  YAML::Emitter out;
  out << YAML::BeginMap;
  WriteCameraOptions(Freiburg2(), &out);
  out << YAML::EndMap;
  testing::WriteText(dir / "cam.yaml", out.c_str());
  const CameraOptions back = LoadCameraConfig(dir / "cam.yaml");
  EXPECT_EQ(back.fx, Freiburg2().fx);
  EXPECT_EQ(back.k3, Freiburg2().k3);
  EXPECT_EQ(back.width, 640);
}

TEST(CameraConfig, BadConfigsAreRejectedWithTheKey) {
  testing::TempDir dir;
  auto message = [&](const std::string& text) -> std::string {
    testing::WriteText(dir / "c.yaml", text);
    try {
      LoadCameraConfig(dir / "c.yaml");
    } catch (const Error& e) {
      return e.what();
    }
    return "(no error)";
  };
  const std::string ok = "camera:\n  fx: 500\n  fy: 500\n  cx: 320\n  cy: 240\n";
  EXPECT_EQ(message(ok), "(no error)");
  EXPECT_NE(message(ok + "  k9: 1\n").find("unknown key 'camera.k9'"), std::string::npos);
  EXPECT_NE(message(ok + "extra: 1\n").find("unknown key 'extra'"), std::string::npos);
  EXPECT_NE(message("camera:\n  fy: 500\n  cx: 320\n  cy: 240\n").find("camera.fx is required"),
            std::string::npos);
  EXPECT_NE(message("camera:\n  fx: -5\n  fy: 500\n  cx: 320\n  cy: 240\n").find("camera.fx"),
            std::string::npos);
  // The message of a config names the file and the key, with the value.
  const std::string huge = message("camera:\n  fx: 1e308\n  fy: 500\n  cx: 320\n  cy: 240\n");
  EXPECT_EQ(huge.find((dir / "c.yaml").string() + ": camera.fx: "), 0u) << huge;
  EXPECT_NE(huge.find("got 1e+308"), std::string::npos) << huge;
  EXPECT_NE(message(ok + "  depth_factor: 1e308\n").find("camera.depth_factor: "),
            std::string::npos);
  // A run's config may be given for its camera: the run's own sections are left to `run`.
  EXPECT_EQ(message(ok + "mode: sdo\ntracking:\n  local_map_radius: 3\nmapping: {}\n"),
            "(no error)");
  EXPECT_NE(message("other: 1\n").find("unknown key 'other'"), std::string::npos);
  EXPECT_NE(message("{}\n").find("missing the 'camera:' section"), std::string::npos);
}

}  // namespace
}  // namespace sdoslam
