#include "sdoslam/synth/scene.h"

#include <algorithm>
#include <cmath>

namespace sdoslam::synth {
namespace {

uint32_t Hash(uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
  // Integer mixing (after Thomas Wang / murmur finalisers); only needs to look random.
  uint32_t h = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u;
  h ^= (c + 0x165667B1u) * 0xC2B2AE3Du;
  h ^= (d + 0x27D4EB2Fu) * 0x27D4EB2Fu;
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  h ^= h >> 12;
  h *= 0x297A2D39u;
  h ^= h >> 15;
  return h;
}

float Unit(uint32_t h) { return static_cast<float>(h & 0xFFFFFF) / static_cast<float>(0xFFFFFF); }

}  // namespace

bool Intersect(const Primitive& p, const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
               double max_distance, Hit* hit) {
  return RaysFrom(p, origin).Intersect(direction, max_distance, hit);
}

RaysFrom::RaysFrom(const Primitive& primitive, const Eigen::Vector3d& origin)
    : primitive_(&primitive),
      R_(primitive.T_world_primitive.linear()),
      origin_(origin),
      o_local_(R_.transpose() * (origin - primitive.T_world_primitive.translation())) {}

bool RaysFrom::Intersect(const Eigen::Vector3d& direction, double max_distance, Hit* hit) const {
  const Primitive& p = *primitive_;
  const Eigen::Matrix3d& R = R_;
  const Eigen::Vector3d& origin = origin_;
  const Eigen::Vector3d& o = o_local_;
  const Eigen::Vector3d d = R.transpose() * direction;
  double t = 0;
  Eigen::Vector3d local_normal;
  if (p.shape == Primitive::Shape::kBox) {
    // Slab test.
    double t_near = -1e300, t_far = 1e300;
    int axis_near = 0;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d[a]) < 1e-12) {
        if (std::abs(o[a]) > p.half_size[a]) return false;
        continue;
      }
      double t0 = (-p.half_size[a] - o[a]) / d[a];
      double t1 = (p.half_size[a] - o[a]) / d[a];
      if (t0 > t1) std::swap(t0, t1);
      if (t0 > t_near) {
        t_near = t0;
        axis_near = a;
      }
      t_far = std::min(t_far, t1);
      if (t_near > t_far) return false;
    }
    if (t_near <= 1e-9 || t_near >= max_distance) return false;
    t = t_near;
    local_normal = Eigen::Vector3d::Zero();
    local_normal[axis_near] = d[axis_near] > 0 ? -1.0 : 1.0;
  } else {
    // Ellipsoid: scale to the unit sphere.
    const Eigen::Vector3d os = o.cwiseQuotient(p.half_size), ds = d.cwiseQuotient(p.half_size);
    const double a = ds.squaredNorm(), b = os.dot(ds), c = os.squaredNorm() - 1.0;
    const double disc = b * b - a * c;
    if (disc < 0) return false;
    t = (-b - std::sqrt(disc)) / a;
    if (t <= 1e-9 || t >= max_distance) return false;
    local_normal = (o + t * d).cwiseQuotient(p.half_size.cwiseProduct(p.half_size)).normalized();
  }
  hit->distance = t;
  hit->point = origin + t * direction;
  hit->normal = R * local_normal;
  return true;
}

Eigen::Vector3f TextureColour(const Eigen::Vector3f& base, uint32_t seed,
                              const Eigen::Vector3d& q) {
  return TextureSampler().Colour(base, seed, q);
}

int32_t FloorOfQuotient(double x, double divisor, double inverse) {
  // The product with the rounded inverse is within a few ulps of the quotient: away from an
  // integer both have the same floor, and near one (or for values too large to judge) the
  // quotient decides.
  const double product = x * inverse;
  const double below = std::floor(product);
  if (std::abs(product) < 1e6 && product - below > 1e-9 && product - below < 1.0 - 1e-9) {
    return static_cast<int32_t>(below);
  }
  return static_cast<int32_t>(std::floor(x / divisor));
}

namespace {

// Cell sizes in metres, coarse to fine; the finest still spans several pixels at 4 m.
constexpr double kCell[] = {0.37, 0.13, 0.047};
constexpr double kInverseCell[] = {1.0 / kCell[0], 1.0 / kCell[1], 1.0 / kCell[2]};
constexpr float kWeight[] = {0.45f, 0.35f, 0.20f};

}  // namespace

Eigen::Vector3f TextureSampler::Colour(const Eigen::Vector3f& base, uint32_t seed,
                                       const Eigen::Vector3d& q) {
  float value = 0;
  for (int octave = 0; octave < 3; ++octave) {
    const auto ix =
        static_cast<uint32_t>(FloorOfQuotient(q.x(), kCell[octave], kInverseCell[octave]));
    const auto iy =
        static_cast<uint32_t>(FloorOfQuotient(q.y(), kCell[octave], kInverseCell[octave]));
    const auto iz =
        static_cast<uint32_t>(FloorOfQuotient(q.z(), kCell[octave], kInverseCell[octave]));
    Cell& cell = cells_[octave];
    if (!cell.valid || cell.seed != seed || cell.ix != ix || cell.iy != iy || cell.iz != iz) {
      const uint32_t h = Hash(ix, iy, iz, seed * 3u + static_cast<uint32_t>(octave));
      cell = {true, seed, ix, iy, iz, kWeight[octave] * Unit(h)};
      if (octave == 0) {
        tint_ =
            Eigen::Vector3f(Unit(Hash(h, 1, 0, 0)), Unit(Hash(h, 2, 0, 0)), Unit(Hash(h, 3, 0, 0)));
      }
    }
    value += cell.term;
  }
  const Eigen::Vector3f colour =
      base.cwiseProduct(Eigen::Vector3f::Constant(0.25f) + 1.2f * value * Eigen::Vector3f::Ones()) +
      0.25f * (tint_ - Eigen::Vector3f::Constant(0.5f));
  return colour.cwiseMax(0.0f).cwiseMin(1.0f);
}

bool SceneObject::MovesBetween(double t0, double t1) const {
  const Eigen::Isometry3d a = pose_at(t0), b = pose_at(t1);
  if ((a.translation() - b.translation()).norm() > 1e-6) return true;
  if (Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() > 1e-6) return true;
  // Articulated parts (limbs) can move while the reference frame does not.
  const auto pa = parts_at(t0), pb = parts_at(t1);
  for (size_t k = 0; k < pa.size() && k < pb.size(); ++k) {
    if (!pa[k].T_world_primitive.isApprox(pb[k].T_world_primitive, 1e-9)) return true;
  }
  return false;
}

}  // namespace sdoslam::synth
