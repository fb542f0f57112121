#pragma once

#include <Eigen/Core>

// The camera geometry that optimisation, matching, mapping and loop closing all speak: the
// pinhole of the undistorted image, a point's image measurement and the one χ² test of a
// reprojection error. It lives here, below all of them, so that none has to include another's
// headers (or link Ceres) for it.

namespace sdoslam {

struct PinholeIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double bf = 0;  // baseline × fx of the virtual stereo pair (RGB-D: depth → right image)
};

// The skew-symmetric matrix of v: Hat(v)·x = v × x.
Eigen::Matrix3d Hat(const Eigen::Vector3d& v);

// One image measurement of a point. right_u < 0: no depth (monocular residual).
struct PointObservation {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // undistorted
  double right_u = -1.0;
  double inv_sigma2 = 1.0;  // 1 / (pyramid scale of the keypoint's level)²
  // With the virtual right coordinate the error has three degrees of freedom, else two.
  bool stereo() const { return right_u >= 0; }
};

// χ² (95 %) thresholds of ORB-SLAM for 2 and 3 degrees of freedom.
inline constexpr double kChi2Mono = 5.991;
inline constexpr double kChi2Stereo = 7.815;

// The threshold of the reprojection χ² test: 3 degrees of freedom for an observation with a
// right coordinate (PointObservation::stereo()), 2 without.
inline double ReprojectionChi2Threshold(bool stereo) { return stereo ? kChi2Stereo : kChi2Mono; }

// The whitened squared reprojection error of a point at `p_camera` (camera frame) against `m`:
// (Δu² + Δv² [+ Δu_R², with u_R = u − bf/z, where m has a right coordinate]) · m.inv_sigma2,
// the value compared with ReprojectionChi2Threshold(m.stereo()). The point must be in front of
// the camera; callers test that first, each with its own margin.
double ReprojectionChi2(const PinholeIntrinsics& k, const Eigen::Vector3d& p_camera,
                        const PointObservation& m);

}  // namespace sdoslam
