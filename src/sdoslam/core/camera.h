#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "sdoslam/core/config.h"

namespace YAML {
class Emitter;
}

namespace sdoslam {

// A pinhole RGB-D camera with radial-tangential (OpenCV "plumb bob") distortion, as the TUM and
// Bonn datasets publish their calibration.
// Bounds CameraOptions::Check() puts on the distortion coefficients (docs/configuration.md).
inline constexpr double kMaxRadialK12 = 10;  // |k1|, |k2|
inline constexpr double kMaxRadialK3 = 100;  // |k3|
inline constexpr double kMaxTangential = 1;  // |p1|, |p2|
// ... and on the other numbers: finite is not enough (fx: 1e308 ran and wrote a trajectory that
// meant nothing). A focal length of 0.05 to 100 image widths (heights) is a field of view of 169
// to 0.6 degrees; a pinhole model covers no more, and no lens is narrower.
inline constexpr double kMinFocalPerPixel = 0.05;
inline constexpr double kMaxFocalPerPixel = 100;
inline constexpr double kMinFps = 0.01;  // one frame in 100 s (1/fps paces --camera-rate)
inline constexpr double kMaxFps = 1000;
inline constexpr double kMinDepthFactor = 1;  // raw units per metre: 1 m .. 10 um a unit
inline constexpr double kMaxDepthFactor = 1e5;
inline constexpr double kMaxDepth = 1000;  // metres, depth_min and depth_max

struct CameraOptions {
  std::string name = "camera";
  int width = 640;   // image width in pixels
  int height = 480;  // image height in pixels
  double fx = 0.0;   // focal lengths and principal point, pixels
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  double k1 = 0.0;  // radial-tangential distortion (k1 k2 p1 p2 k3); all zero = undistorted
  double k2 = 0.0;
  double p1 = 0.0;
  double p2 = 0.0;
  double k3 = 0.0;
  double fps = 30.0;             // nominal frame rate
  double depth_factor = 5000.0;  // raw 16-bit depth units per metre
  double depth_min = 0.1;        // depth outside [depth_min, depth_max] metres counts as missing
  double depth_max = 10.0;
  // A rolling shutter's readout: seconds from the first row's exposure to the last's (0: a
  // global shutter). Tracking moves each feature to the middle row's pose with the camera's
  // motion (RowMotion in map/frame.h). configs/tum_fr1.yaml says what was measured for the Kinect.
  double readout_s = 0.0;
  // The intrinsics (size, focal lengths, principal point, distortion) come from the dataset's
  // own calibration (an OMD segment's kalibr.yaml, a TUM folder's camera.yaml) when the run
  // opens it; the depth settings above still come from here.
  bool from_dataset = false;

  // Throws Error naming the first impossible field (intrinsics are not checked while they are
  // still to come from the dataset).
  void Check() const;
};

// Reads the keys of a `camera:` section (all optional except fx fy cx cy, which must be absent
// with `from_dataset: true`); rejects unknown keys.
CameraOptions ReadCameraOptions(ConfigMap& section);
void WriteCameraOptions(const CameraOptions& options, YAML::Emitter* out);

// Loads a camera config file: a YAML file with one `camera:` section.
CameraOptions LoadCameraConfig(const std::filesystem::path& path);

class Camera {
 public:
  explicit Camera(const CameraOptions& options);  // checks the options

  const CameraOptions& options() const { return options_; }
  int width() const { return options_.width; }
  int height() const { return options_.height; }
  bool HasDistortion() const { return has_distortion_; }

  // Pinhole projection of a point in the camera frame to undistorted pixel coordinates.
  Eigen::Vector2d Project(const Eigen::Vector3d& point_camera) const;
  // Back-projects an undistorted pixel with its depth (metres, along the optical axis).
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel, double depth) const;

  // Applies the lens distortion to an undistorted pixel (the forward model, used to render).
  Eigen::Vector2d Distort(const Eigen::Vector2d& undistorted_pixel) const;
  // Removes the lens distortion from measured pixels (iterative inverse, OpenCV).
  std::vector<cv::Point2f> UndistortPoints(const std::vector<cv::Point2f>& distorted) const;

  cv::Matx33d K() const;
  cv::Mat DistortionCoefficients() const;  // 1x5: k1 k2 p1 p2 k3

 private:
  CameraOptions options_;
  bool has_distortion_ = false;
};

}  // namespace sdoslam
