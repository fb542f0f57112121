#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace sdoslam::synth {

// Geometry of the synthetic world. Units are metres; the world frame has y up.

// A solid primitive placed in the world: a box (half extents) or an ellipsoid (radii).
struct Primitive {
  enum class Shape { kBox, kEllipsoid };
  Shape shape = Shape::kBox;
  Eigen::Isometry3d T_world_primitive = Eigen::Isometry3d::Identity();
  Eigen::Vector3d half_size = Eigen::Vector3d::Constant(0.5);       // half extents or radii
  Eigen::Vector3f base_colour = Eigen::Vector3f(0.6f, 0.6f, 0.6f);  // linear RGB in [0, 1]
  uint32_t texture_seed = 0;
  // Texture coordinates are taken in this frame, so a part's texture moves with its object
  // (for articulated parts: the object's frame, not the limb's).
  Eigen::Isometry3d T_world_texture = Eigen::Isometry3d::Identity();
  // Texture coordinates are divided by this: < 1 gives finer, denser texture (more corners).
  double texture_scale = 1.0;
};

// What a ray hit.
struct Hit {
  double distance = 0;  // along the (unit) ray
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // world, facing the ray
};

// Ray/primitive intersection for rays starting outside the primitive; false when missed.
bool Intersect(const Primitive& primitive, const Eigen::Vector3d& origin,
               const Eigen::Vector3d& direction, double max_distance, Hit* hit);

// The same test, and the same result bit for bit, for many rays from one origin (the renderer's
// camera centre): what depends on the origin alone is computed once by the constructor. It
// keeps a pointer to the primitive, which must outlive it.
class RaysFrom {
 public:
  RaysFrom(const Primitive& primitive, const Eigen::Vector3d& origin);
  bool Intersect(const Eigen::Vector3d& direction, double max_distance, Hit* hit) const;

 private:
  const Primitive* primitive_;
  Eigen::Matrix3d R_;        // the primitive's orientation in the world
  Eigen::Vector3d origin_;   // world
  Eigen::Vector3d o_local_;  // the origin in the primitive's frame
};

// Procedural, non-repeating texture: several octaves of 3-D value cells (sharp-edged blocks,
// so ORB finds corners) hashed from the cell index and seed. Returns linear RGB in [0, 1].
Eigen::Vector3f TextureColour(const Eigen::Vector3f& base_colour, uint32_t seed,
                              const Eigen::Vector3d& point_in_texture_frame);

// floor(x / divisor) for |x / divisor| < 2^31, the same bit for bit, mostly without the division:
// `inverse` is 1 / divisor.
int32_t FloorOfQuotient(double x, double divisor, double inverse);

// TextureColour for one pixel after another, the same colours bit for bit: it remembers each
// octave's last cell, and neighbouring pixels mostly fall in the same cells (the finest spans
// several pixels at 4 m), so their hashes are not computed again; and it finds a cell by a
// product (FloorOfQuotient). The renderer keeps one per row of pixels; rendering a frame takes
// about 4 % less CPU.
class TextureSampler {
 public:
  Eigen::Vector3f Colour(const Eigen::Vector3f& base_colour, uint32_t seed,
                         const Eigen::Vector3d& point_in_texture_frame);

 private:
  struct Cell {
    bool valid = false;
    uint32_t seed = 0, ix = 0, iy = 0, iz = 0;
    float term = 0;  // the octave's weighted value
  };
  Cell cells_[3];
  Eigen::Vector3f tint_ = Eigen::Vector3f::Zero();  // of the coarsest octave's cell
};

// One object of the scene: its parts at time t. Instance id 0 is the static structure
// (room, furniture); objects have ids >= 1.
struct SceneObject {
  uint16_t id = 0;
  std::string name;
  std::string class_name;  // COCO class for known objects ("person"), empty for unknown ones
  // Parts in the world at time t (seconds from the start of the sequence).
  std::function<std::vector<Primitive>(double t)> parts_at;
  // Pose of the object's reference frame at time t (ground truth object poses).
  std::function<Eigen::Isometry3d(double t)> pose_at;
  // The sensor reads the object's depth (1 + depth_bias) times as far as it is: real sensors
  // misread some materials by a few percent (only over a real background).
  double depth_bias = 0.0;
  // Whether the object moves between t0 and t1 (for the dynamic mask).
  bool MovesBetween(double t0, double t1) const;
};

struct Scene {
  std::vector<Primitive> static_parts;  // id 0
  std::vector<SceneObject> objects;
  Eigen::Vector3d light_direction = Eigen::Vector3d(0.4, 1.0, -0.3).normalized();  // towards light
};

}  // namespace sdoslam::synth
