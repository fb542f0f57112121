#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

#include "sdoslam/core/error.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/io/tum_dataset.h"
#include "sdoslam/synth/renderer.h"
#include "sdoslam/synth/scenarios.h"
#include "sdoslam/synth/sensor.h"
#include "sdoslam/synth/sequence.h"
#include "sdoslam/testing/test_util.h"

namespace sdoslam::synth {
namespace {

// Is a world point on the surface of `p` (within `tolerance` metres)?
bool OnSurface(const Primitive& p, const Eigen::Vector3d& world, double tolerance) {
  const Eigen::Vector3d local = p.T_world_primitive.inverse() * world;
  if (p.shape == Primitive::Shape::kEllipsoid) {
    return std::abs(local.cwiseQuotient(p.half_size).norm() - 1.0) * p.half_size.minCoeff() <
           tolerance;
  }
  const Eigen::Vector3d excess = local.cwiseAbs() - p.half_size;
  return excess.maxCoeff() < tolerance && excess.maxCoeff() > -tolerance;
}

TEST(Intersect, BoxAndEllipsoidHitsLieOnTheSurfaceWithOutwardNormals) {
  Primitive box;
  box.T_world_primitive.linear() =
      Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  box.T_world_primitive.translation() = Eigen::Vector3d(0, 0, 5);
  box.half_size = Eigen::Vector3d(0.5, 1.0, 0.3);
  Primitive ellipsoid = box;
  ellipsoid.shape = Primitive::Shape::kEllipsoid;
  for (const Primitive* p : {&box, &ellipsoid}) {
    int hits = 0;
    for (double x = -0.6; x <= 0.6; x += 0.05) {
      for (double y = -0.6; y <= 0.6; y += 0.05) {
        const Eigen::Vector3d direction(x / 5, y / 5, 1);
        Hit hit;
        if (!Intersect(*p, Eigen::Vector3d::Zero(), direction, 1e9, &hit)) continue;
        ++hits;
        EXPECT_TRUE(OnSurface(*p, hit.point, 1e-9));
        EXPECT_LT(hit.normal.dot(direction), 0.0);        // faces the camera
        EXPECT_NEAR(hit.point.z(), hit.distance, 1e-12);  // z-unit rays: parameter = depth
      }
    }
    EXPECT_GT(hits, 50);
  }
  Hit hit;
  EXPECT_FALSE(Intersect(box, Eigen::Vector3d::Zero(), Eigen::Vector3d(1, 0, 0.01), 1e9, &hit));
  EXPECT_FALSE(
      Intersect(box, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 1), 4.0, &hit));  // too far
}

TEST(Renderer, SupersampledColourAveragesThePixelArea) {
  // A plain grey wall 5 m ahead whose left edge projects at u = 40.3: pixel 40 spans
  // [39.5, 40.5], so 20 % of it shows the wall (black beyond). One ray through its centre misses
  // the wall; 4 × 4 rays put one column of four on it (u = 40.375): a quarter of the wall's
  // colour. A wrong sub-pixel offset puts none or two columns there.
  CameraOptions o;
  o.width = 80;
  o.height = 60;
  o.fx = o.fy = 100;
  o.cx = 39.5;
  o.cy = 29.5;
  const Camera camera(o);
  constexpr double kDepth = 5.0, kEdgeU = 40.3;
  Primitive wall;
  wall.half_size = Eigen::Vector3d(10, 10, 0.1);
  // Value cells of 37 cm and less would vary the wall's colour: a cell spans several metres
  // with this scale, and the wall falls in one or two.
  wall.texture_scale = 100;
  const double edge_x = (kEdgeU - o.cx) * kDepth / o.fx;
  wall.T_world_primitive.translation() = Eigen::Vector3d(edge_x + 10, 0, kDepth + 0.1);
  Scene scene;
  scene.static_parts.push_back(wall);
  const Eigen::Isometry3d at_origin = Eigen::Isometry3d::Identity();

  const RenderedView one_ray = Render(scene, 0.0, at_origin, camera);
  const cv::Mat area = RenderColour(scene, 0.0, at_origin, camera, 4);
  ASSERT_EQ(area.size(), one_ray.colour.size());
  ASSERT_EQ(area.type(), CV_32FC3);
  const int row = 30;
  const cv::Vec3f inside = one_ray.colour.at<cv::Vec3f>(row, 45);
  ASSERT_GT(inside[1], 0.05f);
  EXPECT_EQ(one_ray.colour.at<cv::Vec3f>(row, 40), cv::Vec3f(0, 0, 0));
  EXPECT_GT(one_ray.colour.at<cv::Vec3f>(row, 41)[1], 0.05f);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(area.at<cv::Vec3f>(row, 40)[c], 0.25f * inside[c], 0.02f) << "channel " << c;
    EXPECT_NEAR(area.at<cv::Vec3f>(row, 45)[c], inside[c], 1e-3f);  // wholly on the wall
    EXPECT_EQ(area.at<cv::Vec3f>(row, 35)[c], 0.0f);                // wholly off it
  }
  EXPECT_EQ(RenderColour(scene, 0.0, at_origin, camera, 1).at<cv::Vec3f>(row, 40),
            cv::Vec3f(0, 0, 0));
}

TEST(Renderer, StaticPixelsReprojectOntoTheSameSurfaceInTheNextFrame) {
  // Photometric and depth consistency of the static world between consecutive frames, using
  // only the ground-truth depth, poses and intrinsics.
  const Camera camera(SyntheticCamera());
  const double dt = 1.0 / 30.0;
  for (CameraMotion motion : {CameraMotion::kXyz, CameraMotion::kRpy, CameraMotion::kHalfsphere}) {
    const Scenario scenario = MakeScenario("walking_xyz", 10.0, motion);
    const double t0 = 2.0, t1 = t0 + 3 * dt;
    const Eigen::Isometry3d T0 = CameraPoseAt(motion, t0, 10.0),
                            T1 = CameraPoseAt(motion, t1, 10.0);
    ASSERT_GT((T0.translation() - T1.translation()).norm() +
                  Eigen::AngleAxisd(T0.linear().transpose() * T1.linear()).angle(),
              0.005);
    const RenderedView a = Render(scenario.scene, t0, T0, camera);
    const RenderedView b = Render(scenario.scene, t1, T1, camera);
    const Eigen::Isometry3d T_b_a = T1.inverse() * T0;
    int checked = 0, depth_ok = 0;
    std::vector<float> colour_errors;
    for (int v = 0; v < a.depth.rows; v += 3) {
      for (int u = 0; u < a.depth.cols; u += 3) {
        const float z = a.depth.at<float>(v, u);
        if (z <= 0 || a.instance.at<uint16_t>(v, u) != 0) continue;
        const Eigen::Vector3d p = T_b_a * camera.Unproject({u, v}, z);
        if (p.z() <= 0.1) continue;
        const Eigen::Vector2d q = camera.Project(p);
        const int ub = static_cast<int>(std::lround(q.x())),
                  vb = static_cast<int>(std::lround(q.y()));
        if (ub < 0 || vb < 0 || ub >= b.depth.cols || vb >= b.depth.rows) continue;
        if (b.instance.at<uint16_t>(vb, ub) != 0) continue;  // now hidden behind a person
        // The nearest pixel centre is up to half a pixel away; on a slanted surface its depth
        // differs by that much of the local slope.
        ++checked;
        if (std::abs(b.depth.at<float>(vb, ub) - p.z()) < 0.01 * p.z()) {
          ++depth_ok;
          const cv::Vec3f ca = a.colour.at<cv::Vec3f>(v, u), cb = b.colour.at<cv::Vec3f>(vb, ub);
          colour_errors.push_back(static_cast<float>(cv::norm(ca - cb, cv::NORM_INF)));
        }
      }
    }
    ASSERT_GT(checked, 10000) << ToString(motion);
    EXPECT_GT(depth_ok, 0.95 * checked) << ToString(motion);
    std::sort(colour_errors.begin(), colour_errors.end());
    // Texture cells cover many pixels: most reprojections land inside the same cell, and the
    // Lambertian shade does not depend on the view. Only cell borders differ.
    EXPECT_LT(colour_errors[colour_errors.size() / 2], 1e-5) << ToString(motion);
    EXPECT_LT(colour_errors[colour_errors.size() * 8 / 10], 0.02) << ToString(motion);
  }
}

// The pixels of a rendering of `scenario` at time t whose depth or instance differs from a
// brute-force one, where every pixel's ray is tested against every primitive, nearest hit first
// and the earlier primitive on a tie, as the renderer orders them. `on_objects`: the pixels the
// brute force finds on a moving object.
int MismatchedPixels(const Scenario& scenario, double t, const Eigen::Isometry3d& T_world_camera,
                     const Camera& camera, int* on_objects) {
  const CameraOptions& o = camera.options();
  const RenderedView rendered = Render(scenario.scene, t, T_world_camera, camera);
  std::vector<Primitive> parts = scenario.scene.static_parts;
  std::vector<uint16_t> ids(parts.size(), 0);
  for (const SceneObject& object : scenario.scene.objects) {
    for (const Primitive& part : object.parts_at(t)) {
      parts.push_back(part);
      ids.push_back(object.id);
    }
  }
  std::vector<cv::Point2f> pixels;
  for (int v = 0; v < o.height; ++v)
    for (int u = 0; u < o.width; ++u)
      pixels.emplace_back(static_cast<float>(u), static_cast<float>(v));
  if (camera.HasDistortion()) pixels = camera.UndistortPoints(pixels);
  const Eigen::Vector3d origin = T_world_camera.translation();
  int mismatched = 0;
  *on_objects = 0;
  for (int v = 0; v < o.height; ++v) {
    for (int u = 0; u < o.width; ++u) {
      const cv::Point2f& q = pixels[static_cast<size_t>(v) * o.width + u];
      const Eigen::Vector3d direction =
          T_world_camera.linear() * Eigen::Vector3d((q.x - o.cx) / o.fx, (q.y - o.cy) / o.fy, 1.0);
      Hit best, hit;
      best.distance = 1e9;
      uint16_t id = 0;
      bool any = false;
      for (size_t k = 0; k < parts.size(); ++k) {
        if (Intersect(parts[k], origin, direction, best.distance, &hit)) {
          best = hit;
          id = ids[k];
          any = true;
        }
      }
      const float depth = any ? static_cast<float>(best.distance) : 0.0f;
      *on_objects += id != 0;
      mismatched +=
          rendered.depth.at<float>(v, u) != depth || rendered.instance.at<uint16_t>(v, u) != id;
    }
  }
  return mismatched;
}

// The synthetic camera at half resolution: a quarter of the brute force's time.
CameraOptions HalfSyntheticCamera() {
  CameraOptions o = SyntheticCamera();
  o.width /= 2;
  o.height /= 2;
  o.fx /= 2;
  o.fy /= 2;
  o.cx = (o.cx + 0.5) / 2 - 0.5;
  o.cy = (o.cy + 0.5) / 2 - 0.5;
  return o;
}

// The renderer tests a ray only against the primitives whose screen rectangle holds its pixel.
// Every pixel is rendered here again against every primitive (MismatchedPixels): depth and
// instance must agree exactly, so a rectangle that leaves out a pixel the primitive covers
// shows. The views include walls partly behind the camera, people close to it, and a camera
// pressed against a cabinet and a wall.
TEST(Renderer, ScreenRectanglesLeaveOutNoPixelAPrimitiveCovers) {
  const Camera camera(HalfSyntheticCamera());
  struct View {
    std::string scenario;
    double t;
    double duration;
  };
  int views = 0, people_views = 0;
  for (const View& view :
       {View{"walking_xyz", 1.0, 10.0}, View{"walking_halfsphere", 6.0, 10.0},
        View{"long_loop_people", 9.0, 24.0}, View{"long_loop_people", 15.0, 24.0},
        View{"long_loop", 4.0, 24.0}, View{"mixed", 3.0, 10.0}, View{"box_alongside", 2.0, 10.0}}) {
    const Scenario scenario = MakeScenario(view.scenario, view.duration);
    std::vector<Eigen::Isometry3d> poses = {CameraPoseAt(scenario.motion, view.t, view.duration)};
    if (views == 0) {
      // 5 cm in front of the cabinet at (-2.4, 3.0), looking at it.
      Eigen::Matrix3d R;
      R << 1, 0, 0, 0, 0, 1, 0, -1, 0;  // camera x = world x, y = -z (down), z = world y
      poses.push_back(Pose(Eigen::Vector3d(-2.0, 2.55, 1.0), R));
      // 5 cm from the left wall, looking at it, above the shelves that reach out behind.
      Eigen::Matrix3d L;
      L << 0, 0, -1, 1, 0, 0, 0, -1, 0;
      poses.push_back(Pose(Eigen::Vector3d(-2.95, 0.0, 1.5), L));
    }
    for (const Eigen::Isometry3d& T_world_camera : poses) {
      SCOPED_TRACE(view.scenario + " t = " + std::to_string(view.t));
      int on_objects = 0;
      EXPECT_EQ(MismatchedPixels(scenario, view.t, T_world_camera, camera, &on_objects), 0);
      ++views;
      people_views += on_objects > 100;
    }
  }
  EXPECT_EQ(views, 9);
  EXPECT_GE(people_views, 4);  // the movers were in view, not only the room
}

// Under a lens that distorts (freiburg1's, the strongest of the TUM cameras) the rectangles
// bound the rays' directions instead of pixels, and each row keeps only the primitives its rays
// may reach: still no pixel left out. Rendered twice, so that the second rendering takes the
// undistorted pixels from the renderer's cache.
TEST(Renderer, DirectionRectanglesUnderDistortionLeaveOutNoPixel) {
  CameraOptions o = HalfSyntheticCamera();
  o.k1 = 0.262383;
  o.k2 = -0.953104;
  o.p1 = -0.005358;
  o.p2 = 0.002628;
  o.k3 = 1.163314;
  const Camera camera(o);
  ASSERT_TRUE(camera.HasDistortion());
  const Scenario scenario = MakeScenario("mixed", 10.0);
  int people_views = 0;
  for (const double t : {3.0, 3.0, 6.0}) {
    SCOPED_TRACE("t = " + std::to_string(t));
    int on_objects = 0;
    EXPECT_EQ(
        MismatchedPixels(scenario, t, CameraPoseAt(scenario.motion, t, 10.0), camera, &on_objects),
        0);
    people_views += on_objects > 100;
  }
  EXPECT_GE(people_views, 2);
}

// The texture's cells are found by a product with the inverse cell size: the same cell as the
// division everywhere, at the borders above all (multiples of the size and their neighbours).
TEST(Texture, FloorOfQuotientIsTheDivisionsFloor) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> metres(-50.0, 50.0);
  int checked = 0, differ = 0, near_borders = 0;
  for (const double size : {0.37, 0.13, 0.047, 0.1, 1.0 / 3.0}) {
    const double inverse = 1.0 / size;
    auto check = [&](double x) {
      ++checked;
      differ += FloorOfQuotient(x, size, inverse) != static_cast<int32_t>(std::floor(x / size));
    };
    for (int k = 0; k < 100000; ++k) check(metres(rng));
    for (int k = -400; k <= 400; ++k) {
      double x = k * size;
      for (int step = 0; step < 3; ++step) x = std::nextafter(x, -1e9);
      for (int step = 0; step < 7; ++step, x = std::nextafter(x, 1e9)) {
        check(x);
        near_borders += std::floor(x / size) != std::floor(std::nextafter(x, 1e9) / size);
      }
    }
  }
  EXPECT_EQ(differ, 0) << "of " << checked;
  EXPECT_GT(near_borders, 3000);  // the border points did straddle the cells' edges
}

// A sampler that remembers the last cells gives every point of a path the colour a fresh
// TextureColour gives it, across cell borders, seeds and base colours.
TEST(Texture, TheSamplerRemembersCellsWithoutChangingColours) {
  TextureSampler sampler;
  int points = 0, differ = 0;
  std::set<std::array<float, 3>> colours;
  for (int k = 0; k < 6000; ++k) {
    for (const uint32_t seed : {1u, 7u, 7u}) {  // two primitives side by side, in turn
      const Eigen::Vector3d q(-1.0 + 0.0006 * k, 0.3 + 0.0002 * k, 2.0 - 0.0004 * k);
      const Eigen::Vector3f base(0.2f + 0.1f * static_cast<float>(seed % 3), 0.5f, 0.7f);
      const Eigen::Vector3f a = sampler.Colour(base, seed, q), b = TextureColour(base, seed, q);
      ++points;
      differ += a != b;
      colours.insert({a.x(), a.y(), a.z()});
    }
  }
  EXPECT_EQ(differ, 0) << "of " << points;
  EXPECT_GT(colours.size(), 100u);  // the path crossed many cells
}

TEST(Scenarios, LoopReturnsToItsStartAndUnknownNamesAreErrors) {
  const Eigen::Isometry3d start = CameraPoseAt(CameraMotion::kLoop, 0.0, 9.0);
  const Eigen::Isometry3d end = CameraPoseAt(CameraMotion::kLoop, 9.0, 9.0);
  const Eigen::Isometry3d middle = CameraPoseAt(CameraMotion::kLoop, 4.5, 9.0);
  EXPECT_TRUE(start.isApprox(end, 1e-9));
  EXPECT_GT((start.translation() - middle.translation()).norm(), 1.0);
  try {
    MakeScenario("walking_sideways", 1.0);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("unknown scenario 'walking_sideways' (known: static_room"),
              std::string::npos);
  }
  EXPECT_THROW(ParseCameraMotion("spiral"), Error);
  for (const auto& name : ScenarioNames()) EXPECT_NO_THROW(MakeScenario(name, 5.0)) << name;
}

// The synthetic camera at a quarter of the resolution: enough to see what is in view, quickly.
Camera SmallCamera() {
  CameraOptions o = SyntheticCamera();
  o.width /= 4;
  o.height /= 4;
  o.fx /= 4;
  o.fy /= 4;
  o.cx /= 4;
  o.cy /= 4;
  return Camera(o);
}

// The fraction of the static pixels seen from `a` that `b` sees too (in its image, not hidden).
double SharedView(const Scene& scene, const Eigen::Isometry3d& a, const Eigen::Isometry3d& b,
                  const Camera& camera) {
  const RenderedView view_a = Render(scene, 0.0, a, camera);
  const RenderedView view_b = Render(scene, 0.0, b, camera);
  const Eigen::Isometry3d T_b_a = b.inverse() * a;
  int seen = 0, shared = 0;
  for (int v = 0; v < view_a.depth.rows; ++v) {
    for (int u = 0; u < view_a.depth.cols; ++u) {
      const float z = view_a.depth.at<float>(v, u);
      if (z <= 0 || view_a.instance.at<uint16_t>(v, u) != 0) continue;
      ++seen;
      const Eigen::Vector3d p = T_b_a * camera.Unproject({u, v}, z);
      if (p.z() <= 0.1) continue;
      const Eigen::Vector2d q = camera.Project(p);
      const int ub = static_cast<int>(std::lround(q.x())),
                vb = static_cast<int>(std::lround(q.y()));
      if (ub < 0 || vb < 0 || ub >= view_b.depth.cols || vb >= view_b.depth.rows) continue;
      shared += std::abs(view_b.depth.at<float>(vb, ub) - p.z()) < 0.03 * p.z();
    }
  }
  return seen > 0 ? static_cast<double>(shared) / seen : 0.0;
}

TEST(Scenarios, LongLoopIsAClosedHandHeldWalkThatEndsSeeingItsStart) {
  const double dt = 1.0 / 30.0;
  const double duration = (kLongLoopFrames - 1) * dt;
  auto pose = [&](int k) { return CameraPoseAt(CameraMotion::kLongLoop, k * dt, duration); };
  auto angle = [](const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
  };
  const Eigen::Isometry3d start = pose(0);

  // One lap closes exactly, and the end walks the first stretch again with the same poses.
  EXPECT_GE(LongLoopLength(), 8.0);
  EXPECT_TRUE(LongLoopPoseAtArc(LongLoopLength()).isApprox(start, 1e-9));
  EXPECT_TRUE(LongLoopPoseAtArc(LongLoopLength() + 0.3).isApprox(LongLoopPoseAtArc(0.3), 1e-9));
  EXPECT_NEAR(LongLoopArcAt(duration, duration), LongLoopLength() + LongLoopRetrace(), 1e-9);

  // A walk a hand can hold: at most 0.5 m/s and 60°/s, starting and ending at rest, and the
  // camera never closer than 0.7 m to anything, so that depth is there all the time.
  double walked = 0, fastest = 0, fastest_turn = 0;
  for (int k = 0; k + 1 < kLongLoopFrames; ++k) {
    const double step = (pose(k + 1).translation() - pose(k).translation()).norm();
    walked += step;
    fastest = std::max(fastest, step / dt);
    fastest_turn = std::max(fastest_turn, angle(pose(k), pose(k + 1)) / dt);
  }
  EXPECT_NEAR(walked, LongLoopLength() + LongLoopRetrace(), 0.05);
  EXPECT_LE(fastest, 0.5);
  EXPECT_LE(fastest_turn * 180 / M_PI, 60.0);
  EXPECT_LT((pose(1).translation() - start.translation()).norm() / dt, 0.01);
  const int last = kLongLoopFrames - 1;
  EXPECT_LT((pose(last).translation() - pose(last - 1).translation()).norm() / dt, 0.01);

  const Camera camera = SmallCamera();
  const Scenario scenario = MakeScenario("long_loop", duration);
  for (int k = 0; k < kLongLoopFrames; k += 25) {
    const RenderedView view = Render(scenario.scene, k * dt, pose(k), camera);
    double nearest = 1e9;
    for (int v = 0; v < view.depth.rows; ++v) {
      for (int u = 0; u < view.depth.cols; ++u) {
        const float z = view.depth.at<float>(v, u);
        ASSERT_GT(z, 0.0f) << "frame " << k;  // inside the room: something in every direction
        nearest = std::min(nearest, static_cast<double>(z));
      }
    }
    EXPECT_GT(nearest, 0.7) << "frame " << k;
  }

  // The lap ends on the start pose within its last 3 s; from there to the end the camera walks
  // the first stretch again and sees most of what the first 3 s saw (for place recognition).
  int back = -1;
  for (int k = last - 90; k <= last; ++k) {
    if ((pose(k).translation() - start.translation()).norm() < 0.01 &&
        angle(pose(k), start) < 0.01) {
      back = k;
      break;
    }
  }
  ASSERT_GE(back, 0) << "the lap does not end on the start pose in the last 3 s";
  // At least 2 s of the first stretch walked again: a keyframe or two more than one lap's drift
  // needs, so that the loop is still found when a busy machine shifts the keyframes.
  EXPECT_GE(last - back, 60);
  EXPECT_LT((pose(last).translation() - start.translation()).norm(), LongLoopRetrace() + 0.05);
  EXPECT_GT(SharedView(scenario.scene, start, pose(back), camera), 0.98);
  for (int k = back - 30; k <= back + 30; k += 15) {
    EXPECT_GT(SharedView(scenario.scene, start, pose(k), camera), 0.6) << "frame " << k;
  }
  for (int k = back; k <= last; k += 15) {
    double best = 0;
    for (int j = 0; j <= 90; j += 15)
      best = std::max(best, SharedView(scenario.scene, pose(j), pose(k), camera));
    EXPECT_GT(best, 0.6) << "frame " << k;
  }
  // Halfway round, the camera looks at the other side of the room.
  EXPECT_LT(SharedView(scenario.scene, start, pose(last / 2), camera), 0.05);
}

TEST(Scenarios, LongLoopPeopleWalkThroughTheViewButNotThroughTheStartView) {
  const double dt = 1.0 / 30.0;
  const double duration = (kLongLoopFrames - 1) * dt;
  const Scenario scenario = MakeScenario("long_loop_people", duration);
  EXPECT_EQ(scenario.motion, CameraMotion::kLongLoop);
  ASSERT_GE(scenario.scene.objects.size(), 2u);
  const Camera camera = SmallCamera();
  std::set<uint16_t> seen;
  int frames_with_people = 0, frames = 0;
  double largest = 0;
  for (int k = 0; k < kLongLoopFrames; k += 10) {
    const RenderedView view =
        Render(scenario.scene, k * dt, CameraPoseAt(scenario.motion, k * dt, duration), camera);
    const double covered =
        cv::countNonZero(view.instance) / static_cast<double>(view.instance.total());
    ++frames;
    frames_with_people += covered > 0;
    largest = std::max(largest, covered);
    for (int v = 0; v < view.instance.rows; ++v) {
      for (int u = 0; u < view.instance.cols; ++u) {
        if (view.instance.at<uint16_t>(v, u) != 0) seen.insert(view.instance.at<uint16_t>(v, u));
      }
    }
    // The first and last 2.5 s, where a loop would be recognised, are free of people.
    if (k * dt < 2.5 || k * dt > duration - 2.5) {
      EXPECT_EQ(covered, 0.0) << "frame " << k;
    }
  }
  EXPECT_EQ(seen.size(), scenario.scene.objects.size());  // every walker comes into view
  EXPECT_GT(frames_with_people, frames / 5);
  EXPECT_LT(largest, 0.6);  // never hides most of the room
}

TEST(Sensor, DepthNoiseFollowsTheModelAndSilhouettesLoseDepth) {
  const Camera camera(SyntheticCamera());
  const Scenario scenario = MakeScenario("walking_static", 10.0);
  const RenderedView view =
      Render(scenario.scene, 1.0, CameraPoseAt(scenario.motion, 1.0, 10.0), camera);
  SensorOptions options;
  const SensorFrame frame = Sense(view, camera.options(), options, 5, 0);
  double sum_sq = 0, model_sq = 0;
  int n = 0, missing_at_edges = 0, edges = 0;
  for (int v = 1; v + 1 < view.depth.rows; ++v) {
    for (int u = 1; u + 1 < view.depth.cols; ++u) {
      const float z = view.depth.at<float>(v, u);
      const float left = view.depth.at<float>(v, u - 1);
      const uint16_t raw = frame.depth.at<uint16_t>(v, u);
      if (left > 0 && z - left > 0.2f * z) {  // far side of a big jump
        ++edges;
        missing_at_edges += raw == 0;
      }
      if (raw == 0 || z < 2.0f || z > 3.0f) continue;
      const double error = raw / 5000.0 - z;
      const double sigma = options.depth_noise_a + options.depth_noise_b * (z - 0.4) * (z - 0.4);
      sum_sq += error * error;
      model_sq += sigma * sigma;
      ++n;
    }
  }
  ASSERT_GT(n, 5000);
  EXPECT_NEAR(std::sqrt(sum_sq / n), std::sqrt(model_sq / n), 0.1 * std::sqrt(model_sq / n));
  ASSERT_GT(edges, 50);
  EXPECT_EQ(missing_at_edges, edges);
  // Image noise: σ = 2 grey levels.
  cv::Mat perfect;
  view.colour.convertTo(perfect, CV_8UC3, 255.0);
  cv::Mat diff;
  cv::subtract(frame.bgr, perfect, diff, cv::noArray(), CV_32FC3);
  cv::Scalar mean, stddev;
  cv::meanStdDev(diff.reshape(1), mean, stddev);
  EXPECT_NEAR(stddev[0], 2.0, 0.3);
}

// The sensor's noise is std::normal_distribution<float>'s, drawn by hand for speed: the same
// values bit for bit, so sequences stay as they were rendered before.
TEST(Sensor, UnitNormalDrawsWhatTheStandardLibraryDraws) {
  for (const uint32_t seed : {17u, 7919u * 5u + 17u, 123456789u}) {
    std::mt19937 ours(seed), theirs(seed);
    UnitNormal unit_normal(ours);
    std::normal_distribution<float> library(0.0f, 1.0f);
    int differ = 0;
    double sum = 0, sum_sq = 0;
    constexpr int kDraws = 1000000;
    for (int k = 0; k < kDraws; ++k) {
      const float a = unit_normal(), b = library(theirs);
      differ += std::memcmp(&a, &b, sizeof a) != 0;
      sum += a;
      sum_sq += double(a) * a;
    }
    EXPECT_EQ(differ, 0) << "seed " << seed;
    EXPECT_NEAR(sum / kDraws, 0.0, 0.005);
    EXPECT_NEAR(sum_sq / kDraws, 1.0, 0.005);
    EXPECT_EQ(ours(), theirs());  // and the generator left in the same state
  }
}

// Fill draws the values in bulk (the sensor fills a row at a time): the same values as the
// library's, whatever the sizes of the batches, odd ones (which keep the second value of a
// pair for the next) and empty ones included.
TEST(Sensor, UnitNormalFillDrawsWhatTheStandardLibraryDraws) {
  std::mt19937 ours(29), theirs(29);
  UnitNormal unit_normal(ours);
  std::normal_distribution<float> library(0.0f, 1.0f);
  std::vector<float> batch;
  int differ = 0, drawn = 0;
  for (const size_t size : {1, 0, 2, 3, 3, 7, 1920, 1, 639, 640, 5}) {
    batch.assign(size, 0.0f);
    unit_normal.Fill(batch.data(), size);
    for (const float a : batch) {
      const float b = library(theirs);
      differ += std::memcmp(&a, &b, sizeof a) != 0;
      ++drawn;
    }
    // A single call in between takes the next value in turn.
    const float a = unit_normal(), b = library(theirs);
    differ += std::memcmp(&a, &b, sizeof a) != 0;
    ++drawn;
  }
  EXPECT_EQ(drawn, 3232);
  EXPECT_EQ(differ, 0);
  EXPECT_EQ(ours(), theirs());
}

TEST(Sensor, DepthDistortionGrowsTowardsTheCorners) {
  const Camera camera(SyntheticCamera());
  const Scenario scenario = MakeScenario("static_room", 10.0);
  const RenderedView view =
      Render(scenario.scene, 1.0, CameraPoseAt(scenario.motion, 1.0, 10.0), camera);
  SensorOptions options;
  options.depth_noise_a = options.depth_noise_b = 0;
  options.depth_distortion = 0.04;
  const SensorFrame frame = Sense(view, camera.options(), options, 5, 0);
  auto ratio = [&](int u, int v) {
    return frame.depth.at<uint16_t>(v, u) / 5000.0 / view.depth.at<float>(v, u);
  };
  const int w = view.depth.cols, h = view.depth.rows;
  EXPECT_NEAR(ratio(w / 2, h / 2), 1.0, 1e-3);
  for (auto [u, v] : {std::pair{2, 2}, {w - 3, 2}, {2, h - 3}, {w - 3, h - 3}}) {
    EXPECT_NEAR(ratio(u, v), 1.04, 2e-3) << u << " " << v;
  }
  EXPECT_NEAR(ratio(w / 2, 2), 1.0 + 0.04 * h * h / (w * w + h * h), 2e-3);
  options.depth_distortion = 0;  // the default: exact depth
  EXPECT_NEAR(Sense(view, camera.options(), options, 5, 0).depth.at<uint16_t>(2, 2) / 5000.0,
              view.depth.at<float>(2, 2), 1e-3);
  EXPECT_EQ(MakeScenario("long_loop", 10.0).depth_distortion, 0.04);
  EXPECT_EQ(MakeScenario("loop", 10.0).depth_distortion, 0.0);
}

class SequenceTest : public ::testing::Test {
 protected:
  static SynthOptions Options(const std::string& scenario, int frames, bool noise) {
    SynthOptions o;
    o.scenario = scenario;
    o.frames = frames;
    o.sensor.enabled = noise;
    return o;
  }
  testing::TempDir dir_;
};

TEST_F(SequenceTest, WrittenSequenceIsATumDatasetWhoseGroundTruthIsGeometricallyConsistent) {
  // Back-project every pixel of an object with the *written* depth, camera.yaml and
  // groundtruth.txt, move it into the object's frame with object_poses.txt, and it must lie on
  // the object's surface: intrinsics, poses, depth factor and masks all agree.
  const auto out = dir_ / "seq";
  WriteSequence(Options("boxes_translational", 3, false), out);
  const CameraOptions config = LoadCameraConfig(out / "camera.yaml");
  EXPECT_EQ(config.fx, SyntheticCamera().fx);
  EXPECT_EQ(config.cy, SyntheticCamera().cy);
  const TumDataset dataset(out, config);
  ASSERT_EQ(dataset.size(), 3u);
  const Trajectory gt = ReadTumTrajectory(out / "groundtruth.txt");
  ASSERT_EQ(gt.size(), 3u);

  std::map<std::pair<std::string, int>, Eigen::Isometry3d> object_pose;  // (stamp, id)
  std::istringstream poses(testing::ReadText(out / "object_poses.txt"));
  for (std::string line; std::getline(poses, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream f(line);
    std::string stamp;
    int id;
    double x, y, z, qx, qy, qz, qw;
    f >> stamp >> id >> x >> y >> z >> qx >> qy >> qz >> qw;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(x, y, z);
    object_pose[{stamp, id}] = T;
  }
  const Scenario scenario = MakeScenario("boxes_translational", 2.0 / 30.0);
  const Camera camera(config);
  int objects_checked = 0;
  for (size_t k = 0; k < dataset.size(); ++k) {
    const RgbdFrame frame = dataset.Load(k);
    const std::string stamp = dataset.entries()[k].rgb_path.stem().string();
    const cv::Mat instance =
        cv::imread((out / "instance" / (stamp + ".png")).string(), cv::IMREAD_UNCHANGED);
    const cv::Mat dynamic =
        cv::imread((out / "dynamic" / (stamp + ".png")).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(instance.type(), CV_16UC1);
    // Every object here moves all the time: dynamic mask == any object.
    EXPECT_EQ(cv::countNonZero((instance > 0) != (dynamic == 255)), 0);
    for (const SceneObject& object : scenario.scene.objects) {
      const Primitive body = object.parts_at(k / 30.0)[0];  // the box (not the rod)
      const Eigen::Isometry3d T_world_object = object_pose.at({stamp, object.id});
      ASSERT_TRUE(T_world_object.isApprox(object.pose_at(k / 30.0), 1e-6));
      int on_box = 0, total = 0;
      for (int v = 0; v < instance.rows; v += 2) {
        for (int u = 0; u < instance.cols; u += 2) {
          if (instance.at<uint16_t>(v, u) != object.id || frame.depth.at<float>(v, u) <= 0)
            continue;
          const Eigen::Vector3d world =
              gt[k].T_world_camera * camera.Unproject({u, v}, frame.depth.at<float>(v, u));
          Primitive in_object_frame = body;
          in_object_frame.T_world_primitive =
              T_world_object * (object.pose_at(k / 30.0).inverse() * body.T_world_primitive);
          ++total;
          on_box += OnSurface(in_object_frame, world, 0.002);
        }
      }
      if (total > 200) {
        ++objects_checked;
        EXPECT_GT(on_box, 0.8 * total) << object.name;  // the rest is the thin rod
      }
    }
  }
  EXPECT_GE(objects_checked, 9);  // most boxes are in view in every frame
}

TEST_F(SequenceTest, DetectionsBoxThePeople) {
  const auto out = dir_ / "seq";
  WriteSequence(Options("walking_static", 2, true), out);
  const auto j = nlohmann::json::parse(testing::ReadText(out / "detections.json"));
  ASSERT_EQ(j["frames"].size(), 2u);
  for (const auto& frame : j["frames"]) {
    const std::string stamp = frame["timestamp"];
    const cv::Mat instance =
        cv::imread((out / "instance" / (stamp + ".png")).string(), cv::IMREAD_UNCHANGED);
    ASSERT_GE(frame["detections"].size(), 1u);
    for (const auto& d : frame["detections"]) {
      EXPECT_EQ(d["class"], "person");
      const cv::Rect box(d["box"][0], d["box"][1], d["box"][2], d["box"][3]);
      const cv::Mat mask = instance == d["instance"].get<int>();
      EXPECT_EQ(cv::countNonZero(mask(box)), cv::countNonZero(mask));  // all inside
      EXPECT_EQ(cv::boundingRect(mask), box);                          // and tight
    }
  }
}

TEST_F(SequenceTest, SameSeedGivesByteIdenticalFilesAndOtherSeedsDiffer) {
  WriteSequence(Options("mixed", 2, true), dir_ / "a");
  WriteSequence(Options("mixed", 2, true), dir_ / "b");
  SynthOptions other = Options("mixed", 2, true);
  other.seed = 2;
  WriteSequence(other, dir_ / "c");
  int files = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir_ / "a")) {
    if (!entry.is_regular_file()) continue;
    const auto relative = std::filesystem::relative(entry.path(), dir_ / "a");
    EXPECT_EQ(testing::ReadText(entry.path()), testing::ReadText(dir_ / "b" / relative))
        << relative;
    ++files;
  }
  EXPECT_EQ(files, 17);  // 4 images × 2 frames + 8 lists, poses, configs and JSON + marker
  const auto rgb = std::filesystem::path("rgb") / "1000.000000.png";
  EXPECT_NE(testing::ReadText(dir_ / "a" / rgb), testing::ReadText(dir_ / "c" / rgb));
  EXPECT_EQ(testing::ReadText(dir_ / "a" / "groundtruth.txt"),
            testing::ReadText(dir_ / "c" / "groundtruth.txt"));
}

TEST_F(SequenceTest, NeverOverwritesAnExistingSequenceUnlessAsked) {
  const auto out = dir_ / "seq";
  testing::WriteText(out / "precious.txt", "earlier result");
  EXPECT_THROW(WriteSequence(Options("static_room", 1, false), out), Error);
  EXPECT_EQ(testing::ReadText(out / "precious.txt"), "earlier result");
  SynthOptions bad = Options("nope", 1, false);
  EXPECT_THROW(WriteSequence(bad, dir_ / "x"), Error);
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x"));
  // Not even when asked: the folder holds a file synth did not write.
  EXPECT_THROW(WriteSequence(Options("static_room", 1, false), out, /*overwrite=*/true), Error);
  EXPECT_EQ(testing::ReadText(out / "precious.txt"), "earlier result");
  // An earlier sequence of its own it replaces when asked.
  std::filesystem::remove(out / "precious.txt");
  WriteSequence(Options("static_room", 2, false), out);
  WriteSequence(Options("static_room", 1, false), out, /*overwrite=*/true);
  EXPECT_FALSE(std::filesystem::exists(out / "rgb" / "1000.033333.png"));  // frame 2 went
  EXPECT_TRUE(std::filesystem::exists(out / "rgb.txt"));
}

}  // namespace
}  // namespace sdoslam::synth
