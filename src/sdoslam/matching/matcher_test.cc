#include "sdoslam/matching/matcher.h"

#include <gtest/gtest.h>

#include "sdoslam/optim/optimizer.h"
#include "sdoslam/place/default_vocabulary.h"
#include "sdoslam/testing/room_frames.h"

namespace sdoslam {
namespace {

// Two noisy renderings of the static room 0.2 s apart, with their true poses.
class MatcherTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (double t : {1.0, 1.2})
      frames_.push_back(room_.MakeFrame(frames_.size(), t, static_cast<int>(t * 10)));
    // The first frame becomes a keyframe with points from its depth.
    keyframe_ = map_.AddKeyFrame(frames_[0]);
    testing::AddDepthPoints(map_, keyframe_);
  }

  // Fraction of matches whose map point agrees with the matched feature's own back-projection
  // in the second frame (at its true pose), within what the depth noise of both frames allows
  // (σ(z) = 1.2 mm + 1.9 mm·(z − 0.4)² each; ≈4.5σ of the difference, plus 1 cm).
  double CorrectFraction(const Frame& frame, int* matches) const {
    int total = 0, correct = 0;
    for (size_t i = 0; i < frame.size(); ++i) {
      const MapPoint* p = frame.map_points[i];
      if (p == nullptr || !frame.HasDepth(static_cast<int>(i))) continue;
      ++total;
      const double z = frame.depth[i];
      const double sigma = 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4);
      correct +=
          (frame.UnprojectWorld(static_cast<int>(i)) - p->position).norm() < 0.01 + 4.5 * sigma;
    }
    *matches = total;
    return total > 0 ? static_cast<double>(correct) / total : 0.0;
  }

  testing::RoomFrames room_;
  std::vector<Frame> frames_;
  Map map_;
  KeyFrame* keyframe_ = nullptr;
};

TEST_F(MatcherTest, ProjectionSearchFindsCorrectMatches) {
  // Search from a predicted pose 2 cm / 0.5° off, as a motion model gives.
  Frame current = frames_[1];
  const Eigen::Isometry3d truth = current.T_camera_world;
  current.T_camera_world.translation() += Eigen::Vector3d(0.02, -0.01, 0.01);
  current.T_camera_world.linear() =
      Eigen::AngleAxisd(0.009, Eigen::Vector3d::UnitY()).toRotationMatrix() *
      current.T_camera_world.linear();
  const int n = SearchByProjection(current, keyframe_->frame, 15.0);
  EXPECT_GT(n, 300);
  // The 15-px window admits some look-alikes of the repetitive texture; most are right, and the
  // robust pose optimisation that follows in tracking removes the rest.
  std::vector<Eigen::Vector3d> points;
  std::vector<PointObservation> observations;
  for (size_t i = 0; i < current.size(); ++i) {
    if (current.map_points[i] == nullptr) continue;
    points.push_back(current.map_points[i]->position);
    observations.push_back(current.Observation(static_cast<int>(i)));
  }
  const PoseOptimizationResult optimised =
      OptimizePose(room_.geometry()->intrinsics, current.T_camera_world, points, observations);
  current.T_camera_world = truth;
  int with_depth = 0;
  EXPECT_GT(CorrectFraction(current, &with_depth), 0.8);
  EXPECT_LT((optimised.T_camera_world.translation() - truth.translation()).norm(), 0.01);
  EXPECT_LT(
      Eigen::AngleAxisd(optimised.T_camera_world.linear() * truth.linear().transpose()).angle(),
      0.0035);
  // At a wrong pose (30 cm off) the same search finds far fewer, and mostly wrong, matches.
  Frame displaced = frames_[1];
  displaced.T_camera_world.translation() += Eigen::Vector3d(0.3, 0, 0);
  const int wrong = SearchByProjection(displaced, keyframe_->frame, 15.0);
  EXPECT_LT(wrong, n / 3);
}

// Vocabulary-guided (the built-in vocabulary's direct indexes): a keyframe feature meets only
// the frame's features under its node, yet most of the brute-force matches are found, as
// correct; with direct indexes that share no node nothing is compared at all.
TEST_F(MatcherTest, VocabularyGuidedDescriptorSearchFindsMostMatchesComparingFew) {
  const Vocabulary& vocabulary = DefaultVocabulary();
  BowVector bow;
  FeatureVector keyframe_words, current_words;
  vocabulary.Transform(keyframe_->frame.descriptors, &bow, &keyframe_words);
  vocabulary.Transform(frames_[1].descriptors, &bow, &current_words);
  size_t compared = 0;
  for (const auto& [node, features] : keyframe_words) {
    const auto it = current_words.find(node);
    if (it != current_words.end()) compared += features.size() * it->second.size();
  }
  const size_t all_pairs = keyframe_->frame.size() * frames_[1].size();
  EXPECT_LT(compared, all_pairs / 20) << "pairs compared of " << all_pairs;

  Frame brute = frames_[1], guided = frames_[1];
  brute.T_camera_world = guided.T_camera_world = Eigen::Isometry3d::Identity();
  const int n_brute = SearchByDescriptor(brute, *keyframe_);
  const int n_guided = SearchByDescriptor(guided, *keyframe_, &keyframe_words, &current_words);
  std::cout << "descriptor search: brute force " << n_brute << " matches, vocabulary-guided "
            << n_guided << " comparing " << compared << " of " << all_pairs << " pairs\n";
  EXPECT_GE(n_guided, n_brute / 2);
  guided.T_camera_world = frames_[1].T_camera_world;
  int matches = 0;
  EXPECT_GT(CorrectFraction(guided, &matches), 0.9);

  Frame none = frames_[1];
  const FeatureVector elsewhere = {{0xFFFFFFFFu, {0, 1, 2}}};
  EXPECT_EQ(SearchByDescriptor(none, *keyframe_, &keyframe_words, &elsewhere), 0);
}

TEST_F(MatcherTest, DescriptorSearchNeedsNoPoseAndLocalSearchAddsNoDuplicates) {
  Frame current = frames_[1];
  current.T_camera_world = Eigen::Isometry3d::Identity();  // no prediction at all
  const int n = SearchByDescriptor(current, *keyframe_);
  current.T_camera_world = frames_[1].T_camera_world;  // judge the matches at the true pose
  int matches = 0;
  EXPECT_GT(n, 100);
  EXPECT_GT(CorrectFraction(current, &matches), 0.9);

  Frame local = frames_[1];
  std::vector<MapPoint*> points;
  for (const auto& [id, p] : map_.points()) points.push_back(p.get());
  const int found = SearchLocalPoints(local, points, 1, 1.0);
  EXPECT_GT(found, 300);
  EXPECT_GT(CorrectFraction(local, &matches), 0.95);
  std::set<const MapPoint*> unique;
  for (const MapPoint* p : local.map_points) {
    if (p != nullptr) {
      EXPECT_TRUE(unique.insert(p).second) << "point matched twice";
    }
  }
  // A second pass may settle a few matches that were ambiguous, but never matches a point twice.
  EXPECT_LT(SearchLocalPoints(local, points, 1, 1.0), found / 20);
  unique.clear();
  for (const MapPoint* p : local.map_points) {
    if (p != nullptr) {
      EXPECT_TRUE(unique.insert(p).second) << "point matched twice";
    }
  }
}

// The local-map search's window scales with radius_factor: from a pose that puts the points
// about 10 px off (1.1 degrees of rotation, as under fast rotation with blur), the 1x window
// (2.5-4 px times the level's scale) misses most points of the finer levels, and the 3x window
// of ORB-SLAM2's RGB-D tracking (tracking.local_map_radius) finds them. The room's repetitive
// texture lets some look-alikes into the wide window; the pose optimisation after it removes them.
TEST_F(MatcherTest, LocalSearchWindowScalesWithRadiusFactor) {
  std::vector<MapPoint*> points;
  for (const auto& [id, p] : map_.points()) points.push_back(p.get());
  const Eigen::Isometry3d truth = frames_[1].T_camera_world;
  const auto search = [&](double radius_factor, Frame* frame) {
    frame->T_camera_world.linear() =
        Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()).toRotationMatrix() * truth.linear();
    const int found = SearchLocalPoints(*frame, points, 1, radius_factor, false);
    frame->T_camera_world = truth;  // judge the matches at the true pose
    return found;
  };
  Frame narrow = frames_[1], wide = frames_[1];
  const int found_narrow = search(1.0, &narrow);
  const int found_wide = search(3.0, &wide);
  int matches = 0;
  const double correct_narrow = found_narrow * CorrectFraction(narrow, &matches);
  const double correct_wide = found_wide * CorrectFraction(wide, &matches);
  EXPECT_GT(found_wide, 300);
  EXPECT_GT(correct_wide, 2 * correct_narrow) << found_narrow << " and " << found_wide << " found";
  EXPECT_GT(correct_wide / found_wide, 0.75);
}

}  // namespace
}  // namespace sdoslam
