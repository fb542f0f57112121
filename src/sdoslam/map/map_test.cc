// The map's invariants under every edit local mapping and tracking make: observations both
// ways, covisibility both ways, the spanning tree across culling, and the lifetime of culled
// points.
#include "sdoslam/map/map.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "sdoslam/testing/single_feature_keyframe.h"

namespace sdoslam {
namespace {

class MapTest : public ::testing::Test {
 protected:
  MapTest()
      : camera_(MakeCamera()),
        extractor_(OrbOptions{}),
        geometry_(std::make_shared<FrameGeometry>(camera_, extractor_, 40.0, 3.0)) {}

  static Camera MakeCamera() {
    CameraOptions o;
    o.fx = o.fy = 500;
    o.cx = 320;
    o.cy = 240;
    return Camera(o);
  }

  // A keyframe of a noise texture (plenty of features) with depth 2 m everywhere, at a pose
  // that differs for every index.
  KeyFrame* AddKeyFrame(size_t index) {
    cv::Mat gray(480, 640, CV_8U);
    cv::RNG rng(static_cast<uint64_t>(index) + 1);
    rng.fill(gray, cv::RNG::UNIFORM, 0, 256);
    const cv::Mat depth(480, 640, CV_32F, cv::Scalar(2.0f));
    Frame frame(index, static_cast<double>(index), gray, depth, geometry_, extractor_);
    frame.T_camera_world = PoseFor(index);
    return map_.AddKeyFrame(std::move(frame));
  }

  static Eigen::Isometry3d PoseFor(size_t index) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const double s = static_cast<double>(index);
    T.linear() = (Eigen::AngleAxisd(0.05 * s, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(0.03 * s, Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() = Eigen::Vector3d(0.1 * s, -0.02 * s, 0.05 * s * s);
    return T;
  }

  // n unconnected keyframes.
  std::vector<KeyFrame*> KeyFrames(size_t n) {
    std::vector<KeyFrame*> kfs;
    for (size_t i = 0; i < n; ++i) kfs.push_back(AddKeyFrame(i));
    return kfs;
  }

  // `count` points seen by both keyframes, on features [first, first + count) of each.
  std::vector<MapPoint*> Share(KeyFrame* a, KeyFrame* b, int first, int count) {
    std::vector<MapPoint*> points;
    for (int i = first; i < first + count; ++i) {
      MapPoint* p = map_.AddMapPoint(a->frame.UnprojectWorld(i), a);
      map_.AddObservation(p, a, i);
      map_.AddObservation(p, b, i);
      p->UpdateFromObservations();
      points.push_back(p);
    }
    return points;
  }

  // A chain k0 <- k1 <- ... <- k(n-1) in the spanning tree: each shares 40 points with the
  // one before it, and nothing else.
  std::vector<KeyFrame*> Chain(size_t n) {
    std::vector<KeyFrame*> kfs;
    for (size_t i = 0; i < n; ++i) {
      kfs.push_back(AddKeyFrame(i));
      if (i > 0) {
        Share(kfs[i - 1], kfs[i], static_cast<int>(40 * i), 40);
        map_.UpdateConnections(kfs[i]);
      }
    }
    return kfs;
  }

  // Every observation is recorded on both sides; no good keyframe refers to a culled point or
  // culled keyframe; covisibility is symmetric; parents are good.
  void ExpectConsistent() const {
    size_t good_keyframes = 0, good_points = 0;
    for (const auto& [id, kf] : map_.keyframes()) {
      if (kf->bad) {
        EXPECT_EQ(kf->frame.size(), 0u) << "culled keyframe " << id << " keeps its features";
        ASSERT_NE(kf->parent, nullptr) << "culled keyframe " << id << " has no parent";
        EXPECT_FALSE(kf->parent->bad) << "keyframe " << id << " hangs from a culled parent";
        continue;
      }
      ++good_keyframes;
      if (kf->parent != nullptr) {
        EXPECT_FALSE(kf->parent->bad) << "keyframe " << id << " hangs from a culled parent";
        EXPECT_EQ(kf->parent->children.count(id), 1u);
      }
      for (size_t i = 0; i < kf->frame.size(); ++i) {
        const MapPoint* p = kf->frame.map_points[i];
        if (p == nullptr) continue;
        EXPECT_FALSE(p->bad) << "keyframe " << id << " feature " << i
                             << " refers to a culled point";
        const auto it = p->observations.find(id);
        ASSERT_NE(it, p->observations.end()) << "point " << p->id << " misses keyframe " << id;
        EXPECT_EQ(it->second.second, static_cast<int>(i));
      }
      for (const auto& [other_id, weight] : kf->covisibility) {
        const KeyFrame* other = map_.keyframes().at(other_id).get();
        EXPECT_FALSE(other->bad);
        ASSERT_EQ(other->covisibility.count(id), 1u) << id << " -> " << other_id << " one-sided";
        EXPECT_EQ(other->covisibility.at(id), weight);
      }
      EXPECT_EQ(kf->best_covisible.size(), kf->covisibility.size());
      for (const KeyFrame* other : kf->best_covisible) {
        EXPECT_EQ(kf->covisibility.count(other->id), 1u)
            << "keyframe " << id << " lists " << other->id << " among its best, not linked";
      }
    }
    for (const auto& [id, p] : map_.points()) {
      if (p->bad) {
        EXPECT_TRUE(p->observations.empty());
        continue;
      }
      ++good_points;
      for (const auto& [kf_id, obs] : p->observations) {
        EXPECT_FALSE(obs.first->bad) << "point " << id << " observed by culled keyframe " << kf_id;
        EXPECT_EQ(obs.first->frame.map_points[static_cast<size_t>(obs.second)], p.get());
      }
    }
    EXPECT_EQ(map_.GoodKeyFrames(), good_keyframes);
    EXPECT_EQ(map_.GoodPoints(), good_points);
  }

  Camera camera_;
  OrbExtractor extractor_;
  std::shared_ptr<const FrameGeometry> geometry_;
  Map map_;
};

bool Near(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff() < 1e-9;
}

TEST_F(MapTest, UpdateConnectionsMakesTheMostCovisibleKeyFrameTheParent) {
  const std::vector<KeyFrame*> k = KeyFrames(3);
  KeyFrame *k0 = k[0], *k1 = k[1], *k2 = k[2];
  Share(k0, k1, 0, 30);
  map_.UpdateConnections(k1);
  Share(k0, k2, 100, 20);
  Share(k1, k2, 200, 50);
  map_.UpdateConnections(k2);
  EXPECT_EQ(k1->parent, k0);
  EXPECT_EQ(k2->parent, k1);  // 50 shared beat 20
  ASSERT_EQ(k2->best_covisible.size(), 2u);
  EXPECT_EQ(k2->best_covisible[0], k1);
  EXPECT_EQ(k2->covisibility.at(k0->id), 20);
  EXPECT_EQ(k0->covisibility.at(k2->id), 20);
  EXPECT_EQ(k0->children.size(), 1u);
  ExpectConsistent();
}

// The neighbourhood local mapping adjusts and loop closing fuses over: the keyframe first, then
// its most covisible keyframes that are not culled, strongest first, at most `count`.
TEST_F(MapTest, WithStrongestNeighboursTakesTheKeyFrameThenItsStrongestGoodLinks) {
  const std::vector<KeyFrame*> k = KeyFrames(5);
  Share(k[1], k[0], 0, 40);
  map_.UpdateConnections(k[1]);
  Share(k[2], k[1], 100, 60);
  map_.UpdateConnections(k[2]);
  Share(k[3], k[1], 200, 50);
  map_.UpdateConnections(k[3]);
  Share(k[4], k[1], 300, 30);
  map_.UpdateConnections(k[4]);
  map_.UpdateConnections(k[1]);
  using List = std::vector<KeyFrame*>;
  EXPECT_EQ(WithStrongestNeighbours(k[1], 2), (List{k[1], k[2], k[3]}));
  EXPECT_EQ(WithStrongestNeighbours(k[1], 0), (List{k[1]}));
  EXPECT_EQ(WithStrongestNeighbours(k[1], 100), (List{k[1], k[2], k[3], k[0], k[4]}));
  ASSERT_TRUE(map_.SetBad(k[2]));
  EXPECT_EQ(WithStrongestNeighbours(k[1], 2), (List{k[1], k[3], k[0]}));
}

TEST_F(MapTest, EdgesBelowFifteenSharedPointsAreKeptOnlyWhenThereIsNoOther) {
  const std::vector<KeyFrame*> k = KeyFrames(3);
  KeyFrame *k0 = k[0], *k1 = k[1], *k2 = k[2];
  Share(k0, k2, 0, 10);
  Share(k1, k2, 100, 30);
  map_.UpdateConnections(k2);
  EXPECT_EQ(k2->covisibility.count(k0->id), 0u);
  EXPECT_EQ(k2->covisibility.count(k1->id), 1u);
  KeyFrame* k3 = AddKeyFrame(3);
  Share(k0, k3, 200, 5);
  map_.UpdateConnections(k3);
  EXPECT_EQ(k3->covisibility.at(k0->id), 5);  // the only one: kept so k3 is connected
  ExpectConsistent();
}

// An edge that falls below fifteen shared points goes from both sides: from the other
// keyframe's covisibility and from its ordered list of best neighbours, which local mapping and
// loop closing walk.
TEST_F(MapTest, AnEdgeThatWeakensBelowFifteenLeavesBothSidesAndTheirBestLists) {
  const std::vector<KeyFrame*> k = KeyFrames(3);
  KeyFrame *k0 = k[0], *k1 = k[1], *k2 = k[2];
  const std::vector<MapPoint*> shared = Share(k0, k1, 0, 30);
  Share(k1, k2, 100, 40);
  map_.UpdateConnections(k1);
  ASSERT_EQ(k0->best_covisible, std::vector<KeyFrame*>{k1});
  for (size_t i = 0; i < 20; ++i) map_.EraseObservation(shared[i], k1);
  map_.UpdateConnections(k1);
  EXPECT_EQ(k1->covisibility.count(k0->id), 0u);
  EXPECT_EQ(k0->covisibility.count(k1->id), 0u);
  EXPECT_TRUE(k0->best_covisible.empty());
  EXPECT_EQ(k1->best_covisible, std::vector<KeyFrame*>{k2});
  ExpectConsistent();
}

TEST_F(MapTest, EraseObservationHandsOverTheReferenceAndCullsAPointSeenOnce) {
  const std::vector<KeyFrame*> k = KeyFrames(3);
  KeyFrame *k0 = k[0], *k1 = k[1], *k2 = k[2];
  MapPoint* p = Share(k0, k1, 0, 1)[0];
  map_.AddObservation(p, k2, 5);
  map_.EraseObservation(p, k0);
  EXPECT_FALSE(p->bad);
  EXPECT_EQ(p->reference, k1);
  EXPECT_EQ(k0->frame.map_points[0], nullptr);
  map_.EraseObservation(p, k1);  // one observation left: an RGB-D point needs two
  EXPECT_TRUE(p->bad);
  EXPECT_EQ(k2->frame.map_points[5], nullptr);
  ExpectConsistent();
}

TEST_F(MapTest, ReplaceMovesEveryObservationOnce) {
  const std::vector<KeyFrame*> k = KeyFrames(3);
  KeyFrame *k0 = k[0], *k1 = k[1], *k2 = k[2];
  MapPoint* a = Share(k0, k1, 0, 1)[0];
  MapPoint* b = Share(k1, k2, 10, 1)[0];
  a->visible = 4;
  a->found = 3;
  map_.Replace(a, b);
  EXPECT_TRUE(a->bad);
  EXPECT_EQ(b->observations.size(), 3u);  // k0 from a; k1 and k2 its own
  EXPECT_EQ(b->observations.at(k0->id).second, 0);
  EXPECT_EQ(b->observations.at(k1->id).second, 10);  // k1 saw both: b's feature stays
  EXPECT_EQ(k1->frame.map_points[0], nullptr);
  EXPECT_EQ(k0->frame.map_points[0], b);
  EXPECT_EQ(b->visible, 5);
  EXPECT_EQ(b->found, 4);
  ExpectConsistent();
}

TEST_F(MapTest, CullingAKeyFrameErasesItsObservationsAndReleasesItsFeatures) {
  const std::vector<KeyFrame*> k = Chain(3);
  ASSERT_GT(k[1]->frame.size(), 500u);
  const size_t points_before = map_.GoodPoints();
  EXPECT_TRUE(map_.SetBad(k[1]));
  EXPECT_TRUE(k[1]->bad);
  EXPECT_EQ(k[1]->frame.size(), 0u);
  // Every point was seen by k1 and one other keyframe: all are culled with it.
  EXPECT_EQ(map_.GoodPoints(), points_before - 80);
  EXPECT_EQ(k[2]->parent, k[0]);
  EXPECT_TRUE(k[0]->covisibility.empty());
  ExpectConsistent();
  EXPECT_FALSE(map_.SetBad(k[0])) << "the first keyframe holds the gauge";
  EXPECT_FALSE(map_.SetBad(k[1])) << "culled twice";
}

// A map started again after an early loss: its first keyframe has no parent and shares its
// points only with the keyframes made after it, its children. Updating its connections later
// (local mapping does, after fusing) must not make one of them its parent: the cycle that
// closed turned, once the two were culled, into a keyframe that is its own parent, and placing
// a frame tracked against it never ended.
TEST_F(MapTest, TheFirstKeyFrameOfAMapStartedAgainTakesNoChildAsItsParent) {
  KeyFrame* old_root = AddKeyFrame(0);
  KeyFrame* old_child = AddKeyFrame(1);
  Share(old_root, old_child, 0, 40);
  map_.UpdateConnections(old_child);
  KeyFrame* new_root = AddKeyFrame(2);  // nothing shared with the old map
  KeyFrame* child = AddKeyFrame(3);
  KeyFrame* grandchild = AddKeyFrame(4);
  Share(new_root, child, 40, 40);
  map_.UpdateConnections(child);
  Share(child, grandchild, 80, 40);
  Share(new_root, grandchild, 120, 60);  // the root's strongest link is its grandchild
  map_.UpdateConnections(grandchild);
  ASSERT_EQ(child->parent, new_root);
  ASSERT_EQ(grandchild->parent, new_root);
  map_.UpdateConnections(new_root);
  EXPECT_EQ(new_root->parent, nullptr) << "a descendant became the root's parent";
  EXPECT_TRUE(DescendsFrom(grandchild, new_root));
  EXPECT_FALSE(DescendsFrom(new_root, grandchild));
  // Culling what can be culled leaves every reference reachable from a good keyframe.
  const Eigen::Isometry3d T_camera_reference = Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d world = ComposeWithReference(child, T_camera_reference);
  EXPECT_FALSE(map_.SetBad(new_root)) << "a map's first keyframe holds its gauge";
  EXPECT_TRUE(map_.SetBad(child));
  EXPECT_TRUE(Near(ComposeWithReference(child, T_camera_reference), world));
  ExpectConsistent();
  EXPECT_EQ(old_child->parent, old_root);
}

// The frames of a run are stored relative to their reference keyframe. After any culling
// order, each must compose to the world pose it was tracked at, and follow its surviving
// ancestor rigidly when that ancestor is refined.
class ChainCulling : public MapTest, public ::testing::WithParamInterface<std::vector<int>> {};

TEST_P(ChainCulling, EveryFrameKeepsItsWorldPose) {
  const std::vector<KeyFrame*> k = Chain(6);
  struct TrackedFrame {
    const KeyFrame* reference;
    Eigen::Isometry3d T_camera_reference, T_camera_world;
  };
  std::vector<TrackedFrame> frames;
  for (size_t i = 0; i < k.size(); ++i) {
    for (int j = 0; j < 3; ++j) {
      Eigen::Isometry3d T_camera_world = PoseFor(i);
      T_camera_world.translation() += Eigen::Vector3d(0.01 * j, 0.02, -0.01 * j);
      frames.push_back({k[i], T_camera_world * k[i]->pose().inverse(), T_camera_world});
    }
  }
  for (int victim : GetParam()) {
    ASSERT_TRUE(map_.SetBad(k[static_cast<size_t>(victim)])) << "keyframe " << victim;
    ExpectConsistent();
    for (const TrackedFrame& f : frames) {
      EXPECT_TRUE(Near(ComposeWithReference(f.reference, f.T_camera_reference), f.T_camera_world))
          << "a frame of keyframe " << f.reference->id << " moved after culling " << victim;
    }
  }
  // Bundle adjustment then moves every surviving keyframe: each frame follows its nearest
  // surviving ancestor rigidly.
  std::map<const KeyFrame*, Eigen::Isometry3d> old_pose;
  for (KeyFrame* kf : k) {
    if (kf->bad) continue;
    old_pose[kf] = kf->pose();
    Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
    shift.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    shift.translation() = Eigen::Vector3d(0.3, 0.01 * static_cast<double>(kf->id), 0);
    kf->frame.T_camera_world = kf->pose() * shift;
  }
  for (const TrackedFrame& f : frames) {
    const KeyFrame* anchor = f.reference;
    while (anchor->bad) anchor = anchor->parent;
    const Eigen::Isometry3d expected =
        f.T_camera_world * old_pose.at(anchor).inverse() * anchor->pose();
    EXPECT_TRUE(Near(ComposeWithReference(f.reference, f.T_camera_reference), expected))
        << "a frame of keyframe " << f.reference->id << " does not follow keyframe " << anchor->id;
  }
}

// Child before parent is the order that broke frame poses at 1,500 frames: the culled child
// was handed to its grandparent without composing its pose relative to the culled parent.
INSTANTIATE_TEST_SUITE_P(Orders, ChainCulling,
                         ::testing::Values(std::vector<int>{3, 2}, std::vector<int>{4, 3, 2, 1},
                                           std::vector<int>{1, 2, 3, 4},
                                           std::vector<int>{2, 4, 1, 3}));

// Loop closing moves keyframes; tracking carries a frame tied to the old map over with its
// reference's change. A frame placed through a culled reference moves as that reference's
// first good ancestor moved, which is where ComposeWithReference puts it.
TEST_F(MapTest, ACulledKeyFrameMovesWithItsGoodAncestorAndCorrectionsCompose) {
  const std::vector<KeyFrame*> kfs = Chain(4);
  const Eigen::Isometry3d T_frame_k3 = PoseFor(9) * kfs[3]->pose().inverse();
  const Eigen::Isometry3d frame_before = ComposeWithReference(kfs[3], T_frame_k3);
  ASSERT_TRUE(map_.SetBad(kfs[3]));
  EXPECT_EQ(map_.correction_epoch(), 0u);
  EXPECT_TRUE(map_.CorrectionSince(kfs[2], 0).isApprox(Eigen::Isometry3d::Identity()));
  // A loop moves k2 (k3's parent) and k1.
  Eigen::Isometry3d move = Eigen::Isometry3d::Identity();
  move.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  move.translation() = Eigen::Vector3d(0.05, -0.02, 0.03);
  std::map<uint64_t, Eigen::Isometry3d> changes;
  for (KeyFrame* kf : {kfs[1], kfs[2]}) {
    const Eigen::Isometry3d T_new = kf->pose() * move;
    changes[kf->id] = kf->pose().inverse() * T_new;
    kf->frame.T_camera_world = T_new;
  }
  map_.NoteCorrection(changes);
  EXPECT_EQ(map_.correction_epoch(), 1u);
  EXPECT_TRUE(map_.CorrectionSince(kfs[3], 0).isApprox(changes.at(kfs[2]->id)));
  EXPECT_TRUE(map_.CorrectionSince(kfs[0], 0).isApprox(Eigen::Isometry3d::Identity()));
  // The frame's old world pose carried over equals its pose composed through the culled
  // reference after the move.
  const Eigen::Isometry3d carried = frame_before * map_.CorrectionSince(kfs[3], 0);
  EXPECT_TRUE(carried.isApprox(ComposeWithReference(kfs[3], T_frame_k3), 1e-9));
  // A second correction (a global BA after the pose graph) before tracking looks: the changes
  // compose, and one already carried over is not applied again.
  Eigen::Isometry3d nudge = Eigen::Isometry3d::Identity();
  nudge.translation() = Eigen::Vector3d(0.0, 0.01, -0.02);
  const Eigen::Isometry3d k2_new = kfs[2]->pose() * nudge;
  map_.NoteCorrection({{kfs[2]->id, kfs[2]->pose().inverse() * k2_new}});
  kfs[2]->frame.T_camera_world = k2_new;
  EXPECT_EQ(map_.correction_epoch(), 2u);
  EXPECT_TRUE((frame_before * map_.CorrectionSince(kfs[3], 0))
                  .isApprox(ComposeWithReference(kfs[3], T_frame_k3), 1e-9));
  EXPECT_TRUE((carried * map_.CorrectionSince(kfs[3], 1))
                  .isApprox(ComposeWithReference(kfs[3], T_frame_k3), 1e-9));
  EXPECT_TRUE(map_.CorrectionSince(kfs[3], 2).isApprox(Eigen::Isometry3d::Identity()));
}

TEST_F(MapTest, ACulledPointIsFreedOnlyWhenTrackingAndQueuedKeyFramesAreDone) {
  KeyFrame* k0 = AddKeyFrame(0);
  KeyFrame* k1 = AddKeyFrame(1);
  map_.KeyFrameInserted(k0);
  map_.KeyFrameInserted(k1);
  MapPoint* p = Share(k0, k1, 0, 1)[0];
  const uint64_t id = p->id;
  KeyFrame* queued = AddKeyFrame(2);  // made by tracking, not yet inserted by mapping
  queued->frame.map_points[7] = p;    // as tracking matched it
  map_.SetBad(p);
  EXPECT_EQ(map_.PendingGarbage(), 1u);
  EXPECT_EQ(map_.CollectGarbage(), 0u) << "the frame being tracked may hold it";
  map_.FrameFinished();
  EXPECT_EQ(map_.CollectGarbage(), 0u) << "a queued keyframe holds it";
  EXPECT_TRUE(queued->frame.map_points[7]->bad);  // still readable: that is the point
  queued->frame.map_points[7] = nullptr;          // what inserting it does with a culled point
  map_.KeyFrameInserted(queued);
  EXPECT_EQ(map_.CollectGarbage(), 1u);
  EXPECT_EQ(map_.points().count(id), 0u);
  EXPECT_EQ(map_.PendingGarbage(), 0u);
  ExpectConsistent();
}

TEST_F(MapTest, PointsCulledAfterAFrameWaitForTheNextOne) {
  const std::vector<KeyFrame*> k = Chain(2);
  map_.KeyFrameInserted(k[1]);
  std::vector<MapPoint*> points;
  for (const auto& [id, p] : map_.points()) points.push_back(p.get());
  ASSERT_EQ(points.size(), 40u);
  map_.SetBad(points[0]);
  map_.FrameFinished();
  map_.SetBad(points[1]);
  EXPECT_EQ(map_.CollectGarbage(), 1u);
  map_.FrameFinished();
  EXPECT_EQ(map_.CollectGarbage(), 1u);
  EXPECT_EQ(map_.points().size(), 38u);
  ExpectConsistent();
}

// A point seen by many keyframes: the representative descriptor is the appearance most of its
// observations share, wherever in time they lie. Here the oldest 40 and the newest 40 views
// show two other appearances and the 120 between them the main one, so a choice made from the
// first or the last kMaxDescriptorCandidates views alone would pick an outlier.
TEST_F(MapTest, ThePointDescriptorOfManyViewsIsTheirMajorityAppearance) {
  constexpr int kViews = 200;
  ASSERT_GT(static_cast<size_t>(kViews), MapPoint::kMaxDescriptorCandidates);
  cv::RNG rng(7);
  auto random_descriptor = [&rng] {
    cv::Mat d(1, 32, CV_8U);
    rng.fill(d, cv::RNG::UNIFORM, 0, 256);
    return d;
  };
  const cv::Mat main = random_descriptor(), oldest = random_descriptor(),
                newest = random_descriptor();
  // Each view flips up to three bits of its appearance: sensor noise.
  auto noisy = [&rng](const cv::Mat& d) {
    cv::Mat v = d.clone();
    const int flips = rng.uniform(0, 4);
    for (int f = 0; f < flips; ++f) v.at<uint8_t>(0, rng.uniform(0, 32)) ^= 1 << rng.uniform(0, 8);
    return v;
  };
  MapPoint* p = nullptr;
  for (int v = 0; v < kViews; ++v) {
    KeyFrame* kf = testing::AddSingleFeatureKeyFrame(map_, static_cast<size_t>(v),
                                                     noisy(v < 40             ? oldest
                                                           : v >= kViews - 40 ? newest
                                                                              : main),
                                                     geometry_, extractor_);
    if (p == nullptr) p = map_.AddMapPoint(Eigen::Vector3d(0, 0, 2), kf);
    map_.AddObservation(p, kf, 0);
  }
  p->UpdateDescriptor();
  EXPECT_LE(DescriptorDistance(p->descriptor.ptr<uint8_t>(), main.ptr<uint8_t>()), 3);
}

}  // namespace
}  // namespace sdoslam
