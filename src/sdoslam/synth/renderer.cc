#include "sdoslam/synth/renderer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <list>
#include <memory>
#include <mutex>
#include <opencv2/imgproc.hpp>

namespace sdoslam::synth {
namespace {

// Where a primitive may show: a pixel rectangle and, for a lens that distorts (whose pixel
// rectangle is the whole image), the rectangle of normalised undistorted coordinates x/z, y/z
// its rays pass through.
struct Bounds {
  cv::Rect screen;
  double x0 = -1e300, x1 = 1e300, y0 = -1e300, y1 = 1e300;
};

struct Candidate {
  const Primitive* primitive;
  uint16_t id;
  Bounds bounds;
  Eigen::Isometry3d T_texture_world;
  RaysFrom rays;  // from the camera centre
};

// Pixels whose rays pass within x0..x1, y0..y1 in normalised coordinates, with a pixel to spare.
cv::Rect PixelsOf(const Camera& camera, double x0, double x1, double y0, double y1) {
  const CameraOptions& o = camera.options();
  auto clamp = [](double value) { return std::clamp(value, -1e6, 1e6); };
  const cv::Point top_left(static_cast<int>(std::floor(clamp(o.fx * x0 + o.cx))) - 1,
                           static_cast<int>(std::floor(clamp(o.fy * y0 + o.cy))) - 1);
  const cv::Point bottom_right(static_cast<int>(std::ceil(clamp(o.fx * x1 + o.cx))) + 2,
                               static_cast<int>(std::ceil(clamp(o.fy * y1 + o.cy))) + 2);
  return cv::Rect(top_left, bottom_right);
}

// Conservative bounds of a primitive on the screen: where both its box and its bounding sphere
// may show.
Bounds ScreenBounds(const Primitive& p, const Eigen::Isometry3d& T_camera_world,
                    const Camera& camera) {
  const cv::Rect full(0, 0, camera.width(), camera.height());
  const Eigen::Vector3d c = T_camera_world * p.T_world_primitive.translation();
  const double r = p.half_size.norm();
  if (c.z() + r < 0.0) return {};
  // The primitive's box (an ellipsoid lies inside the box of its radii) bounds it more tightly
  // than its sphere. Only its part in front of the plane z = kNear can be hit (hits are taken at
  // depths above 1e-9 m, and a computed depth is within 1e-13 m of the true one); that part is a
  // convex polyhedron whose corners are the box's corners in front of the plane and the points
  // where the box's edges cross it. Its image lies inside the bounding rectangle of theirs
  // (perspective maps segments in front of the camera to segments): a wall partly behind the
  // camera covers the side of the image it is on, a wall wholly behind it nothing, a thin shelf
  // far fewer pixels than its sphere. Rays outside hit nothing, so the image is the same bit for
  // bit, from a fifth of the intersection tests (synthetic rooms: 1.7-1.9 a pixel, of which 1.5
  // hit, against 8.3-10.3 with the spheres alone; rendering a sequence -20 % CPU).
  constexpr double kNear = 1e-10;
  std::array<Eigen::Vector3d, 8> corners;
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d local((k & 1 ? 1 : -1) * p.half_size.x(),
                                (k & 2 ? 1 : -1) * p.half_size.y(),
                                (k & 4 ? 1 : -1) * p.half_size.z());
    corners[k] = T_camera_world * (p.T_world_primitive * local);
  }
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  bool any = false;
  auto include = [&](const Eigen::Vector3d& q) {
    any = true;
    x0 = std::min(x0, q.x() / q.z());
    x1 = std::max(x1, q.x() / q.z());
    y0 = std::min(y0, q.y() / q.z());
    y1 = std::max(y1, q.y() / q.z());
  };
  for (int k = 0; k < 8; ++k) {
    if (corners[k].z() >= kNear) include(corners[k]);
    for (int axis_bit : {1, 2, 4}) {  // the edge to the corner that differs in one coordinate
      const int other = k | axis_bit;
      if (other == k) continue;
      const Eigen::Vector3d &a = corners[k], &b = corners[other];
      if ((a.z() < kNear) == (b.z() < kNear)) continue;
      Eigen::Vector3d q = a + (kNear - a.z()) / (b.z() - a.z()) * (b - a);
      q.z() = kNear;
      include(q);
    }
  }
  if (!any) return {};
  if (c.z() - r >= 0.05) {
    // The sphere: the projection of its bounding box (x/z is extreme at the box's corners).
    const double z_near = c.z() - r, z_far = c.z() + r;
    auto ratio_range = [&](double lo, double hi) {
      return std::pair{lo < 0 ? lo / z_near : lo / z_far, hi > 0 ? hi / z_near : hi / z_far};
    };
    const auto [sx0, sx1] = ratio_range(c.x() - r, c.x() + r);
    const auto [sy0, sy1] = ratio_range(c.y() - r, c.y() + r);
    if (!camera.HasDistortion()) {
      return {PixelsOf(camera, x0, x1, y0, y1) & full & PixelsOf(camera, sx0, sx1, sy0, sy1)};
    }
    x0 = std::max(x0, sx0);
    x1 = std::min(x1, sx1);
    y0 = std::max(y0, sy0);
    y1 = std::min(y1, sy1);
    if (x0 > x1 || y0 > y1) return {};
  } else if (!camera.HasDistortion()) {
    return {PixelsOf(camera, x0, x1, y0, y1) & full};
  }
  // A distorting lens bends the pixels' rays: the rectangle is one of ray directions, tested
  // pixel by pixel, with two pixels to spare as PixelsOf keeps.
  const CameraOptions& o = camera.options();
  const double spare_x = 2.0 / o.fx, spare_y = 2.0 / o.fy;
  return {full, x0 - spare_x, x1 + spare_x, y0 - spare_y, y1 + spare_y};
}

// The primitives the camera may see at time t, each with its screen bounds: the scene's static
// parts and the objects' parts at t (made into `object_parts`, which the candidates point into).
std::vector<Candidate> VisibleCandidates(const Scene& scene, double t,
                                         const Eigen::Isometry3d& T_world_camera,
                                         const Camera& camera,
                                         std::vector<Primitive>* object_parts) {
  const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
  const Eigen::Vector3d origin = T_world_camera.translation();
  std::vector<uint16_t> object_ids;
  for (const SceneObject& object : scene.objects) {
    for (Primitive& part : object.parts_at(t)) {
      object_parts->push_back(std::move(part));
      object_ids.push_back(object.id);
    }
  }
  std::vector<Candidate> candidates;
  for (const Primitive& p : scene.static_parts) {
    const Bounds b = ScreenBounds(p, T_camera_world, camera);
    if (b.screen.area() > 0) {
      candidates.push_back({&p, 0, b, p.T_world_texture.inverse(), RaysFrom(p, origin)});
    }
  }
  for (size_t k = 0; k < object_parts->size(); ++k) {
    const Bounds b = ScreenBounds((*object_parts)[k], T_camera_world, camera);
    if (b.screen.area() > 0) {
      candidates.push_back({&(*object_parts)[k], object_ids[k], b,
                            (*object_parts)[k].T_world_texture.inverse(),
                            RaysFrom((*object_parts)[k], origin)});
    }
  }

  return candidates;
}

// Each pixel's undistorted position (row by row) and, per row, the range of their normalised
// y; empty for a camera without distortion.
struct UndistortedGrid {
  std::vector<cv::Point2f> pixels;
  std::vector<std::pair<double, double>> row_y;  // per row: least and greatest (y - cy) / fy
};

// The grid of a camera, computed once per calibration: undistorting every pixel (OpenCV's
// iterative undistortPoints) cost more than ray casting the frame (a quarter of the CPU of the
// plays over the real desk clip). The last few calibrations are kept; a sequence uses one.
std::shared_ptr<const UndistortedGrid> UndistortedPixels(const Camera& camera) {
  static std::mutex mutex;
  static std::list<std::pair<CameraOptions, std::shared_ptr<const UndistortedGrid>>> cache;
  const CameraOptions& o = camera.options();
  auto same = [&o](const CameraOptions& a) {
    return a.width == o.width && a.height == o.height && a.fx == o.fx && a.fy == o.fy &&
           a.cx == o.cx && a.cy == o.cy && a.k1 == o.k1 && a.k2 == o.k2 && a.p1 == o.p1 &&
           a.p2 == o.p2 && a.k3 == o.k3;
  };
  {
    const std::lock_guard<std::mutex> lock(mutex);
    for (const auto& [options, grid] : cache)
      if (same(options)) return grid;
  }
  auto grid = std::make_shared<UndistortedGrid>();
  const int width = camera.width(), height = camera.height();
  if (camera.HasDistortion()) {
    grid->pixels.reserve(static_cast<size_t>(width) * height);
    for (int v = 0; v < height; ++v)
      for (int u = 0; u < width; ++u)
        grid->pixels.emplace_back(static_cast<float>(u), static_cast<float>(v));
    grid->pixels = camera.UndistortPoints(grid->pixels);
    grid->row_y.assign(static_cast<size_t>(height), {1e300, -1e300});
    for (int v = 0; v < height; ++v) {
      for (int u = 0; u < width; ++u) {
        const double y = (grid->pixels[static_cast<size_t>(v) * width + u].y - o.cy) / o.fy;
        auto& [lo, hi] = grid->row_y[static_cast<size_t>(v)];
        lo = std::min(lo, y);
        hi = std::max(hi, y);
      }
    }
  }
  const std::lock_guard<std::mutex> lock(mutex);
  cache.emplace_front(o, grid);
  if (cache.size() > 4) cache.pop_back();
  return grid;
}

}  // namespace

RenderedView AllocateView(const Camera& camera) {
  RenderedView view;
  view.colour.create(camera.height(), camera.width(), CV_32FC3);
  view.depth.create(camera.height(), camera.width(), CV_32FC1);
  view.instance.create(camera.height(), camera.width(), CV_16UC1);
  return view;
}

RenderedView Render(const Scene& scene, double t, const Eigen::Isometry3d& T_world_camera,
                    const Camera& camera) {
  RenderedView view = AllocateView(camera);
  RenderRows(scene, t, T_world_camera, camera, 0, camera.height(), &view);
  return view;
}

void RenderRows(const Scene& scene, double t, const Eigen::Isometry3d& T_world_camera,
                const Camera& camera, int row_begin, int row_end, RenderedView* out) {
  const int width = camera.width();
  RenderedView& view = *out;
  CV_Assert(view.colour.size() == cv::Size(width, camera.height()) && row_begin >= 0 &&
            row_end <= camera.height());

  std::vector<Primitive> object_parts;
  const std::vector<Candidate> candidates =
      VisibleCandidates(scene, t, T_world_camera, camera, &object_parts);
  // Ray directions with z = 1 in the camera frame, so a hit's ray parameter is its depth.
  const std::shared_ptr<const UndistortedGrid> grid = UndistortedPixels(camera);
  const std::vector<cv::Point2f>& pixels = grid->pixels;
  const bool distorted = !pixels.empty();  // rays are bounded by direction (Bounds), not pixel

  const CameraOptions& o = camera.options();
  const Eigen::Matrix3d R = T_world_camera.linear();
  const Eigen::Vector3d light = scene.light_direction.normalized();

  // Rows in parallel. Under ThreadSanitizer (scripts/tsan.sh) they run in order on this thread:
  // TBB is not built with TSan, whose reports on the renderer's rows would then be about TBB's
  // own synchronisation, which it cannot see, and would hide those on sdoslam's threads.
  auto render_row = [&](int v) {
    auto* colour_row = view.colour.ptr<cv::Vec3f>(v);
    auto* depth_row = view.depth.ptr<float>(v);
    auto* id_row = view.instance.ptr<uint16_t>(v);
    TextureSampler texture;
    std::vector<const Candidate*> row_candidates;
    for (const Candidate& c : candidates) {
      const cv::Rect& screen = c.bounds.screen;
      if (v < screen.y || v >= screen.y + screen.height) continue;
      if (!grid->row_y.empty()) {
        const auto [lo, hi] = grid->row_y[static_cast<size_t>(v)];
        if (hi < c.bounds.y0 || lo > c.bounds.y1) continue;
      }
      row_candidates.push_back(&c);
    }
    for (int u = 0; u < width; ++u) {
      double x = (u - o.cx) / o.fx, y = (v - o.cy) / o.fy;
      if (!pixels.empty()) {
        const cv::Point2f& q = pixels[static_cast<size_t>(v) * width + u];
        x = (q.x - o.cx) / o.fx;
        y = (q.y - o.cy) / o.fy;
      }
      const Eigen::Vector3d direction = R * Eigen::Vector3d(x, y, 1.0);
      Hit best, hit;
      best.distance = 1e9;
      const Candidate* best_candidate = nullptr;
      for (const Candidate* c : row_candidates) {
        const Bounds& b = c->bounds;
        if (u < b.screen.x || u >= b.screen.x + b.screen.width) continue;
        if (distorted && (x < b.x0 || x > b.x1 || y < b.y0 || y > b.y1)) continue;
        if (c->rays.Intersect(direction, best.distance, &hit)) {
          best = hit;
          best_candidate = c;
        }
      }
      if (best_candidate == nullptr) {
        colour_row[u] = cv::Vec3f(0, 0, 0);
        depth_row[u] = 0;
        id_row[u] = 0;
        continue;
      }
      const Primitive& p = *best_candidate->primitive;
      const Eigen::Vector3d in_texture = best_candidate->T_texture_world * best.point;
      // (x / 1 is x: the common scale costs no divisions.)
      const Eigen::Vector3f albedo = texture.Colour(
          p.base_colour, p.texture_seed,
          p.texture_scale == 1.0 ? in_texture : Eigen::Vector3d(in_texture / p.texture_scale));
      const double lambert = std::max(0.0, best.normal.dot(light));
      const float shade = static_cast<float>(0.35 + 0.65 * lambert);
      colour_row[u] = cv::Vec3f(albedo.z() * shade, albedo.y() * shade, albedo.x() * shade);
      depth_row[u] = static_cast<float>(best.distance);
      id_row[u] = best_candidate->id;
    }
  };
#if defined(__SANITIZE_THREAD__)
  for (int v = row_begin; v < row_end; ++v) render_row(v);
#else
  tbb::parallel_for(row_begin, row_end, render_row);
#endif
}

cv::Mat RenderColour(const Scene& scene, double t, const Eigen::Isometry3d& T_world_camera,
                     const Camera& camera, int samples_per_side) {
  const int n = samples_per_side;
  if (n <= 1) return Render(scene, t, T_world_camera, camera).colour;
  // The same camera at n times the resolution: its pixel (n·u + k, n·v + l) looks through
  // (u + (k − (n − 1)/2)/n, v + (l − (n − 1)/2)/n) of this one, so an n × n block of it covers
  // this camera's pixel (u, v) evenly. The distortion acts on normalised coordinates and stays.
  CameraOptions fine = camera.options();
  fine.width *= n;
  fine.height *= n;
  fine.fx *= n;
  fine.fy *= n;
  fine.cx = n * fine.cx + 0.5 * (n - 1);
  fine.cy = n * fine.cy + 0.5 * (n - 1);
  const cv::Mat sharp = Render(scene, t, T_world_camera, Camera(fine)).colour;
  cv::Mat colour;
  // An integer factor: INTER_AREA is the plain mean of each n × n block.
  cv::resize(sharp, colour, cv::Size(camera.width(), camera.height()), 0, 0, cv::INTER_AREA);
  return colour;
}

}  // namespace sdoslam::synth
