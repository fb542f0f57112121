#include "sdoslam/eval/metrics.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <optional>

#include "sdoslam/core/error.h"
#include "sdoslam/core/timestamps.h"

namespace sdoslam {
namespace {

std::string TimeRange(const Trajectory& t) {
  if (t.empty()) return "(empty)";
  char buffer[96];
  std::snprintf(buffer, sizeof(buffer), "[%.6f, %.6f]", t.front().timestamp, t.back().timestamp);
  return buffer;
}

}  // namespace

ErrorStats ComputeErrorStats(const std::vector<double>& errors) {
  ErrorStats s;
  s.count = errors.size();
  if (errors.empty()) return s;
  const double n = static_cast<double>(errors.size());
  double sum = 0, sum_sq = 0;
  for (double e : errors) {
    sum += e;
    sum_sq += e * e;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double var = 0;
  for (double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  s.min = sorted.front();
  s.max = sorted.back();
  const size_t mid = sorted.size() / 2;
  s.median = sorted.size() % 2 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  return s;
}

AlignmentMode ParseAlignmentMode(const std::string& name) {
  if (name == "se3") return AlignmentMode::kSE3;
  if (name == "sim3") return AlignmentMode::kSim3;
  if (name == "none") return AlignmentMode::kNone;
  throw Error("unknown alignment '" + name + "' (use se3, sim3 or none)");
}

std::string ToString(AlignmentMode mode) {
  switch (mode) {
    case AlignmentMode::kSE3:
      return "se3";
    case AlignmentMode::kSim3:
      return "sim3";
    case AlignmentMode::kNone:
      return "none";
  }
  return "?";
}

Similarity AlignPositions(const std::vector<Eigen::Vector3d>& estimate,
                          const std::vector<Eigen::Vector3d>& ground_truth, AlignmentMode mode) {
  if (estimate.size() != ground_truth.size() || estimate.size() < 3) {
    throw Error("alignment needs at least 3 corresponding positions");
  }
  Similarity s;
  if (mode == AlignmentMode::kNone) return s;
  Eigen::Matrix3Xd src(3, estimate.size()), dst(3, estimate.size());
  for (size_t k = 0; k < estimate.size(); ++k) {
    src.col(k) = estimate[k];
    dst.col(k) = ground_truth[k];
  }
  const Eigen::Matrix4d T = Eigen::umeyama(src, dst, mode == AlignmentMode::kSim3);
  s.scale = T.block<3, 1>(0, 0).norm();
  s.rotation = T.block<3, 3>(0, 0) / s.scale;
  s.translation = T.block<3, 1>(0, 3);
  if (mode == AlignmentMode::kSE3) s.scale = 1.0;
  return s;
}

void AteOptions::Check() const {
  if (!(max_time_difference > 0) || !std::isfinite(max_time_difference)) {
    throw Error("max_time_difference must be positive");
  }
  if (!std::isfinite(time_offset)) throw Error("time_offset must be finite");
}

TrajectoryMatch MatchTrajectories(const Trajectory& ground_truth, const Trajectory& estimate,
                                  double max_time_difference, double time_offset) {
  std::vector<double> gt_times, est_times;
  for (const auto& p : ground_truth) gt_times.push_back(p.timestamp);
  for (const auto& p : estimate) est_times.push_back(p.timestamp);
  TrajectoryMatch match;
  for (const auto& [gt, est] :
       AssociateTimestamps(gt_times, est_times, max_time_difference, time_offset)) {
    match.ground_truth_index.push_back(gt);
    match.estimate_index.push_back(est);
  }
  if (match.size() == 0) {
    throw Error("no timestamps of the estimate " + TimeRange(estimate) + " lie within " +
                std::to_string(max_time_difference) + " s of the ground truth " +
                TimeRange(ground_truth) + " (wrong files, or a time offset?)");
  }
  if (match.size() < 3) {
    throw Error("only " + std::to_string(match.size()) +
                " poses of the estimate match the ground truth in time; at least 3 are needed");
  }
  return match;
}

namespace {

// Matches the estimate to the ground truth; aligns it with `alignment`, or, without one, with
// the least-squares alignment of options.alignment's kind.
AteResult ComputeAteWith(const Trajectory& ground_truth, const Trajectory& estimate,
                         const std::optional<Similarity>& alignment, const AteOptions& options) {
  options.Check();
  AteResult result;
  result.match =
      MatchTrajectories(ground_truth, estimate, options.max_time_difference, options.time_offset);
  std::vector<Eigen::Vector3d> est;
  for (size_t k = 0; k < result.match.size(); ++k) {
    const StampedPose& gt = ground_truth[result.match.ground_truth_index[k]];
    result.timestamps.push_back(gt.timestamp);
    result.ground_truth.push_back(gt.T_world_camera.translation());
    est.push_back(estimate[result.match.estimate_index[k]].T_world_camera.translation());
  }
  result.alignment =
      alignment ? *alignment : AlignPositions(est, result.ground_truth, options.alignment);
  for (size_t k = 0; k < est.size(); ++k) {
    result.estimate_aligned.push_back(result.alignment.Apply(est[k]));
    result.errors.push_back((result.estimate_aligned[k] - result.ground_truth[k]).norm());
  }
  result.translation = ComputeErrorStats(result.errors);
  return result;
}

}  // namespace

AteResult ComputeAte(const Trajectory& ground_truth, const Trajectory& estimate,
                     const AteOptions& options) {
  return ComputeAteWith(ground_truth, estimate, std::nullopt, options);
}

AteResult ComputeAteUnderAlignment(const Trajectory& ground_truth, const Trajectory& estimate,
                                   const Similarity& alignment, const AteOptions& options) {
  return ComputeAteWith(ground_truth, estimate, alignment, options);
}

DeltaUnit ParseDeltaUnit(const std::string& name) {
  if (name == "frames" || name == "f") return DeltaUnit::kFrames;
  if (name == "s" || name == "seconds") return DeltaUnit::kSeconds;
  throw Error("unknown delta unit '" + name + "' (use frames or s)");
}

RtePairing ParseRtePairing(const std::string& name) {
  if (name == "tum") return RtePairing::kTum;
  if (name == "strict") return RtePairing::kStrict;
  throw Error("unknown RTE pairing '" + name + "' (use tum or strict)");
}

const char* ToString(RtePairing pairing) { return pairing == RtePairing::kTum ? "tum" : "strict"; }

namespace {

// Index of the value in sorted `values` closest to `target` (the earlier one on a tie).
size_t ClosestIndex(const std::vector<double>& values, double target) {
  const size_t hi =
      static_cast<size_t>(std::lower_bound(values.begin(), values.end(), target) - values.begin());
  if (hi == values.size()) return hi - 1;
  if (hi > 0 && target - values[hi - 1] <= values[hi] - target) return hi - 1;
  return hi;
}

// Pairs as TUM's evaluate_rpe.py --fixed_delta forms them: {estimate i, estimate j,
// ground truth i, ground truth j}.
std::vector<std::array<size_t, 4>> PairAsTum(const Trajectory& ground_truth,
                                             const Trajectory& estimate,
                                             const RteOptions& options) {
  std::vector<std::array<size_t, 4>> out;
  const size_t n = estimate.size();
  std::vector<double> est_times(n), gt_times(ground_truth.size()), gt_intervals;
  for (size_t k = 0; k < n; ++k) est_times[k] = estimate[k].timestamp;
  for (size_t k = 0; k < ground_truth.size(); ++k) gt_times[k] = ground_truth[k].timestamp;
  for (size_t k = 1; k < gt_times.size(); ++k)
    gt_intervals.push_back(gt_times[k] - gt_times[k - 1]);
  if (n < 2 || gt_intervals.empty()) return out;
  const double gt_tolerance = 2 * ComputeErrorStats(gt_intervals).median;
  for (size_t i = 0; i < n; ++i) {
    size_t j = 0;
    if (options.unit == DeltaUnit::kFrames) {
      // Compared as doubles: converting a delta beyond size_t (1e20) is undefined, and gave 0.
      j = options.delta >= static_cast<double>(n - 1 - i) ? n - 1
                                                          : i + static_cast<size_t>(options.delta);
    } else {
      j = ClosestIndex(est_times, est_times[i] + options.delta);
    }
    if (j == n - 1) continue;  // the script never pairs with the last pose
    const double ti = est_times[i] + options.time_offset, tj = est_times[j] + options.time_offset;
    const size_t gi = ClosestIndex(gt_times, ti), gj = ClosestIndex(gt_times, tj);
    if (std::abs(gt_times[gi] - ti) > gt_tolerance || std::abs(gt_times[gj] - tj) > gt_tolerance)
      continue;
    out.push_back({i, j, gi, gj});
  }
  return out;
}

// The strict pairing over matched poses (indices into `match`).
std::vector<std::pair<size_t, size_t>> StrictPairs(const TrajectoryMatch& match,
                                                   const Trajectory& estimate,
                                                   const RteOptions& options) {
  const size_t n = match.size();
  auto est_pose = [&](size_t k) { return estimate[match.estimate_index[k]]; };
  std::vector<std::pair<size_t, size_t>> pairs;
  if (options.unit == DeltaUnit::kFrames) {
    if (options.delta >= static_cast<double>(n)) return pairs;  // as PairAsTum: no size_t cast
    const size_t delta = static_cast<size_t>(options.delta);
    for (size_t i = 0; i + delta < n; ++i) pairs.emplace_back(i, i + delta);
  } else {
    std::vector<double> times(n), intervals;
    for (size_t k = 0; k < n; ++k) times[k] = est_pose(k).timestamp;
    for (size_t k = 1; k < n; ++k) intervals.push_back(times[k] - times[k - 1]);
    const double tolerance = 0.5 * ComputeErrorStats(intervals).median + 1e-9;
    for (size_t i = 0; i < n; ++i) {
      const double target = times[i] + options.delta;
      const size_t hi =
          static_cast<size_t>(std::lower_bound(times.begin(), times.end(), target) - times.begin());
      size_t j = hi;
      if (hi == n || (hi > 0 && target - times[hi - 1] < times[hi] - target)) j = hi - 1;
      if (j > i && std::abs(times[j] - target) <= tolerance) pairs.emplace_back(i, j);
    }
  }
  return pairs;
}

}  // namespace

void RteOptions::Check() const {
  if (!(delta > 0) || !std::isfinite(delta)) throw Error("delta must be positive");
  if (unit == DeltaUnit::kFrames && delta != std::floor(delta)) {
    throw Error("delta in frames must be a whole number");
  }
  if (!(scale > 0) || !std::isfinite(scale)) throw Error("scale must be positive");
  AteOptions{max_time_difference, time_offset, AlignmentMode::kSE3}.Check();
}

RteResult ComputeRte(const Trajectory& ground_truth, const Trajectory& estimate,
                     const RteOptions& options) {
  options.Check();
  // Overlap and at least three matches are required in both pairings: a trajectory that does
  // not overlap the ground truth is an error, not an empty result.
  const TrajectoryMatch match =
      MatchTrajectories(ground_truth, estimate, options.max_time_difference, options.time_offset);
  // Pairs as indices into `estimate` and `ground_truth`: start and end of each.
  std::vector<std::array<size_t, 4>> pairs;
  if (options.pairing == RtePairing::kTum) {
    pairs = PairAsTum(ground_truth, estimate, options);
  } else {
    for (const auto& [i, j] : StrictPairs(match, estimate, options)) {
      pairs.push_back({match.estimate_index[i], match.estimate_index[j],
                       match.ground_truth_index[i], match.ground_truth_index[j]});
    }
  }
  if (pairs.empty()) {
    throw Error(fmt::format(
        "RTE delta (--delta) {:g} {}: no pose pairs that far apart; the trajectory has {} poses "
        "over {:.3f} s, too short for this delta",
        options.delta, options.unit == DeltaUnit::kFrames ? "frames" : "s", estimate.size(),
        estimate.empty() ? 0.0 : estimate.back().timestamp - estimate.front().timestamp));
  }

  RteResult result;
  for (const auto& [ei, ej, gi, gj] : pairs) {
    Eigen::Isometry3d est_motion =
        estimate[ei].T_world_camera.inverse() * estimate[ej].T_world_camera;
    est_motion.translation() *= options.scale;
    const Eigen::Isometry3d gt_motion =
        ground_truth[gi].T_world_camera.inverse() * ground_truth[gj].T_world_camera;
    const Eigen::Isometry3d error = est_motion.inverse() * gt_motion;
    result.timestamps.push_back(estimate[ei].timestamp);
    result.translation_errors.push_back(error.translation().norm());
    // AngleAxis is accurate for small angles, where arccos((tr R − 1)/2) loses digits.
    result.rotation_errors_deg.push_back(Eigen::AngleAxisd(error.rotation()).angle() * 180.0 /
                                         M_PI);
  }
  result.translation = ComputeErrorStats(result.translation_errors);
  result.rotation = ComputeErrorStats(result.rotation_errors_deg);
  return result;
}

}  // namespace sdoslam
