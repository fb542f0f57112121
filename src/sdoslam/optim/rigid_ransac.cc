#include "sdoslam/optim/rigid_ransac.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>

#include "sdoslam/core/error.h"
#include "sdoslam/optim/ransac.h"

namespace sdoslam {
namespace {

// A minimal set whose triangle is lower than this fraction of its longest side is taken as
// collinear: the rotation about that side would be fixed by noise alone.
constexpr double kMinHeightRatio = 0.1;
// The same for the final inlier set: its spread across the main direction against along it
// (square roots of the covariance's two largest eigenvalues).
constexpr double kMinSpreadRatio = 0.05;
// Rounds of refitting on the inliers and reclassifying; the set settles in one or two.
constexpr int kMaxRefits = 5;

// Too close to a line (or to a point) to fix a rotation, at the scale of the noise too: a
// triangle lower than the smallest inlier threshold has its third point within the noise of
// the line through the other two.
bool Collinear(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
               double min_height) {
  const double longest = std::max({(p1 - p0).norm(), (p2 - p0).norm(), (p2 - p1).norm()});
  if (!(longest > 0)) return true;
  const double height = (p1 - p0).cross(p2 - p0).norm() / longest;
  return !(height >= kMinHeightRatio * longest && height >= min_height);
}

Eigen::Isometry3d Fit(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                      const std::vector<int>& indices) {
  Eigen::Matrix3Xd src(3, indices.size()), dst(3, indices.size());
  for (size_t k = 0; k < indices.size(); ++k) {
    src.col(static_cast<Eigen::Index>(k)) = a[static_cast<size_t>(indices[k])];
    dst.col(static_cast<Eigen::Index>(k)) = b[static_cast<size_t>(indices[k])];
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = Eigen::umeyama(src, dst, /*with_scaling=*/false);
  return T;
}

struct Consensus {
  int count = 0;
  // MSAC cost Σ min((e/threshold)², 1): breaks ties between equal counts in favour of the
  // tighter fit.
  double cost = std::numeric_limits<double>::infinity();
};

Consensus Score(const Eigen::Isometry3d& T, const std::vector<Eigen::Vector3d>& a,
                const std::vector<Eigen::Vector3d>& b, const std::vector<double>& threshold,
                std::vector<bool>* inlier) {
  Consensus c;
  c.cost = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double e = (T * a[i] - b[i]).norm();
    const bool in = e < threshold[i];
    if (inlier != nullptr) (*inlier)[i] = in;
    c.count += in;
    c.cost += in ? (e / threshold[i]) * (e / threshold[i]) : 1.0;
  }
  return c;
}

bool Better(const Consensus& x, const Consensus& y) {
  return x.count > y.count || (x.count == y.count && x.cost < y.cost);
}

// Samples needed to draw one all-inlier minimal set with probability `confidence` when a
// fraction `w` of the matches are inliers.
int AdaptiveIterations(double w, double confidence, int max_iterations) {
  const double all_inlier = w * w * w;
  if (all_inlier >= 1.0) return 1;
  if (all_inlier <= 0.0) return max_iterations;
  const double n = std::ceil(std::log(1.0 - confidence) / std::log(1.0 - all_inlier));
  return n >= max_iterations ? max_iterations : std::max(1, static_cast<int>(n));
}

// Whether the inlier points of `a` spread across a line: with all of them on one, the rotation
// about it is not determined.
bool SpreadAcrossALine(const std::vector<Eigen::Vector3d>& a, const std::vector<int>& indices) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int i : indices) mean += a[static_cast<size_t>(i)];
  mean /= static_cast<double>(indices.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (int i : indices) {
    const Eigen::Vector3d d = a[static_cast<size_t>(i)] - mean;
    covariance += d * d.transpose();
  }
  // Eigenvalues in increasing order.
  const Eigen::Vector3d eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance, Eigen::EigenvaluesOnly)
          .eigenvalues();
  return std::sqrt(std::max(0.0, eigenvalues(1))) >=
         kMinSpreadRatio * std::sqrt(std::max(0.0, eigenvalues(2)));
}

std::vector<int> Indices(const std::vector<bool>& inlier) {
  std::vector<int> indices;
  for (size_t i = 0; i < inlier.size(); ++i)
    if (inlier[i]) indices.push_back(static_cast<int>(i));
  return indices;
}

// The RANSAC problem (ransac.h): minimal sets of 3 matches, fitted by Umeyama's method, scored by
// inlier count with the MSAC cost as tie-break, the number of samples adapted to the best
// inlier ratio.
class RigidProblem {
 public:
  using Model = Eigen::Isometry3d;
  using Score = Consensus;

  RigidProblem(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
               const std::vector<double>& threshold, const RigidRansacOptions& options)
      : a_(a), b_(b), threshold_(threshold), options_(options), rng_(options.seed) {}

  std::optional<Model> Hypothesis() {
    std::vector<int> sample(3);
    sample[0] = Draw();
    do sample[1] = Draw();
    while (sample[1] == sample[0]);
    do sample[2] = Draw();
    while (sample[2] == sample[0] || sample[2] == sample[1]);
    const auto& a0 = a_[static_cast<size_t>(sample[0])];
    const auto& a1 = a_[static_cast<size_t>(sample[1])];
    const auto& a2 = a_[static_cast<size_t>(sample[2])];
    const auto& b0 = b_[static_cast<size_t>(sample[0])];
    const auto& b1 = b_[static_cast<size_t>(sample[1])];
    const auto& b2 = b_[static_cast<size_t>(sample[2])];
    if (Collinear(a0, a1, a2, options_.inlier_base) || Collinear(b0, b1, b2, options_.inlier_base))
      return std::nullopt;
    // A rigid motion keeps distances: a pair whose distances differ by more than both
    // thresholds together cannot be two inliers, and the fit would be wasted.
    for (int p = 0; p < 3; ++p) {
      const size_t i = static_cast<size_t>(sample[static_cast<size_t>(p)]);
      const size_t j = static_cast<size_t>(sample[static_cast<size_t>((p + 1) % 3)]);
      if (std::abs((a_[i] - a_[j]).norm() - (b_[i] - b_[j]).norm()) > threshold_[i] + threshold_[j])
        return std::nullopt;
    }
    return Fit(a_, b_, sample);
  }
  Score Evaluate(const Model& T) const { return sdoslam::Score(T, a_, b_, threshold_, nullptr); }
  static bool Better(const Consensus& x, const Consensus& y) { return sdoslam::Better(x, y); }
  static void Improve(Model*, Score*) {}
  int Iterations(const Consensus& best) const {
    return AdaptiveIterations(static_cast<double>(best.count) / static_cast<double>(a_.size()),
                              options_.confidence, options_.max_iterations);
  }
  static Consensus Worst() { return {}; }

 private:
  // mt19937 is specified to the bit and the indices are taken from its raw output (not through a
  // distribution, whose algorithm the standard leaves open), so the samples are the same on
  // every platform.
  int Draw() { return static_cast<int>(rng_() % a_.size()); }

  const std::vector<Eigen::Vector3d>& a_;
  const std::vector<Eigen::Vector3d>& b_;
  const std::vector<double>& threshold_;
  const RigidRansacOptions& options_;
  std::mt19937 rng_;
};

}  // namespace

void RigidRansacOptions::Check(const std::string& path) const {
  if (max_iterations < 1) throw Error(path + "max_iterations must be >= 1");
  if (!(confidence > 0 && confidence < 1)) throw Error(path + "confidence must be in (0, 1)");
  if (!(inlier_base > 0 && std::isfinite(inlier_base)))
    throw Error(path + "inlier_base must be > 0 (metres)");
  if (!(inlier_per_depth2 >= 0 && std::isfinite(inlier_per_depth2)))
    throw Error(path + "inlier_per_depth2 must be >= 0 (1/metres)");
  if (min_inliers < 3) throw Error(path + "min_inliers must be >= 3");
}

RigidRansacResult EstimateRigidTransformRansac(const std::vector<Eigen::Vector3d>& a,
                                               const std::vector<Eigen::Vector3d>& b,
                                               const RigidRansacOptions& options) {
  options.Check();
  if (a.size() != b.size()) {
    throw Error("EstimateRigidTransformRansac: " + std::to_string(a.size()) + " points in A but " +
                std::to_string(b.size()) + " in B; they must be matched one to one");
  }
  const size_t n = a.size();
  RigidRansacResult result;
  result.inlier.assign(n, false);
  if (n < 3) return result;

  std::vector<double> threshold(n);
  for (size_t i = 0; i < n; ++i)
    threshold[i] = options.inlier_base + options.inlier_per_depth2 * b[i].z() * b[i].z();

  RigidProblem problem(a, b, threshold, options);
  const RansacOutcome<Eigen::Isometry3d, Consensus> outcome = Ransac(problem);
  result.iterations = outcome.iterations;
  if (!outcome.model || outcome.score.count < 3) return result;
  const Eigen::Isometry3d& best_T = *outcome.model;

  // Refit on all inliers; the first refit is always taken (a least-squares fit on the whole
  // consensus beats one on 3 of its points), later ones only while they keep the inliers.
  std::vector<bool> inlier(n, false);
  Consensus current = Score(best_T, a, b, threshold, &inlier);
  Eigen::Isometry3d T = best_T;
  for (int round = 0; round < kMaxRefits; ++round) {
    const std::vector<int> indices = Indices(inlier);
    if (indices.size() < 3) break;
    const Eigen::Isometry3d refit = Fit(a, b, indices);
    std::vector<bool> refit_inlier(n, false);
    const Consensus c = Score(refit, a, b, threshold, &refit_inlier);
    if (round > 0 && c.count < current.count) break;
    const bool changed = refit_inlier != inlier;
    T = refit;
    current = c;
    inlier.swap(refit_inlier);
    if (!changed) break;
  }
  const std::vector<int> indices = Indices(inlier);
  if (current.count < options.min_inliers || !SpreadAcrossALine(a, indices)) return result;
  result.found = true;
  result.T_b_a = T;
  result.inlier = std::move(inlier);
  result.num_inliers = current.count;
  return result;
}

}  // namespace sdoslam
