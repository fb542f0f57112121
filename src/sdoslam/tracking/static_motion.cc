#include "sdoslam/tracking/static_motion.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <random>

#include "sdoslam/core/error.h"
#include "sdoslam/optim/optimizer.h"
#include "sdoslam/optim/ransac.h"

namespace sdoslam {

void StaticMotionOptions::Check(const std::string& path) const {
  if (grid_columns < 2 || grid_rows < 2)
    throw Error(path + "grid_columns and " + path + "grid_rows must be >= 2");
  if (!(min_corner_strength >= 0)) throw Error(path + "min_corner_strength must be >= 0");
  if (hypotheses < 1) throw Error(path + "hypotheses must be >= 1");
  if (!(inlier_px > 0)) throw Error(path + "inlier_px must be positive");
  if (!(min_gain >= 0)) throw Error(path + "min_gain must be >= 0");
  if (min_extra_samples < 0) throw Error(path + "min_extra_samples must be >= 0");
  if (!(min_shift_px >= 0)) throw Error(path + "min_shift_px must be >= 0");
  if (min_correspondences < 3) throw Error(path + "min_correspondences must be >= 3");
}

namespace {

bool IsInlier(const PinholeIntrinsics& k, const MotionCorrespondence& m, const Eigen::Isometry3d& T,
              double limit2) {
  const Eigen::Vector3d p = T * m.past_world;
  if (p.z() <= 1e-6) return false;
  const Eigen::Vector2d uv(k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy);
  return (uv - m.current_pixel).squaredNorm() <= limit2;
}

// How far `T` moves the correspondences' projections from where `rough` puts them: the median
// over the correspondences, in px.
double MedianShiftPx(const PinholeIntrinsics& k, const std::vector<MotionCorrespondence>& matches,
                     const Eigen::Isometry3d& T, const Eigen::Isometry3d& rough) {
  std::vector<double> shifts;
  for (const MotionCorrespondence& m : matches) {
    const Eigen::Vector3d a = T * m.past_world, b = rough * m.past_world;
    if (a.z() <= 1e-6 || b.z() <= 1e-6) continue;
    shifts.push_back(
        std::hypot(k.fx * (a.x() / a.z() - b.x() / b.z()), k.fy * (a.y() / a.z() - b.y() / b.z())));
  }
  if (shifts.empty()) return 0;
  const auto middle = shifts.begin() + static_cast<std::ptrdiff_t>(shifts.size() / 2);
  std::nth_element(shifts.begin(), middle, shifts.end());
  return *middle;
}

// The rigid motion of all inliers of T (3-D–3-D, closed form), or T when too few.
Eigen::Isometry3d FitToInliers(const StaticMotionOptions& options, const PinholeIntrinsics& k,
                               const std::vector<MotionCorrespondence>& matches,
                               const Eigen::Isometry3d& T) {
  const double limit2 = options.inlier_px * options.inlier_px;
  std::vector<size_t> inliers;
  for (size_t j = 0; j < matches.size(); ++j) {
    if (IsInlier(k, matches[j], T, limit2)) inliers.push_back(j);
  }
  if (inliers.size() < 4) return T;
  Eigen::Matrix3Xd from(3, static_cast<Eigen::Index>(inliers.size())), to(3, from.cols());
  for (size_t c = 0; c < inliers.size(); ++c) {
    from.col(static_cast<Eigen::Index>(c)) = matches[inliers[c]].past_world;
    to.col(static_cast<Eigen::Index>(c)) = matches[inliers[c]].current_camera;
  }
  return Eigen::Isometry3d(Eigen::umeyama(from, to, false));
}

}  // namespace

std::vector<cv::Point2f> GridCorners(const StaticMotionOptions& options, const cv::Mat& gray,
                                     const cv::Mat& depth, const cv::Mat& half_gray) {
  CV_Assert(gray.type() == CV_8UC1 && depth.type() == CV_32FC1 && gray.size() == depth.size());
  cv::Mat strength;
  const int step = options.half_resolution_corners ? 2 : 1;
  if (step == 2) {
    cv::Mat half = half_gray;
    if (half.empty()) {
      cv::pyrDown(gray, half);
    } else {
      CV_Assert(half.type() == CV_8UC1 &&
                half.size() == cv::Size((gray.cols + 1) / 2, (gray.rows + 1) / 2));
    }
    cv::cornerMinEigenVal(half, strength, 3, 3);
  } else {
    cv::cornerMinEigenVal(gray, strength, 5, 3);
  }
  CV_Assert(strength.type() == CV_32FC1);
  std::vector<cv::Point2f> samples;
  for (int gy = 0; gy < options.grid_rows; ++gy) {
    for (int gx = 0; gx < options.grid_columns; ++gx) {
      const int x0 = gx * strength.cols / options.grid_columns;
      const int x1 = (gx + 1) * strength.cols / options.grid_columns;
      const int y0 = gy * strength.rows / options.grid_rows;
      const int y1 = (gy + 1) * strength.rows / options.grid_rows;
      if (x1 <= x0 || y1 <= y0) continue;
      // The cell's strongest response, the first in row order among equals (as cv::minMaxLoc
      // gives it; a loop of our own because minMaxLoc's set-up cost more than its 10 x 10
      // pixels: a third of the samples' instructions).
      float strongest = strength.at<float>(y0, x0);
      cv::Point at(0, 0);
      for (int y = y0; y < y1; ++y) {
        const float* row = strength.ptr<float>(y);
        for (int x = x0; x < x1; ++x) {
          if (row[x] > strongest) strongest = row[x], at = cv::Point(x - x0, y - y0);
        }
      }
      if (strongest < options.min_corner_strength) continue;
      // pyrDown's pixel (x, y) is centred on the full image's (2x, 2y).
      const int x = std::min(gray.cols - 1, step * (x0 + at.x));
      const int y = std::min(gray.rows - 1, step * (y0 + at.y));
      if (depth.at<float>(y, x) > 0)
        samples.emplace_back(static_cast<float>(x), static_cast<float>(y));
    }
  }
  return samples;
}

int CountMotionInliers(const StaticMotionOptions& options, const PinholeIntrinsics& k,
                       const std::vector<MotionCorrespondence>& matches,
                       const Eigen::Isometry3d& T) {
  const double limit2 = options.inlier_px * options.inlier_px;
  int inliers = 0;
  for (const MotionCorrespondence& m : matches) inliers += IsInlier(k, m, T, limit2);
  return inliers;
}

// The RANSAC problem (optim/ransac.h): minimal sets of 3 samples fitted by Umeyama's method,
// scored by their inliers, a fixed number of samples, each new best refitted to its inliers.
class StaticMotionProblem {
 public:
  using Model = Eigen::Isometry3d;
  using Score = int;

  StaticMotionProblem(const StaticMotionOptions& options, const PinholeIntrinsics& k,
                      const std::vector<MotionCorrespondence>& matches)
      : options_(options),
        k_(k),
        matches_(matches),
        random_(options.seed),
        pick_(0, matches.size() - 1) {}

  std::optional<Model> Hypothesis() {
    const std::array<size_t, 3> s{pick_(random_), pick_(random_), pick_(random_)};
    if (s[0] == s[1] || s[0] == s[2] || s[1] == s[2]) return std::nullopt;
    Eigen::Matrix3d from, to;
    for (int c = 0; c < 3; ++c) {
      from.col(c) = matches_[s[static_cast<size_t>(c)]].past_world;
      to.col(c) = matches_[s[static_cast<size_t>(c)]].current_camera;
    }
    // A nearly collinear sample fixes no rotation about its line.
    const Eigen::Vector3d a = from.col(1) - from.col(0), b = from.col(2) - from.col(0);
    if (a.cross(b).norm() < 0.05 * a.norm() * b.norm()) return std::nullopt;
    return Eigen::Isometry3d(Eigen::umeyama(from, to, false));
  }
  int Evaluate(const Model& T) const { return CountMotionInliers(options_, k_, matches_, T); }
  static bool Better(int inliers, int best) { return inliers > best; }
  // Local optimisation (LO-RANSAC): three samples' depths are noisy, so a good draw explains
  // only part of its motion's samples; the fit to all its inliers explains them all.
  void Improve(Model* T, int* inliers) const {
    for (int round = 0; round < 2; ++round) {
      const Eigen::Isometry3d refit = FitToInliers(options_, k_, matches_, *T);
      const int refit_inliers = Evaluate(refit);
      if (refit_inliers <= *inliers) break;
      *T = refit;
      *inliers = refit_inliers;
    }
  }
  int Iterations(int) const { return options_.hypotheses; }
  static int Worst() { return -1; }

 private:
  const StaticMotionOptions& options_;
  const PinholeIntrinsics& k_;
  const std::vector<MotionCorrespondence>& matches_;
  std::mt19937 random_;
  std::uniform_int_distribution<size_t> pick_;
};

StaticMotionResult FindStaticMotion(const StaticMotionOptions& options, const PinholeIntrinsics& k,
                                    const std::vector<MotionCorrespondence>& matches,
                                    const Eigen::Isometry3d& rough) {
  StaticMotionResult result;
  result.T_camera_world = rough;
  result.rough_inliers = result.inliers = CountMotionInliers(options, k, matches, rough);
  // Whether `inliers` explain clearly more than the rough pose does.
  const auto clearly_more = [&](double inliers) {
    return inliers > (1.0 + options.min_gain) * result.rough_inliers &&
           inliers >= result.rough_inliers + options.min_extra_samples;
  };
  if (!options.enabled || static_cast<int>(matches.size()) < options.min_correspondences)
    return result;
  // No motion can explain more than all samples: where the rough pose already explains so many
  // that the gain is out of reach, it stays (most frames of a static scene end here).
  if (!clearly_more(static_cast<double>(matches.size()))) return result;

  StaticMotionProblem problem(options, k, matches);
  const RansacOutcome<Eigen::Isometry3d, int> outcome = Ransac(problem);
  Eigen::Isometry3d best = outcome.model.value_or(rough);
  int best_inliers = outcome.score;
  if (!clearly_more(best_inliers)) return result;
  // Refine on the inliers by their reprojection error (the depth of a sample is noisier than
  // its position), twice: the inlier set grows as the pose settles.
  const double limit2 = options.inlier_px * options.inlier_px;
  for (int round = 0; round < 2; ++round) {
    std::vector<Eigen::Vector3d> points;
    std::vector<PointObservation> observations;
    for (const MotionCorrespondence& m : matches) {
      if (!IsInlier(k, m, best, limit2)) continue;
      points.push_back(m.past_world);
      PointObservation o;
      o.pixel = m.current_pixel;
      observations.push_back(o);
    }
    if (points.size() < 6) break;
    PoseOptimizationOptions refine;
    refine.rounds = 2;
    const Eigen::Isometry3d refined =
        OptimizePose(k, best, points, observations, refine).T_camera_world;
    const int inliers = CountMotionInliers(options, k, matches, refined);
    if (inliers < best_inliers) break;
    best = refined;
    best_inliers = inliers;
  }
  if (!clearly_more(best_inliers)) return result;
  // Within the samples' noise of the rough pose: a fit to that noise, not another motion.
  if (MedianShiftPx(k, matches, best, rough) < options.min_shift_px) return result;
  result.replaced = true;
  result.T_camera_world = best;
  result.inliers = best_inliers;
  return result;
}

}  // namespace sdoslam
