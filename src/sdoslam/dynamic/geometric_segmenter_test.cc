#include "sdoslam/dynamic/geometric_segmenter.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "sdoslam/core/camera.h"
#include "sdoslam/core/error.h"
#include "sdoslam/dynamic/segment_test_util.h"
#include "sdoslam/synth/renderer.h"

namespace sdoslam {
namespace {

using testing::CoverIou;
using testing::RenderFrame;

const cv::Matx33d kK(525, 0, 319.5, 0, 525, 239.5, 0, 0, 1);
const cv::Size kImage(640, 480);

// A depth image of the surface z(x) for each image column (metres along the optical axis) of a
// camera with kK: every row sees the same profile.
FrontEndFrame ProfileFrame(const std::function<double(double)>& depth_of_column) {
  FrontEndFrame f;
  f.bgr = cv::Mat(kImage, CV_8UC3, cv::Scalar(90, 120, 150));
  f.depth = cv::Mat(kImage, CV_32F);
  for (int x = 0; x < kImage.width; ++x)
    f.depth.col(x).setTo(static_cast<float>(depth_of_column(x)));
  return f;
}

// Depth of the plane through the point at depth z0 on the optical axis whose x-slope is
// dz/dX = slope: z = z0 / (1 − slope · (x − cx) / fx).
double Plane(double x, double z0, double slope) { return z0 / (1 - slope * (x - 319.5) / 525); }

int LargestSegmentArea(const Segmentation& s) {
  int largest = 0;
  for (int l = 0; l < s.count; ++l) largest = std::max(largest, cv::countNonZero(s.labels == l));
  return largest;
}

// A slanted plane has no edges: one segment, no false crease from the slope.
TEST(GeometricSegmenter, ASlantedPlaneIsOneSegment) {
  GeometricSegmenter segmenter({}, kK, kImage);
  const Segmentation s = segmenter.Segment(ProfileFrame([](double x) { return Plane(x, 2, 1.0); }));
  ASSERT_EQ(s.labels.size(), cv::Size(320, 240));
  EXPECT_EQ(s.count, 1);
  EXPECT_EQ(cv::countNonZero(segmenter.last_edges()), 0);
  EXPECT_EQ(cv::countNonZero(s.labels == 0), 320 * 240);
}

// Two planes meeting at a fold along the image's centre column. Seen from the camera, a valley
// (the fold farther away than both halves' extension: the corner of a room) is concave and cuts;
// a ridge (the fold nearer: the edge of a box) is convex and does not.
TEST(GeometricSegmenter, AConcaveFoldCutsAConvexOneDoesNot) {
  GeometricSegmenter segmenter({}, kK, kImage);
  // Valley: the left half rises towards the camera to the left, the right half to the right.
  const auto valley = [](double x) { return x < 320 ? Plane(x, 2, 1.0) : Plane(x, 2, -1.0); };
  const auto ridge = [](double x) { return x < 320 ? Plane(x, 2, -1.0) : Plane(x, 2, 1.0); };
  const Segmentation v = segmenter.Segment(ProfileFrame(valley));
  EXPECT_EQ(v.count, 2);
  EXPECT_GT(cv::countNonZero(segmenter.last_edges().col(160) == 254), 200) << "the crease";
  const int left = v.labels.at<int>(120, 40), right = v.labels.at<int>(120, 280);
  EXPECT_NE(left, right);
  EXPECT_GT(cv::countNonZero(v.labels.colRange(0, 155) == left), 155 * 240 * 0.99);
  EXPECT_GT(cv::countNonZero(v.labels.colRange(165, 320) == right), 155 * 240 * 0.99);
  const Segmentation r = segmenter.Segment(ProfileFrame(ridge));
  EXPECT_EQ(r.count, 1);
  EXPECT_EQ(LargestSegmentArea(r), 320 * 240);
}

// A surface in front of another: the step is an edge, each side keeps its own pixels, and the
// edge band goes to the surface of its own depth.
TEST(GeometricSegmenter, ADepthStepSeparatesTheNearSurfaceWithItsOutline) {
  GeometricSegmenter segmenter({}, kK, kImage);
  const Segmentation s =
      segmenter.Segment(ProfileFrame([](double x) { return x >= 200 && x < 440 ? 1.5 : 3.0; }));
  EXPECT_EQ(s.count, 3);  // left wall, board, right wall
  const int board = s.labels.at<int>(100, 160);
  EXPECT_EQ(cv::countNonZero(s.labels == board), 120 * 240);  // exactly its columns 100..219
  EXPECT_EQ(cv::countNonZero(s.labels < 0), 0);
  // Without depth there is no geometry to follow.
  FrontEndFrame no_depth;
  no_depth.bgr = cv::Mat(kImage, CV_8UC3, cv::Scalar(0));
  EXPECT_EQ(segmenter.Segment(no_depth).count, 0);
}

// The rendered rooms: people and pendulum boxes by their depth steps, and the box sliding on the
// floor (14), which has no depth step along its base and a colour like the floor's: the default
// colour-and-depth graph segmenter merges it with the floor, the concave crease cuts it off.
TEST(GeometricSegmenter, SeparatesPeopleHangingBoxesAndABoxStandingOnTheFloor) {
  const cv::Matx33d K = Camera(synth::SyntheticCamera()).K();
  const std::map<std::string, std::vector<int>> objects_of = {
      {"walking_xyz", {1, 2}}, {"boxes_translational", {11, 12, 13, 14}}};
  for (const auto& [scenario, ids] : objects_of) {
    cv::Mat instance;
    const FrontEndFrame frame = RenderFrame(scenario, 3.0, &instance);
    GeometricSegmenter segmenter({}, K, frame.bgr.size());
    const Segmentation s = segmenter.Segment(frame);
    cv::Mat labels;
    cv::resize(s.labels, labels, frame.bgr.size(), 0, 0, cv::INTER_NEAREST);
    for (int id : ids) {
      const cv::Mat object = instance == id;
      ASSERT_GT(cv::countNonZero(object), 3000) << scenario << " object " << id << " in view";
      EXPECT_GT(CoverIou(labels, object), 0.8) << scenario << " object " << id;
    }
    if (scenario == "boxes_translational") {
      const Segmentation g = RgbdSegmenter().Segment(frame);
      cv::resize(g.labels, labels, frame.bgr.size(), 0, 0, cv::INTER_NEAREST);
      EXPECT_LT(CoverIou(labels, instance == 14), 0.5) << "the graph segmenter merges box 14";
    }
  }
}

TEST(GeometricSegmenter, RejectsImpossibleOptions) {
  GeometricSegmenterOptions o;
  o.normal_window = 4;
  EXPECT_THROW(o.Check(), Error);
  o = {};
  o.concave_angle_deg = 95;
  EXPECT_THROW(o.Check(), Error);
  EXPECT_THROW(GeometricSegmenter({}, cv::Matx33d::zeros(), kImage), Error);
}

}  // namespace
}  // namespace sdoslam
