#include "sdoslam/io/trajectory.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/text_file.h"

namespace sdoslam {

std::optional<Eigen::Isometry3d> InterpolatePose(const Trajectory& trajectory, double timestamp,
                                                 double max_gap) {
  const auto after =
      std::lower_bound(trajectory.begin(), trajectory.end(), timestamp,
                       [](const StampedPose& pose, double t) { return pose.timestamp < t; });
  if (after == trajectory.end()) return std::nullopt;
  if (after->timestamp == timestamp) return after->T_world_camera;
  if (after == trajectory.begin()) return std::nullopt;
  const StampedPose& a = *(after - 1);
  const StampedPose& b = *after;
  if (timestamp - a.timestamp > max_gap || b.timestamp - timestamp > max_gap) return std::nullopt;
  const double s = (timestamp - a.timestamp) / (b.timestamp - a.timestamp);
  const Eigen::Quaterniond qa(a.T_world_camera.linear()), qb(b.T_world_camera.linear());
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = qa.slerp(s, qb).toRotationMatrix();
  T.translation() = (1 - s) * a.T_world_camera.translation() + s * b.T_world_camera.translation();
  return T;
}

std::map<int, Trajectory> ReadObjectPoses(const std::filesystem::path& path) {
  std::map<int, Trajectory> objects;
  ForEachDataLine(path, [&](int number, const std::vector<std::string>& tokens) {
    if (tokens.size() != 9)
      throw Error(Where(path, number) + "expected timestamp id tx ty tz qx qy qz qw");
    double v[9];
    for (size_t c = 0; c < 9; ++c) v[c] = ParseDouble(tokens[c], path, number, "value");
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(v[8], v[5], v[6], v[7]).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(v[2], v[3], v[4]);
    objects[static_cast<int>(v[1])].push_back({v[0], T});
  });
  for (auto& [id, trajectory] : objects) {
    std::stable_sort(
        trajectory.begin(), trajectory.end(),
        [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  }
  return objects;
}

// A TUM line's columns.
constexpr const char* kNames[] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};

void AppendTumPose(const double (&v)[8], const TrajectoryReadOptions& options, const char* unit,
                   Trajectory* trajectory) {
  for (int k = 1; k <= 3; ++k) {
    if (std::abs(v[k]) > options.max_abs_position) {
      throw Error(fmt::format("{} is {:g} m (more than {:g} m from the origin: not a position)",
                              kNames[k], v[k], options.max_abs_position));
    }
  }
  Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > options.quaternion_norm_tolerance) {
    throw Error("quaternion norm is " + std::to_string(norm) +
                ", not 1 (is the column order qx qy qz qw?)");
  }
  if (!trajectory->empty() && v[0] <= trajectory->back().timestamp) {
    throw Error(fmt::format("timestamp {:.6f} does not increase over the {} before", v[0], unit));
  }
  StampedPose pose;
  pose.timestamp = v[0];
  pose.T_world_camera.linear() = q.normalized().toRotationMatrix();
  pose.T_world_camera.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
  trajectory->push_back(pose);
}

Trajectory ReadTumTrajectory(const std::filesystem::path& path,
                             const TrajectoryReadOptions& options) {
  Trajectory trajectory;
  ForEachDataLine(path, [&](int line, const std::vector<std::string>& tokens) {
    if (tokens.size() != 8) {
      throw Error(Where(path, line) +
                  "expected 8 columns (timestamp tx ty tz qx qy qz qw), found " +
                  std::to_string(tokens.size()));
    }
    double v[8];
    v[0] = ParseTimestamp(tokens[0], path, line, kNames[0]);
    for (int k = 1; k < 8; ++k) v[k] = ParseDouble(tokens[k], path, line, kNames[k]);
    try {
      AppendTumPose(v, options, "line", &trajectory);
    } catch (const Error& e) {
      throw Error(Where(path, line) + e.what());
    }
  });
  return trajectory;
}

void WriteTumTrajectory(const std::filesystem::path& path, const Trajectory& trajectory) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    out << "# timestamp tx ty tz qx qy qz qw\n";
    char buffer[256];
    for (const StampedPose& pose : trajectory) {
      const Eigen::Quaterniond q(pose.T_world_camera.rotation());
      const Eigen::Vector3d t = pose.T_world_camera.translation();
      std::snprintf(buffer, sizeof(buffer), "%.6f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
                    pose.timestamp, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
      out << buffer;
    }
  });
}

void WriteKittiTrajectory(const std::filesystem::path& path, const Trajectory& trajectory) {
  WriteFileAtomically(path, [&](std::ostream& out) {
    char buffer[64];
    for (const StampedPose& pose : trajectory) {
      const Eigen::Matrix<double, 3, 4> m = pose.T_world_camera.matrix().topRows<3>();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
          std::snprintf(buffer, sizeof(buffer), "%.9e", m(r, c));
          out << buffer << (r == 2 && c == 3 ? '\n' : ' ');
        }
      }
    }
  });
}

}  // namespace sdoslam
