#include "sdoslam/core/camera.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <string>
#include <tuple>

#include "sdoslam/core/error.h"

namespace sdoslam {
namespace {

void Require(bool ok, const std::string& field, const std::string& why) {
  if (!ok) throw Error("camera." + field + ": " + why);
}

}  // namespace

void CameraOptions::Check() const {
  auto within = [](double value, double low, double high) {
    return std::isfinite(value) && value >= low && value <= high;
  };
  Require(
      within(fps, kMinFps, kMaxFps), "fps",
      fmt::format("must be within {:g}..{:g} frames a second, got {:g}", kMinFps, kMaxFps, fps));
  Require(within(depth_factor, kMinDepthFactor, kMaxDepthFactor), "depth_factor",
          fmt::format("must be within {:g}..{:g} raw depth units a metre, got {:g}",
                      kMinDepthFactor, kMaxDepthFactor, depth_factor));
  Require(within(depth_min, 0, kMaxDepth), "depth_min",
          fmt::format("must be within 0..{:g} m, got {:g}", kMaxDepth, depth_min));
  Require(within(depth_max, 0, kMaxDepth) && depth_max > depth_min, "depth_max",
          fmt::format("must be larger than depth_min ({:g}) and at most {:g} m, got {:g}",
                      depth_min, kMaxDepth, depth_max));
  // At most one frame interval: a sensor reads its rows out within a frame.
  Require(within(readout_s, 0, 1 / fps), "readout_s",
          fmt::format("must be within 0..{:g} s (one frame at {:g} fps), got {:g}", 1 / fps, fps,
                      readout_s));
  if (from_dataset) return;
  Require(width > 0 && width <= 16384, "width",
          "must be in 1..16384, got " + std::to_string(width));
  Require(height > 0 && height <= 16384, "height",
          "must be in 1..16384, got " + std::to_string(height));
  for (const auto& [name, focal, size, side] :
       {std::tuple{"fx", fx, width, "width"}, {"fy", fy, height, "height"}}) {
    const double low = kMinFocalPerPixel * size, high = kMaxFocalPerPixel * size;
    Require(within(focal, low, high), name,
            fmt::format("focal length must be within {:g}..{:g} pixels ({:g} to {:g} times the "
                        "image {}: a field of view of 169 to 0.6 degrees), got {:g}",
                        low, high, kMinFocalPerPixel, kMaxFocalPerPixel, side, focal));
  }
  Require(std::isfinite(cx) && cx >= 0 && cx <= width, "cx",
          "principal point must lie in the image");
  Require(std::isfinite(cy) && cy >= 0 && cy <= height, "cy",
          "principal point must lie in the image");
  // Bounds far outside any radial-tangential calibration (fisheye lenses have k1 near -0.5,
  // strong wide-angle ones k3 of a few units): beyond them the model is not a lens, and the
  // undistortion silently gave up (k1 = 1e30 behaved as no distortion at all).
  for (const auto& [name, value, bound] : {std::tuple{"k1", k1, kMaxRadialK12},
                                           {"k2", k2, kMaxRadialK12},
                                           {"k3", k3, kMaxRadialK3},
                                           {"p1", p1, kMaxTangential},
                                           {"p2", p2, kMaxTangential}}) {
    Require(std::isfinite(value) && std::abs(value) <= bound, name,
            fmt::format("must be finite and within +-{} (got {})", bound, value));
  }
}

CameraOptions ReadCameraOptions(ConfigMap& section) {
  CameraOptions options;
  section.Read("name", &options.name);
  section.Read("width", &options.width);
  section.Read("height", &options.height);
  section.Read("from_dataset", &options.from_dataset);
  for (const char* key : {"fx", "fy", "cx", "cy"}) {
    if (!options.from_dataset && !section.Has(key)) {
      throw Error(section.origin() + ": camera." + key + " is required");
    }
    if (options.from_dataset && section.Has(key)) {
      throw Error(section.origin() + ": camera." + key +
                  " conflicts with from_dataset: true (the dataset's calibration gives it)");
    }
  }
  section.Read("fx", &options.fx);
  section.Read("fy", &options.fy);
  section.Read("cx", &options.cx);
  section.Read("cy", &options.cy);
  section.Read("k1", &options.k1);
  section.Read("k2", &options.k2);
  section.Read("p1", &options.p1);
  section.Read("p2", &options.p2);
  section.Read("k3", &options.k3);
  section.Read("fps", &options.fps);
  section.Read("depth_factor", &options.depth_factor);
  section.Read("depth_min", &options.depth_min);
  section.Read("depth_max", &options.depth_max);
  section.Read("readout_s", &options.readout_s);
  section.RejectUnknownKeys();
  try {
    options.Check();
  } catch (const Error& e) {
    throw Error(section.origin() + ": " + e.what());
  }
  return options;
}

void WriteCameraOptions(const CameraOptions& o, YAML::Emitter* out) {
  YAML::Emitter& y = *out;
  y << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "name" << YAML::Value << o.name;
  y << YAML::Key << "width" << YAML::Value << o.width;
  y << YAML::Key << "height" << YAML::Value << o.height;
  y << YAML::Precision(17);
  for (const auto& [key, value] : {std::pair{"fx", o.fx},
                                   {"fy", o.fy},
                                   {"cx", o.cx},
                                   {"cy", o.cy},
                                   {"k1", o.k1},
                                   {"k2", o.k2},
                                   {"p1", o.p1},
                                   {"p2", o.p2},
                                   {"k3", o.k3},
                                   {"fps", o.fps},
                                   {"depth_factor", o.depth_factor},
                                   {"depth_min", o.depth_min},
                                   {"depth_max", o.depth_max},
                                   {"readout_s", o.readout_s}}) {
    y << YAML::Key << key << YAML::Value << value;
  }
  y << YAML::EndMap;
}

CameraOptions LoadCameraConfig(const std::filesystem::path& path) {
  ConfigMap root = ConfigMap::LoadFile(path);
  std::optional<ConfigMap> section = root.Section("camera");
  // A run's config (configs/tum_fr1.yaml tunes tracking:, a run's config.yaml has them all)
  // may be given where only its camera is wanted (convert --config, synth --camera): the run's
  // own sections are left to `run`, which reads and checks them; other keys are still errors.
  for (const char* key : {"orb", "rgbd", "tracking", "mapping", "loop_closing", "dynamic", "run",
                          "versions", "consistency"}) {
    root.Section(key);
  }
  for (const char* key : {"mode", "vocabulary"}) {
    std::string ignored;
    root.Read(key, &ignored);
  }
  root.RejectUnknownKeys();
  if (!section) throw Error(path.string() + ": missing the 'camera:' section");
  return ReadCameraOptions(*section);
}

Camera::Camera(const CameraOptions& options) : options_(options) {
  if (options_.from_dataset)
    throw Error("camera: the intrinsics are to come from the dataset, which was not opened");
  options_.Check();
  has_distortion_ = options_.k1 != 0 || options_.k2 != 0 || options_.p1 != 0 || options_.p2 != 0 ||
                    options_.k3 != 0;
}

Eigen::Vector2d Camera::Project(const Eigen::Vector3d& p) const {
  const double inv_z = 1.0 / p.z();
  return {options_.fx * p.x() * inv_z + options_.cx, options_.fy * p.y() * inv_z + options_.cy};
}

Eigen::Vector3d Camera::Unproject(const Eigen::Vector2d& pixel, double depth) const {
  return {(pixel.x() - options_.cx) / options_.fx * depth,
          (pixel.y() - options_.cy) / options_.fy * depth, depth};
}

Eigen::Vector2d Camera::Distort(const Eigen::Vector2d& pixel) const {
  const CameraOptions& o = options_;
  const double x = (pixel.x() - o.cx) / o.fx;
  const double y = (pixel.y() - o.cy) / o.fy;
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (o.k1 + r2 * (o.k2 + r2 * o.k3));
  const double xd = x * radial + 2.0 * o.p1 * x * y + o.p2 * (r2 + 2.0 * x * x);
  const double yd = y * radial + o.p1 * (r2 + 2.0 * y * y) + 2.0 * o.p2 * x * y;
  return {o.fx * xd + o.cx, o.fy * yd + o.cy};
}

std::vector<cv::Point2f> Camera::UndistortPoints(const std::vector<cv::Point2f>& distorted) const {
  if (!has_distortion_ || distorted.empty()) return distorted;
  std::vector<cv::Point2f> undistorted;
  // OpenCV's default is 5 fixed-point iterations, too few for the strong TUM distortion near the
  // corners; iterate to sub-millipixel instead.
  cv::undistortPoints(distorted, undistorted, cv::Mat(K()), DistortionCoefficients(), cv::noArray(),
                      cv::Mat(K()),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 1e-9));
  return undistorted;
}

cv::Matx33d Camera::K() const {
  return {options_.fx, 0, options_.cx, 0, options_.fy, options_.cy, 0, 0, 1};
}

cv::Mat Camera::DistortionCoefficients() const {
  return (cv::Mat_<double>(1, 5) << options_.k1, options_.k2, options_.p1, options_.p2,
          options_.k3);
}

}  // namespace sdoslam
