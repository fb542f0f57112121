#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sdoslam/io/trajectory.h"

namespace sdoslam {

// Summary of a set of errors, as the TUM benchmark tools print them.
struct ErrorStats {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0;  // std: population
  size_t count = 0;
};
ErrorStats ComputeErrorStats(const std::vector<double>& errors);

enum class AlignmentMode {
  kSE3,   // rotation + translation (RGB-D, stereo): the paper's and TUM's choice
  kSim3,  // + scale (monocular)
  kNone,  // compare in the estimate's own frame
};
AlignmentMode ParseAlignmentMode(const std::string& name);  // se3 | sim3 | none
std::string ToString(AlignmentMode mode);

// p_gt ≈ scale · R · p_est + t
struct Similarity {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d Apply(const Eigen::Vector3d& p) const {
    return scale * rotation * p + translation;
  }
};

// Closed-form least-squares alignment of corresponding positions (Umeyama 1991; without scale it
// equals Horn's method used by the TUM tools). Needs at least 3 points.
Similarity AlignPositions(const std::vector<Eigen::Vector3d>& estimate,
                          const std::vector<Eigen::Vector3d>& ground_truth, AlignmentMode mode);

struct AteOptions {
  double max_time_difference = 0.02;  // seconds, for associating estimate and ground truth
  double time_offset = 0.0;           // added to the estimate's timestamps
  AlignmentMode alignment = AlignmentMode::kSE3;
  void Check() const;
};

// Estimate and ground truth associated by timestamp: indices into each, in time order.
struct TrajectoryMatch {
  std::vector<size_t> estimate_index;
  std::vector<size_t> ground_truth_index;
  size_t size() const { return estimate_index.size(); }
};
// Throws Error when no timestamps overlap (naming both time ranges) or fewer than 3 match.
TrajectoryMatch MatchTrajectories(const Trajectory& ground_truth, const Trajectory& estimate,
                                  double max_time_difference, double time_offset);

struct AteResult {
  ErrorStats translation;  // metres
  Similarity alignment;
  TrajectoryMatch match;
  std::vector<double> timestamps;                 // ground-truth time of each match
  std::vector<Eigen::Vector3d> ground_truth;      // matched positions
  std::vector<Eigen::Vector3d> estimate_aligned;  // matched, after alignment
  std::vector<double> errors;                     // per match, metres
};

// Absolute trajectory error (Sturm et al. 2012): RMSE etc. of ‖S·p̂ₖ − pₖ‖ after alignment.
AteResult ComputeAte(const Trajectory& ground_truth, const Trajectory& estimate,
                     const AteOptions& options = {});

// ATE under an alignment found elsewhere (options.alignment is not used). A run's keyframes are
// compared with its frames this way, under the frames' alignment: a dozen keyframes aligned on
// their own spend the alignment's six degrees of freedom on their own noise and look better than
// they are, next to thousands of frames for which the same fit costs nothing.
AteResult ComputeAteUnderAlignment(const Trajectory& ground_truth, const Trajectory& estimate,
                                   const Similarity& alignment, const AteOptions& options = {});

enum class DeltaUnit { kFrames, kSeconds };
DeltaUnit ParseDeltaUnit(const std::string& name);  // frames | f | s | seconds

// How RTE pairs poses Δ apart.
enum class RtePairing {
  // As TUM's evaluate_rpe.py --fixed_delta, whose numbers papers report: every estimate pose i
  // is paired with the estimate pose closest to tᵢ + Δ (frames: index i + Δ), whatever the gap,
  // unless that is the last pose; each end takes the ground-truth pose closest in time, and a
  // pair is dropped when either is more than twice the median ground-truth interval away.
  kTum,
  // Only matched poses (max_time_difference), and a partner only within half the median frame
  // interval of tᵢ + Δ: a gap in the estimate never stretches or shrinks Δ.
  kStrict,
};
RtePairing ParseRtePairing(const std::string& name);  // tum | strict
const char* ToString(RtePairing pairing);

struct RteOptions {
  double delta = 1.0;  // the paper uses one second
  DeltaUnit unit = DeltaUnit::kSeconds;
  RtePairing pairing = RtePairing::kTum;
  double max_time_difference = 0.02;
  double time_offset = 0.0;
  double scale = 1.0;  // applied to the estimate's relative translations (from a sim3 alignment)
  void Check() const;
};

struct RteResult {
  ErrorStats translation;          // metres
  ErrorStats rotation;             // degrees
  std::vector<double> timestamps;  // estimate time of each pair's start
  std::vector<double> translation_errors, rotation_errors_deg;
};

// Relative pose error over a fixed interval Δ (TUM evaluate_rpe with a fixed delta, the paper's
// eq. 12): for each pose k with a partner k+Δ (options.pairing), E = (T̂ₖ⁻¹T̂ₖ₊Δ)⁻¹(Tₖ⁻¹Tₖ₊Δ);
// statistics of ‖trans(E)‖ and of the rotation angle of E. All pairs are used (the TUM script
// samples 10,000 at random when there are more). Throws Error when no pair exists.
RteResult ComputeRte(const Trajectory& ground_truth, const Trajectory& estimate,
                     const RteOptions& options = {});

}  // namespace sdoslam
