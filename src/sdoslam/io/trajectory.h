#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <map>
#include <optional>
#include <vector>

namespace sdoslam {

// A camera pose at a time: T_world_camera maps points from the camera frame to the world frame
// (the TUM convention: translation is the camera centre in the world).
struct StampedPose {
  double timestamp = 0.0;  // seconds
  Eigen::Isometry3d T_world_camera = Eigen::Isometry3d::Identity();
};

using Trajectory = std::vector<StampedPose>;

struct TrajectoryReadOptions {
  // Quaternions whose norm differs from 1 by less than this are normalised; larger deviations
  // are errors (they mean a broken writer, not rounding).
  double quaternion_norm_tolerance = 1e-2;
  // Positions farther than this from the origin (metres) are errors: no indoor or outdoor
  // sequence reaches them, and squares of 1e308 overflow the error statistics to inf.
  double max_abs_position = 1e6;
};

// Appends the pose `values` (timestamp tx ty tz qx qy qz qw) to `trajectory`, its quaternion
// normalised, after the checks ReadTumTrajectory makes of each line: no absurd position, a
// quaternion of norm 1 within the tolerance, a timestamp after the last one. Throws Error saying
// what is wrong (the caller names where); `unit` ("line", "row") names the entry before.
void AppendTumPose(const double (&values)[8], const TrajectoryReadOptions& options,
                   const char* unit, Trajectory* trajectory);

// Reads a TUM trajectory (`timestamp tx ty tz qx qy qz qw`, '#' comments). Throws Error naming
// file and line for a wrong column count, a non-number or NaN, an absurd position, a bad
// quaternion, or timestamps that are absurd (ParseTimestamp) or do not increase.
Trajectory ReadTumTrajectory(const std::filesystem::path& path,
                             const TrajectoryReadOptions& options = {});

// The pose at `timestamp`, interpolated between the two samples around it (linear in position,
// slerp in rotation), or nullopt when the timestamp lies outside the trajectory or either
// neighbour is more than `max_gap` seconds away (motion capture drop-outs). The trajectory
// must be sorted by time, as ReadTumTrajectory returns it.
std::optional<Eigen::Isometry3d> InterpolatePose(const Trajectory& trajectory, double timestamp,
                                                 double max_gap);

// Object poses as sdoslam synth writes them (object_poses.txt: "timestamp id tx ty tz qx qy qz
// qw" per line, T_world_object), by object id, each in time order. Throws Error naming the file
// and line of a malformed row.
std::map<int, Trajectory> ReadObjectPoses(const std::filesystem::path& path);

// Writes TUM format, timestamps with microsecond precision; atomically (see atomic_file.h).
void WriteTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);

// Writes KITTI format: the 3x4 matrix [R|t] of each pose, row-major, one pose a line.
// (KITTI has no timestamps; write TUM alongside when they matter.)
void WriteKittiTrajectory(const std::filesystem::path& path, const Trajectory& trajectory);

}  // namespace sdoslam
