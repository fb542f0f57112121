#include "sdoslam/core/geometry.h"

namespace sdoslam {

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

double ReprojectionChi2(const PinholeIntrinsics& k, const Eigen::Vector3d& p,
                        const PointObservation& m) {
  const double u = k.fx * p.x() / p.z() + k.cx, v = k.fy * p.y() / p.z() + k.cy;
  double e2 = (u - m.pixel.x()) * (u - m.pixel.x()) + (v - m.pixel.y()) * (v - m.pixel.y());
  if (m.stereo()) {
    const double ur = u - k.bf / p.z();
    e2 += (ur - m.right_u) * (ur - m.right_u);
  }
  return e2 * m.inv_sigma2;
}

}  // namespace sdoslam
