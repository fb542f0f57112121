#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/io/tum_dataset.h"

namespace sdoslam {

// The Oxford Multi-motion Dataset (Judd and Gammell, RA-L 2019) as published, per segment folder:
//   rgbd/rgbd.csv                  frame_num, time_sec, time_nsec (header line first)
//   rgbd/NNNNNN_color.png          colour, and NNNNNN_aligned_depth.png: 16-bit, millimetres
//   vicon.csv                      time_sec, time_nsec, object, qx, qy, qz, qw, tx, ty, tz
//                                  (then the same pose as a row-major 4×4, which we do not need):
//                                  T_world_body of every tracked body, the sensor apparatus too
//   vicon.yaml                     T_apparatus_left: the left stereo camera in the apparatus frame
//   kalibr.yaml                    cam0 (left), cam1, ...: intrinsics [fu, fv, pu, pv],
//                                  distortion_coeffs, resolution, rostopic, and for camN > 0
//                                  T_cn_cnm1 (maps points of camera n−1 into camera n)
// Read from the files' descriptions and the dataset authors' MATLAB tools; our own code.

// One camera of a Kalibr calibration.
struct KalibrCamera {
  std::string name;      // cam0, cam1, ...
  std::string rostopic;  // tells the cameras apart (e.g. .../color/image_raw)
  CameraOptions intrinsics;
  Eigen::Isometry3d T_cam0_cam = Eigen::Isometry3d::Identity();  // this camera in cam0's frame
};

// Reads kalibr.yaml, composing the chain of T_cn_cnm1 into each camera's pose in cam0.
// Throws Error naming the file and key for a missing or malformed entry.
std::vector<KalibrCamera> ReadKalibrCameras(const std::filesystem::path& path);

// Reads T_apparatus_left from vicon.yaml.
Eigen::Isometry3d ReadViconCalibration(const std::filesystem::path& path);

// Reads vicon.csv: one trajectory (T_world_body) per body name. Throws Error naming file and
// line for a short row, a non-number, a non-unit quaternion, or a body's rows out of time order.
std::map<std::string, Trajectory> ReadViconBodies(const std::filesystem::path& path);

struct OmdOptions {
  std::string apparatus_body = "sensor_payload";  // the Vicon body of the sensor apparatus
  // The RGB-D camera's name in kalibr.yaml; empty: the one whose rostopic names a colour image.
  std::string rgb_camera;
  double depth_factor = 1000.0;  // the RealSense's aligned depth is in millimetres
  // Vicon samples further apart than this around a frame leave the frame without ground truth.
  double max_ground_truth_gap = 0.05;
  void Check() const;
};

// T_world_rgb(t) = T_world_apparatus(t) · T_apparatus_left · T_left_rgb at each Vicon sample of
// the apparatus: the RGB camera's ground truth in the Vicon world.
Trajectory ComposeCameraTrajectory(const Trajectory& apparatus,
                                   const Eigen::Isometry3d& T_apparatus_left,
                                   const Eigen::Isometry3d& T_left_rgb);

struct OmdSequence {
  std::vector<RgbdFrameEntry> entries;
  CameraOptions camera;     // the RGB camera's intrinsics, with options.depth_factor
  Trajectory ground_truth;  // the RGB camera at each frame with Vicon around it
  std::map<std::string, Trajectory> bodies;  // every Vicon body except the apparatus
};

// Reads an OMD segment folder. Every listed frame needs its colour and depth image.
OmdSequence ReadOmdSequence(const std::filesystem::path& folder, const OmdOptions& options = {});

// Whether `folder` looks like an OMD segment (has rgbd/rgbd.csv).
bool IsOmdFolder(const std::filesystem::path& folder);

// Writes a TUM-layout sequence `tum` (as sdoslam synth writes it, with groundtruth.txt,
// camera.yaml and optionally object_poses.txt) in the OMD layout at `out`: images renamed
// (depth re-quantised to millimetres unless it already is), rgbd.csv, the camera chain
// (`T_apparatus_left` and a kalibr.yaml whose colour camera is cam2, behind a stereo pair), and
// vicon.csv with the apparatus and every object sampled at `vicon_rate_hz` between the frames.
// The given extrinsics are what a reader must undo to recover the camera's trajectory. Written
// to a staging folder and moved into place at the end: an existing non-empty `out` is an error
// unless `overwrite`, and is replaced only once the new segment is complete.
struct OmdWriteOptions {
  // A plausible apparatus: the left camera 5 cm below and 10 cm ahead of the Vicon body's
  // origin, turned from its z-up frame to the camera's z-forward one; an 11 cm stereo pair; the
  // colour camera 6 cm right of the right camera's centre, slightly turned.
  static OmdWriteOptions ExampleApparatus();
  double vicon_rate_hz = 200.0;
  Eigen::Isometry3d T_apparatus_left = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_cam1_cam0 = Eigen::Isometry3d::Identity();  // right stereo from left
  Eigen::Isometry3d T_cam2_cam1 = Eigen::Isometry3d::Identity();  // colour from right
};
// The kind in the marker of an OMD segment's folder that WriteOmdFromTum wrote.
inline constexpr char kOmdSegmentKind[] = "OMD segment";
void WriteOmdFromTum(const std::filesystem::path& tum, const std::filesystem::path& out,
                     const OmdWriteOptions& options, bool overwrite = false);

}  // namespace sdoslam
