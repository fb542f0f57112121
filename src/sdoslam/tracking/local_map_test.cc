#include "sdoslam/tracking/local_map.h"

#include <gtest/gtest.h>

#include "sdoslam/testing/room_frames.h"

namespace sdoslam {
namespace {

// Keyframes that are copies of one rendered frame, with points placed by hand.
class LocalMapTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const testing::RoomFrames::View view = room_.Render(1.0, 0);
    frame_ =
        std::make_unique<Frame>(7, 1.0, view.bgr, view.depth, room_.geometry(), room_.extractor());
    ASSERT_GE(frame_->size(), 10u);
  }

  // A point seen by `keyframes`, as their feature `feature`.
  MapPoint* Point(std::initializer_list<KeyFrame*> keyframes, int feature) {
    MapPoint* p = map_.AddMapPoint(Eigen::Vector3d(0, 0, 1 + feature), *keyframes.begin());
    for (KeyFrame* kf : keyframes) map_.AddObservation(p, kf, feature);
    return p;
  }

  testing::RoomFrames room_;
  std::unique_ptr<Frame> frame_;
  Map map_;
};

TEST_F(LocalMapTest, KeyFramesThatSeeTheMatchesTheirNeighboursAndTheirPoints) {
  KeyFrame* a = map_.AddKeyFrame(*frame_);
  KeyFrame* b = map_.AddKeyFrame(*frame_);
  KeyFrame* c = map_.AddKeyFrame(*frame_);  // b's neighbour: they share p4
  KeyFrame* d = map_.AddKeyFrame(*frame_);  // sees only a culled point the frame matched
  KeyFrame* e = map_.AddKeyFrame(*frame_);  // culled
  MapPoint* p1 = Point({a}, 1);
  MapPoint* p2 = Point({b}, 2);
  MapPoint* p3 = Point({b}, 3);
  MapPoint* p4 = Point({b, c}, 4);
  MapPoint* p5 = Point({b, e}, 5);
  MapPoint* p6 = Point({c}, 6);
  MapPoint* p8 = Point({d}, 8);
  MapPoint* p9 = Point({a}, 9);
  map_.UpdateConnections(b);
  e->bad = true;
  p8->bad = true;
  p9->bad = true;
  Frame frame = *frame_;
  frame.map_points[1] = p1;
  frame.map_points[2] = p2;
  frame.map_points[3] = p3;
  frame.map_points[5] = p5;
  frame.map_points[8] = p8;

  const LocalMap local = FindLocalMap(map_, frame);

  EXPECT_EQ(local.keyframes, (std::vector<KeyFrame*>{a, b, c}));
  EXPECT_EQ(local.reference, b);  // 3 of the matches, a 1
  EXPECT_EQ(local.points, (std::vector<MapPoint*>{p1, p2, p3, p4, p5, p6}));
}

TEST_F(LocalMapTest, ATieGoesToTheFirstKeyFrameAndNoMatchesGiveNothing) {
  KeyFrame* a = map_.AddKeyFrame(*frame_);
  KeyFrame* b = map_.AddKeyFrame(*frame_);
  Frame frame = *frame_;
  const LocalMap none = FindLocalMap(map_, frame);
  EXPECT_TRUE(none.keyframes.empty());
  EXPECT_EQ(none.reference, nullptr);
  EXPECT_TRUE(none.points.empty());

  frame.map_points[1] = Point({b}, 1);
  frame.map_points[2] = Point({a}, 2);
  const LocalMap local = FindLocalMap(map_, frame);
  EXPECT_EQ(local.keyframes, (std::vector<KeyFrame*>{a, b}));
  EXPECT_EQ(local.reference, a);
}

}  // namespace
}  // namespace sdoslam
