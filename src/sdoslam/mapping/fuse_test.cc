#include "sdoslam/mapping/fuse.h"

#include <gtest/gtest.h>

#include <set>

#include "sdoslam/testing/room_frames.h"

namespace sdoslam {
namespace {

// Three keyframes of the static room 0.1 s apart, at their true poses. Points made from each
// one's depth map the same surfaces again, as keyframes that never matched each other leave
// them: the duplicates fusion is for.
class FuseTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (double t : {1.0, 1.1, 1.2}) {
      keyframes_.push_back(
          map_.AddKeyFrame(room_.MakeFrame(keyframes_.size(), t, static_cast<int>(t * 10))));
    }
  }

  std::vector<MapPoint*> AddDepthPoints(KeyFrame* kf) { return testing::AddDepthPoints(map_, kf); }

  // Of the observations of `points` in `kf` on features with depth (`*total`), those whose
  // feature's own back-projection agrees with the point within what the depth noise of both
  // frames allows (σ(z) = 1.2 mm + 1.9 mm·(z − 0.4)² each; ≈4.5σ of the difference, plus 1 cm;
  // as in matcher_test.cc).
  int CorrectObservations(const std::vector<MapPoint*>& points, const KeyFrame* kf,
                          int* total) const {
    int correct = 0;
    *total = 0;
    for (const MapPoint* p : points) {
      const auto it = p->observations.find(kf->id);
      if (p->bad || it == p->observations.end() || !kf->frame.HasDepth(it->second.second)) continue;
      ++*total;
      const double z = kf->frame.depth[static_cast<size_t>(it->second.second)];
      const double sigma = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
      correct +=
          (kf->frame.UnprojectWorld(it->second.second) - p->position).norm() < 0.01 + 4.5 * sigma;
    }
    return correct;
  }

  testing::RoomFrames room_;
  Map map_;
  std::vector<KeyFrame*> keyframes_;
};

TEST_F(FuseTest, AddsObservationsWhereTheKeyFrameHasNoPoint) {
  const std::vector<MapPoint*> points = AddDepthPoints(keyframes_[0]);
  const int fused = Fuse(map_, keyframes_[1], points);
  EXPECT_GT(fused, 300);
  int total = 0;
  const int correct = CorrectObservations(points, keyframes_[1], &total);
  EXPECT_GT(total, 0.8 * fused);
  EXPECT_GT(correct, 0.9 * total);
  // Points the keyframe already observes are left alone: fusing them again changes nothing.
  EXPECT_EQ(Fuse(map_, keyframes_[1], points), 0);
  EXPECT_EQ(Fuse(map_, keyframes_[0], points), 0);
}

TEST_F(FuseTest, MergesDuplicatesKeepingThePointWithMoreObservations) {
  // The first keyframe's points, most of them also observed by the third keyframe.
  const std::vector<MapPoint*> first = AddDepthPoints(keyframes_[0]);
  std::vector<int> first_feature;  // in the first keyframe
  for (const MapPoint* p : first) first_feature.push_back(p->observations.begin()->second.second);
  ASSERT_GT(Fuse(map_, keyframes_[2], first), 300);
  // culled_already: two of them landed on one feature of the third keyframe and were merged.
  std::set<const MapPoint*> seen_twice, culled_already;
  for (const MapPoint* p : first) {
    if (p->observations.size() == 2) seen_twice.insert(p);
    if (p->bad) culled_already.insert(p);
  }
  // The second keyframe's points duplicate them; projected into the first keyframe, they land
  // on its features, which hold the first keyframe's points.
  const std::vector<MapPoint*> second = AddDepthPoints(keyframes_[1]);
  const int fused = Fuse(map_, keyframes_[0], second);
  EXPECT_GT(fused, 300);
  int second_culled = 0;
  for (const MapPoint* p : second) second_culled += p->bad;
  EXPECT_GT(second_culled, 150);
  const std::set<const MapPoint*> second_set(second.begin(), second.end());
  int first_culled = 0;
  for (size_t n = 0; n < first.size(); ++n) {
    if (seen_twice.count(first[n])) {
      // Two observations against one: this point stays, whatever it was fused with.
      EXPECT_FALSE(first[n]->bad);
    } else if (first[n]->bad && !culled_already.count(first[n])) {
      // One against one: the projected point (the second keyframe's) stays and takes the
      // feature.
      ++first_culled;
      const MapPoint* now = keyframes_[0]->frame.map_points[static_cast<size_t>(first_feature[n])];
      ASSERT_NE(now, nullptr);
      EXPECT_TRUE(second_set.count(now));
    }
  }
  EXPECT_GT(first_culled, 100);
  // The second keyframe's points that the first keyframe now observes (in place of a duplicate,
  // or on a feature that had no point) are observed where they belong.
  int total = 0;
  EXPECT_GT(CorrectObservations(second, keyframes_[0], &total), 0.9 * total);
  EXPECT_GT(total, 100);
  for (const MapPoint* p : keyframes_[0]->frame.map_points) {
    if (p != nullptr) {
      EXPECT_FALSE(p->bad);
    }
  }
}

TEST_F(FuseTest, NothingOutOfView) {
  const std::vector<MapPoint*> points = AddDepthPoints(keyframes_[0]);
  // Turned around, the second camera sees none of the first one's points.
  keyframes_[1]->frame.T_camera_world =
      Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()) * keyframes_[1]->frame.T_camera_world;
  EXPECT_EQ(Fuse(map_, keyframes_[1], points), 0);
}

}  // namespace
}  // namespace sdoslam
