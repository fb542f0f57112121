#include "sdoslam/eval/metrics.h"

#include <gtest/gtest.h>

#include <random>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

StampedPose Pose(double t, const Eigen::Vector3d& position,
                 const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity()) {
  StampedPose p;
  p.timestamp = t;
  p.T_world_camera.linear() = rotation;
  p.T_world_camera.translation() = position;
  return p;
}

// A wavy 3-D ground truth at 30 Hz with a rotating camera.
Trajectory WavyTrajectory(int n, double t0 = 100.0) {
  Trajectory t;
  for (int k = 0; k < n; ++k) {
    const double s = k / 30.0;
    t.push_back(Pose(
        t0 + s, {std::sin(s), 0.5 * std::cos(0.7 * s), 0.2 * s},
        Eigen::AngleAxisd(0.3 * s, Eigen::Vector3d(0.2, 1, 0.1).normalized()).toRotationMatrix()));
  }
  return t;
}

Trajectory Transformed(const Trajectory& in, const Eigen::Isometry3d& T, double scale = 1.0) {
  Trajectory out = in;
  for (auto& p : out) {
    p.T_world_camera = T * p.T_world_camera;
    p.T_world_camera.translation() *= scale;
  }
  return out;
}

TEST(ErrorStats, MatchesHandComputedValues) {
  const ErrorStats s = ComputeErrorStats({4, 1, 3, 2});
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));
  EXPECT_DOUBLE_EQ(s.min, 1);
  EXPECT_DOUBLE_EQ(s.max, 4);
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(ComputeErrorStats({3, 1, 2}).median, 2);
}

TEST(Ate, KnownRigidOffsetGivesZeroAfterAlignment) {
  const Trajectory gt = WavyTrajectory(200);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(1.1, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(3, -4, 5);
  const Trajectory est = Transformed(gt, T);
  const AteResult ate = ComputeAte(gt, est);
  EXPECT_EQ(ate.translation.count, 200u);
  EXPECT_LT(ate.translation.rmse, 1e-9);
  EXPECT_TRUE(ate.alignment.rotation.isApprox(T.linear().transpose(), 1e-9));
  // Without alignment the offset is all there is.
  AteOptions none;
  none.alignment = AlignmentMode::kNone;
  EXPECT_GT(ComputeAte(gt, est, none).translation.rmse, 1.0);
}

TEST(Ate, ConstantShiftWithoutAlignmentIsItsLength) {
  const Trajectory gt = WavyTrajectory(50);
  Eigen::Isometry3d shift = Eigen::Isometry3d::Identity();
  shift.translation() = Eigen::Vector3d(0.3, 0.4, 0.0);
  AteOptions none;
  none.alignment = AlignmentMode::kNone;
  const AteResult ate = ComputeAte(gt, Transformed(gt, shift), none);
  EXPECT_NEAR(ate.translation.rmse, 0.5, 1e-12);
  EXPECT_NEAR(ate.translation.std, 0.0, 1e-12);
}

TEST(Ate, SaddleNoisePatternHasKnownRmse) {
  // Ground truth on the corners of squares in the z=0 plane; the estimate is lifted by +d where
  // x·y > 0 and −d elsewhere. This pattern is orthogonal to every rigid motion (its correlation
  // with x, y and the constant vanishes), so the best alignment is the identity and the ATE RMSE
  // is exactly d.
  const double d = 0.01;
  Trajectory gt, est;
  double t = 0;
  for (double r : {1.0, 2.0, 3.0}) {
    for (auto [x, y] : {std::pair{r, r}, {-r, r}, {-r, -r}, {r, -r}}) {
      gt.push_back(Pose(t, {x, y, 0}));
      est.push_back(Pose(t, {x, y, x * y > 0 ? d : -d}));
      t += 0.1;
    }
  }
  const AteResult ate = ComputeAte(gt, est);
  EXPECT_NEAR(ate.translation.rmse, d, 1e-12);
  EXPECT_NEAR(ate.translation.max, d, 1e-12);
  EXPECT_TRUE(ate.alignment.rotation.isApprox(Eigen::Matrix3d::Identity(), 1e-12));
}

TEST(Ate, AlignmentIsTheLeastSquaresOptimum) {
  const Trajectory gt = WavyTrajectory(300);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(1, 2, 3);
  Trajectory est = Transformed(gt, T);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.02);
  for (auto& p : est)
    p.T_world_camera.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  const AteResult ate = ComputeAte(gt, est);
  // The true inverse transform is a feasible alignment, so the optimum cannot be worse...
  double true_sq = 0;
  for (size_t k = 0; k < gt.size(); ++k) {
    true_sq +=
        (T.inverse() * est[k].T_world_camera.translation() - gt[k].T_world_camera.translation())
            .squaredNorm();
  }
  EXPECT_LE(ate.translation.rmse, std::sqrt(true_sq / gt.size()) + 1e-12);
  // ...and any perturbation of the optimum is worse.
  for (int axis = 0; axis < 3; ++axis) {
    double sq = 0;
    for (size_t k = 0; k < gt.size(); ++k) {
      const Eigen::Vector3d moved = ate.estimate_aligned[k] + 1e-4 * Eigen::Vector3d::Unit(axis);
      sq += (moved - gt[k].T_world_camera.translation()).squaredNorm();
    }
    EXPECT_GT(std::sqrt(sq / gt.size()), ate.translation.rmse);
  }
  // Noise of σ = 2 cm per axis: RMSE of the 3-D error ≈ 2·√3 cm.
  EXPECT_NEAR(ate.translation.rmse, 0.02 * std::sqrt(3.0), 0.004);
}

TEST(Ate, FewPosesAlignedOnTheirOwnLookBetterThanUnderTheFramesAlignment) {
  // 3,000 frames and every 200th of them as a keyframe, all with the same noise (σ = 3 mm per
  // axis) and in a frame moved by T. Aligned on its own, the 15-pose subset fits part of its
  // noise; under the frames' alignment it shows the noise the frames have.
  const Trajectory gt = WavyTrajectory(3000);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.3, 1, -0.2).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(-1, 0.5, 2);
  Trajectory frames = Transformed(gt, T);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.003);
  for (auto& p : frames)
    p.T_world_camera.translation() += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  Trajectory keyframes;
  for (size_t k = 0; k < frames.size(); k += 200) keyframes.push_back(frames[k]);
  ASSERT_EQ(keyframes.size(), 15u);

  const AteResult frame_ate = ComputeAte(gt, frames);
  const AteResult own = ComputeAte(gt, keyframes);
  const AteResult shared = ComputeAteUnderAlignment(gt, keyframes, frame_ate.alignment);
  ASSERT_EQ(shared.translation.count, 15u);
  // The shared alignment is the frames' own, and it is close to T's inverse.
  EXPECT_TRUE(shared.alignment.rotation.isApprox(frame_ate.alignment.rotation, 1e-15));
  EXPECT_TRUE(shared.alignment.rotation.isApprox(T.linear().transpose(), 1e-3));
  // Each keyframe's error under it is the frame's error at that time.
  for (size_t k = 0; k < keyframes.size(); ++k)
    EXPECT_NEAR(shared.errors[k], frame_ate.errors[200 * k], 1e-12);
  // Expected RMSE of the noise: 3·√3 = 5.2 mm. The frames show it; the keyframes aligned on
  // their own show less (six parameters fitted to 45 coordinates), under the frames' alignment
  // they do not.
  EXPECT_NEAR(frame_ate.translation.rmse, 0.003 * std::sqrt(3.0), 0.0003);
  EXPECT_LT(own.translation.rmse, shared.translation.rmse);
  // How much less, on average: a rigid alignment fitted to n noisy positions takes six of their
  // 3n degrees of freedom, E[own²] = (3n − 6)/(3n) · E[true²], 0.87 for 15 keyframes.
  double own_sq = 0, true_sq = 0;
  for (int trial = 0; trial < 400; ++trial) {
    Trajectory noisy = keyframes;
    for (size_t k = 0; k < noisy.size(); ++k) {
      noisy[k].T_world_camera.translation() = T * gt[200 * k].T_world_camera.translation() +
                                              Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    }
    own_sq += std::pow(ComputeAte(gt, noisy).translation.rmse, 2);
    true_sq +=
        std::pow(ComputeAteUnderAlignment(gt, noisy, frame_ate.alignment).translation.rmse, 2);
  }
  EXPECT_NEAR(own_sq / true_sq, (45.0 - 6.0) / 45.0, 0.03);
  // An alignment given is used as it is: the identity leaves T in the error.
  EXPECT_GT(ComputeAteUnderAlignment(gt, keyframes, Similarity{}).translation.rmse, 1.0);
}

TEST(Ate, Sim3RecoversScaleWhereSe3Cannot) {
  const Trajectory gt = WavyTrajectory(120);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(0.5, 0, 0);
  const Trajectory est = Transformed(gt, T, 0.5);
  AteOptions sim3;
  sim3.alignment = AlignmentMode::kSim3;
  const AteResult scaled = ComputeAte(gt, est, sim3);
  EXPECT_LT(scaled.translation.rmse, 1e-9);
  EXPECT_NEAR(scaled.alignment.scale, 2.0, 1e-9);
  EXPECT_GT(ComputeAte(gt, est).translation.rmse, 0.05);
}

TEST(Ate, AssociatesByTimestampWithinTolerance) {
  const Trajectory gt = WavyTrajectory(100);
  Trajectory est;
  // Every other pose, 5 ms late, plus poses that have no ground truth nearby.
  for (size_t k = 0; k < gt.size(); k += 2) {
    StampedPose p = gt[k];
    p.timestamp += 0.005;
    est.push_back(p);
  }
  est.push_back(Pose(gt.back().timestamp + 5.0, {9, 9, 9}));
  const AteResult ate = ComputeAte(gt, est);
  EXPECT_EQ(ate.translation.count, 50u);
  EXPECT_LT(ate.translation.rmse, 1e-9);
  AteOptions tight;
  tight.max_time_difference = 0.004;
  EXPECT_THROW(ComputeAte(gt, est, tight), Error);
  AteOptions shifted;
  shifted.time_offset = -0.005;
  shifted.max_time_difference = 0.001;
  EXPECT_EQ(ComputeAte(gt, est, shifted).translation.count, 50u);
}

TEST(Ate, NoOverlapNamesBothRangesAndTooFewMatchesIsAnError) {
  const Trajectory gt = WavyTrajectory(30, 100.0);
  const Trajectory est = WavyTrajectory(30, 200.0);
  try {
    ComputeAte(gt, est);
    FAIL();
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("[200.000000, 200.966667]"), std::string::npos) << m;
    EXPECT_NE(m.find("[100.000000, 100.966667]"), std::string::npos) << m;
  }
  const Trajectory two(gt.begin(), gt.begin() + 2);
  EXPECT_THROW(ComputeAte(gt, two), Error);
}

TEST(Rte, ScaleDriftGivesKnownTranslationError) {
  // Ground truth moves along x at 1 m/s; the estimate at 1.1 m/s. Over Δ = 1 s every pair's
  // relative translation is off by exactly 0.1 m, whatever the unit of Δ.
  Trajectory gt, est;
  for (int k = 0; k < 91; ++k) {
    const double t = k / 30.0;
    gt.push_back(Pose(t, {t, 0, 0}));
    est.push_back(Pose(t, {1.1 * t, 0, 0}));
  }
  RteOptions strict;
  strict.pairing = RtePairing::kStrict;
  const RteResult seconds = ComputeRte(gt, est, strict);
  EXPECT_EQ(seconds.translation.count, 61u);  // k = 0..60 have a partner 30 frames later
  EXPECT_NEAR(seconds.translation.rmse, 0.1, 1e-9);
  EXPECT_NEAR(seconds.translation.std, 0.0, 1e-9);
  EXPECT_NEAR(seconds.rotation.rmse, 0.0, 1e-9);
  RteOptions frames = strict;
  frames.unit = DeltaUnit::kFrames;
  frames.delta = 30;
  const RteResult by_frames = ComputeRte(gt, est, frames);
  EXPECT_EQ(by_frames.translation.count, 61u);
  EXPECT_NEAR(by_frames.translation.rmse, 0.1, 1e-9);
  // TUM's script never pairs with the last pose: k = 60 → 90 is left out, in both units.
  const RteResult tum = ComputeRte(gt, est);
  EXPECT_EQ(tum.translation.count, 60u);
  EXPECT_NEAR(tum.translation.rmse, 0.1, 1e-9);
  frames.pairing = RtePairing::kTum;
  EXPECT_EQ(ComputeRte(gt, est, frames).translation.count, 60u);
  RteOptions rescaled;
  rescaled.scale = 1.0 / 1.1;
  EXPECT_NEAR(ComputeRte(gt, est, rescaled).translation.rmse, 0.0, 1e-9);
}

TEST(Rte, RotationRateErrorGivesKnownAngleAndIgnoresGlobalFrame) {
  // A camera turning in place at 0.2 rad/s, estimated at 0.25 rad/s: 0.05 rad per second.
  Trajectory gt, est;
  for (int k = 0; k < 60; ++k) {
    const double t = k / 30.0;
    gt.push_back(Pose(t, {1, 2, 3},
                      Eigen::AngleAxisd(0.2 * t, Eigen::Vector3d::UnitY()).toRotationMatrix()));
    est.push_back(Pose(t, {1, 2, 3},
                       Eigen::AngleAxisd(0.25 * t, Eigen::Vector3d::UnitY()).toRotationMatrix()));
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(-7, 1, 0);
  RteOptions strict;
  strict.pairing = RtePairing::kStrict;
  const RteResult rte = ComputeRte(gt, Transformed(est, T), strict);
  EXPECT_EQ(rte.rotation.count, 30u);
  EXPECT_NEAR(rte.rotation.rmse, 0.05 * 180.0 / M_PI, 1e-9);
  EXPECT_NEAR(rte.translation.rmse, 0.0, 1e-9);
}

TEST(Rte, GapInTheEstimateDoesNotStretchDelta) {
  Trajectory gt, est;
  for (int k = 0; k < 150; ++k) {
    const double t = k / 30.0;
    gt.push_back(Pose(t, {t, 0, 0}));
    if (k < 30 || k >= 90) est.push_back(Pose(t, {t, 0, 0}));  // lost for 2 s
  }
  RteOptions strict;
  strict.pairing = RtePairing::kStrict;
  const RteResult rte = ComputeRte(gt, est, strict);
  // Pairs exist only within the second block (k = 90..119 → +30).
  EXPECT_EQ(rte.translation.count, 30u);
  for (double t : rte.timestamps) EXPECT_GE(t, 3.0 - 1e-9);
}

// Six estimate poses with uneven gaps, worked by hand (Δ = 1 s). Ground truth moves along x at
// 1 m/s, the estimate at 1.1 m/s, so a pair's error is 0.1 · (tⱼ − tᵢ).
//   TUM: t = 0 → 1.0, 0.5 → 1.5, 1.0 → 1.5 (closest to 2.0), 1.5 → 2.6; 2.6 and 3.0 would
//   pair with the last pose and are dropped. Errors 0.1, 0.1, 0.05, 0.11.
//   Strict (tolerance half the median interval, 0.25 s): 0 → 1.0, 0.5 → 1.5, 1.5 → 2.6.
TEST(Rte, PairsAsTheTumScriptDoesByDefaultAndStrictlyOnRequest) {
  Trajectory gt, est;
  for (int k = 0; k <= 400; ++k) gt.push_back(Pose(k / 100.0, {k / 100.0, 0, 0}));
  for (double t : {0.0, 0.5, 1.0, 1.5, 2.6, 3.0}) est.push_back(Pose(t, {1.1 * t, 0, 0}));
  const RteResult tum = ComputeRte(gt, est);
  ASSERT_EQ(tum.translation.count, 4u);
  EXPECT_NEAR(tum.translation.rmse, std::sqrt((0.01 + 0.01 + 0.0025 + 0.0121) / 4), 1e-9);
  EXPECT_EQ(tum.timestamps, (std::vector<double>{0.0, 0.5, 1.0, 1.5}));
  RteOptions strict;
  strict.pairing = RtePairing::kStrict;
  const RteResult s = ComputeRte(gt, est, strict);
  ASSERT_EQ(s.translation.count, 3u);
  EXPECT_NEAR(s.translation.rmse, std::sqrt((0.01 + 0.01 + 0.0121) / 3), 1e-9);
  EXPECT_EQ(ParseRtePairing("strict"), RtePairing::kStrict);
  EXPECT_THROW(ParseRtePairing("nearest"), Error);
}

// TUM: a pair whose ground truth lies more than twice the median ground-truth interval from
// either end is dropped (the mocap lost the marker).
TEST(Rte, TumPairingDropsPairsWithoutGroundTruthNearby) {
  Trajectory gt, est;
  for (int k = 0; k < 300; ++k) {
    const double t = k / 100.0;
    if (t < 1.2 || t > 1.6) gt.push_back(Pose(t, {t, 0, 0}));  // no ground truth 1.2–1.6 s
  }
  for (int k = 0; k < 90; ++k) est.push_back(Pose(k / 30.0, {k / 30.0, 0, 0}));
  const RteResult r = ComputeRte(gt, est);
  for (double t : r.timestamps) {
    EXPECT_FALSE(t > 1.22 && t < 1.58) << t;          // start without ground truth
    EXPECT_FALSE(t + 1 > 1.22 && t + 1 < 1.58) << t;  // end without ground truth
  }
  EXPECT_GT(r.translation.count, 20u);
  // Each end takes the nearest ground truth, no interpolation (as the script): within 2 cm here.
  EXPECT_LT(r.translation.max, 0.02 + 1e-9);
}

TEST(Rte, BadOptionsAndTooShortRuns) {
  const Trajectory gt = WavyTrajectory(20);
  EXPECT_THROW(ComputeRte(gt, gt), Error);  // 0.63 s of data, Δ = 1 s
  RteOptions bad;
  bad.delta = -1;
  EXPECT_THROW(ComputeRte(gt, gt, bad), Error);
  bad.delta = 1.5;
  bad.unit = DeltaUnit::kFrames;
  EXPECT_THROW(ComputeRte(gt, gt, bad), Error);
  EXPECT_THROW(ParseDeltaUnit("m"), Error);
  EXPECT_THROW(ParseAlignmentMode("affine"), Error);
}

// A delta in frames beyond size_t (1e20) was converted to an index as is (undefined; it gave 0):
// RTE 0.0000 over pairs of a pose with itself, exit 0. A delta longer than the trajectory is an
// error naming --delta, in both pairings, however long.
TEST(Rte, ADeltaLongerThanTheTrajectoryIsAnErrorNamingIt) {
  const Trajectory gt = WavyTrajectory(10);
  for (RtePairing pairing : {RtePairing::kTum, RtePairing::kStrict}) {
    for (double delta : {10.0, 1e6, 1e20, 1e300}) {
      RteOptions options;
      options.unit = DeltaUnit::kFrames;
      options.pairing = pairing;
      options.delta = delta;
      std::string message = "(no error)";
      try {
        ComputeRte(gt, gt, options);
      } catch (const Error& e) {
        message = e.what();
      }
      EXPECT_EQ(message.find("RTE delta (--delta) "), 0u)
          << ToString(pairing) << " " << delta << ": " << message;
      EXPECT_NE(message.find("no pose pairs that far apart; the trajectory has 10 poses"),
                std::string::npos)
          << message;
    }
    RteOptions seconds;
    seconds.pairing = pairing;
    seconds.delta = 1e300;
    EXPECT_THROW(ComputeRte(gt, gt, seconds), Error);
    // The longest delta that fits still pairs: the strict pairing takes 0 -> 9, TUM's script
    // never pairs with the last pose, so one less.
    RteOptions longest;
    longest.unit = DeltaUnit::kFrames;
    longest.pairing = pairing;
    longest.delta = pairing == RtePairing::kStrict ? 9 : 8;
    EXPECT_EQ(ComputeRte(gt, gt, longest).translation.count, 1u) << ToString(pairing);
  }
}

}  // namespace
}  // namespace sdoslam
