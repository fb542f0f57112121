#include "sdoslam/io/omd.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/core/regular_file.h"
#include "sdoslam/core/text_file.h"
#include "sdoslam/core/yaml_file.h"
#include "sdoslam/io/output_folder.h"
#include "sdoslam/io/png_reader.h"

namespace sdoslam {
namespace {

YAML::Node LoadYaml(const std::filesystem::path& path) {
  if (!std::filesystem::exists(path)) throw Error(path.string() + " does not exist");
  const YAML::Node root = LoadYamlFile(path);
  if (!root.IsMap()) throw Error(path.string() + ": expected a YAML map of named entries");
  return root;
}

std::vector<double> Numbers(const YAML::Node& node, const std::filesystem::path& file,
                            const std::string& key, size_t count) {
  std::vector<double> out;
  try {
    if (!node || !node.IsSequence()) throw Error("");
    for (const YAML::Node& v : node) {
      if (v.IsSequence()) {
        for (const YAML::Node& w : v) out.push_back(w.as<double>());
      } else {
        out.push_back(v.as<double>());
      }
    }
  } catch (const std::exception&) {
    throw Error(file.string() + ": " + key + " must be a list of " + std::to_string(count) +
                " numbers");
  }
  if (out.size() != count ||
      !std::all_of(out.begin(), out.end(), [](double x) { return std::isfinite(x); })) {
    throw Error(file.string() + ": " + key + " must be a list of " + std::to_string(count) +
                " finite numbers");
  }
  return out;
}

// A rigid transform from a row-major 4×4 (nested or flat), checked to be one.
Eigen::Isometry3d Transform(const YAML::Node& node, const std::filesystem::path& file,
                            const std::string& key) {
  if (!node) throw Error(file.string() + ": " + key + " is missing");
  const std::vector<double> v = Numbers(node, file, key, 16);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = v[static_cast<size_t>(4 * r + c)];
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    throw Error(file.string() + ": " + key + " is not a rigid transform");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream in(line);
  std::string field;
  while (std::getline(in, field, ',')) {
    const auto first = field.find_first_not_of(" \t\r");
    const auto last = field.find_last_not_of(" \t\r");
    fields.push_back(first == std::string::npos ? "" : field.substr(first, last - first + 1));
  }
  return fields;
}

bool ParseNumber(const std::string& s, double* value) {
  if (s.empty()) return false;
  char* end = nullptr;
  *value = std::strtod(s.c_str(), &end);
  return end == s.c_str() + s.size() && std::isfinite(*value);
}

std::vector<std::string> ReadTextLines(const std::filesystem::path& path) {
  const std::optional<std::string> text = ReadRegularFileIfExists(path);
  if (!text) throw Error(path.string() + ": cannot open");
  std::istringstream in(*text);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// Lines of a CSV file with their numbers; a first line that is not numeric is a header.
struct CsvLine {
  int number;
  std::vector<std::string> fields;
};
std::vector<CsvLine> ReadCsv(const std::filesystem::path& path) {
  const std::vector<std::string> lines = ReadTextLines(path);
  std::vector<CsvLine> out;
  for (size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].find_first_not_of(" \t\r") == std::string::npos) continue;
    std::vector<std::string> fields = SplitCsv(lines[i]);
    double unused;
    if (out.empty() && i == 0 && !fields.empty() && !ParseNumber(fields[0], &unused)) continue;
    out.push_back({static_cast<int>(i + 1), std::move(fields)});
  }
  return out;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// kalibr.yaml and vicon.yaml sit in the segment folder, or once for all segments beside them.
std::filesystem::path Calibration(const std::filesystem::path& folder, const std::string& name) {
  for (const auto& candidate : {folder / name, folder.parent_path() / name}) {
    if (std::filesystem::exists(candidate)) return candidate;
  }
  throw Error(folder.string() + ": an OMD segment needs " + name + " (in the folder or beside it)");
}

}  // namespace

std::vector<KalibrCamera> ReadKalibrCameras(const std::filesystem::path& path) {
  const YAML::Node root = LoadYaml(path);
  std::vector<KalibrCamera> cameras;
  Eigen::Isometry3d T_previous_cam0 = Eigen::Isometry3d::Identity();
  for (size_t n = 0;; ++n) {
    const std::string name = "cam" + std::to_string(n);
    const YAML::Node node = root[name];
    if (!node) break;
    if (!node.IsMap()) throw Error(path.string() + ": " + name + " must be a map of its settings");
    KalibrCamera camera;
    camera.name = name;
    if (node["rostopic"]) camera.rostopic = node["rostopic"].as<std::string>("");
    const std::vector<double> k = Numbers(node["intrinsics"], path, name + ".intrinsics", 4);
    CameraOptions& o = camera.intrinsics;
    o.name = "OMD " + name + (camera.rostopic.empty() ? "" : " (" + camera.rostopic + ")");
    o.fx = k[0];
    o.fy = k[1];
    o.cx = k[2];
    o.cy = k[3];
    const std::vector<double> size = Numbers(node["resolution"], path, name + ".resolution", 2);
    o.width = static_cast<int>(size[0]);
    o.height = static_cast<int>(size[1]);
    const std::string model =
        node["distortion_model"] ? node["distortion_model"].as<std::string>("") : "none";
    if (model == "radtan") {
      const std::vector<double> d =
          Numbers(node["distortion_coeffs"], path, name + ".distortion_coeffs", 4);
      o.k1 = d[0];
      o.k2 = d[1];
      o.p1 = d[2];
      o.p2 = d[3];
    } else if (model != "none") {
      throw Error(path.string() + ": " + name + ".distortion_model '" + model +
                  "' is not supported (radtan or none)");
    }
    if (n > 0) {
      const Eigen::Isometry3d T_cn_cnm1 = Transform(node["T_cn_cnm1"], path, name + ".T_cn_cnm1");
      T_previous_cam0 = T_cn_cnm1 * T_previous_cam0;  // now T_cn_c0
    }
    camera.T_cam0_cam = T_previous_cam0.inverse();
    cameras.push_back(std::move(camera));
  }
  if (cameras.empty()) throw Error(path.string() + ": no cam0 entry");
  return cameras;
}

Eigen::Isometry3d ReadViconCalibration(const std::filesystem::path& path) {
  const YAML::Node root = LoadYaml(path);
  return Transform(root["T_apparatus_left"], path, "T_apparatus_left");
}

std::map<std::string, Trajectory> ReadViconBodies(const std::filesystem::path& path) {
  std::map<std::string, Trajectory> bodies;
  for (const CsvLine& line : ReadCsv(path)) {
    const std::string where = path.string() + ":" + std::to_string(line.number);
    if (line.fields.size() < 10) {
      throw Error(where +
                  ": expected time_sec, time_nsec, object, qx, qy, qz, qw, tx, ty, tz; "
                  "found " +
                  std::to_string(line.fields.size()) + " fields");
    }
    double v[10];
    for (size_t c = 0; c < 10; ++c) {
      if (c == 2) continue;
      if (!ParseNumber(line.fields[c], &v[c]))
        throw Error(where + ": field " + std::to_string(c + 1) + " ('" + line.fields[c] +
                    "') is not a finite number");
    }
    const std::string& body = line.fields[2];
    if (body.empty()) throw Error(where + ": empty object name");
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    const double norm = q.norm();
    if (std::abs(norm - 1.0) > 1e-2)
      throw Error(where + fmt::format(": quaternion norm {:.4f} is not 1", norm));
    StampedPose pose;
    pose.timestamp = v[0] + v[1] * 1e-9;
    pose.T_world_camera.linear() = q.normalized().toRotationMatrix();
    pose.T_world_camera.translation() = Eigen::Vector3d(v[7], v[8], v[9]);
    Trajectory& trajectory = bodies[body];
    if (!trajectory.empty() && pose.timestamp <= trajectory.back().timestamp)
      throw Error(where + ": rows of '" + body + "' out of time order");
    trajectory.push_back(pose);
  }
  if (bodies.empty()) throw Error(path.string() + ": no Vicon rows");
  return bodies;
}

void OmdOptions::Check() const {
  if (apparatus_body.empty()) throw Error("omd.apparatus_body must not be empty");
  if (!(depth_factor > 0)) throw Error("omd.depth_factor must be positive");
  if (!(max_ground_truth_gap > 0)) throw Error("omd.max_ground_truth_gap must be positive");
}

Trajectory ComposeCameraTrajectory(const Trajectory& apparatus,
                                   const Eigen::Isometry3d& T_apparatus_left,
                                   const Eigen::Isometry3d& T_left_rgb) {
  const Eigen::Isometry3d T_apparatus_rgb = T_apparatus_left * T_left_rgb;
  Trajectory out;
  out.reserve(apparatus.size());
  for (const StampedPose& p : apparatus)
    out.push_back({p.timestamp, p.T_world_camera * T_apparatus_rgb});
  return out;
}

bool IsOmdFolder(const std::filesystem::path& folder) {
  return std::filesystem::exists(folder / "rgbd" / "rgbd.csv");
}

OmdSequence ReadOmdSequence(const std::filesystem::path& folder, const OmdOptions& options) {
  options.Check();
  const std::filesystem::path list = folder / "rgbd" / "rgbd.csv";
  if (!std::filesystem::exists(list))
    throw Error(folder.string() + ": not an OMD segment (no rgbd/rgbd.csv)");
  OmdSequence sequence;
  for (const CsvLine& line : ReadCsv(list)) {
    const std::string where = list.string() + ":" + std::to_string(line.number);
    double v[3];
    if (line.fields.size() < 3 || !ParseNumber(line.fields[0], &v[0]) ||
        !ParseNumber(line.fields[1], &v[1]) || !ParseNumber(line.fields[2], &v[2]) || v[0] < 0 ||
        v[0] != std::floor(v[0])) {
      throw Error(where + ": expected frame_num, time_sec, time_nsec");
    }
    RgbdFrameEntry entry;
    entry.timestamp = entry.depth_timestamp = v[1] + v[2] * 1e-9;
    const std::string stem = fmt::format("{:06d}", static_cast<long long>(v[0]));
    entry.rgb_path = folder / "rgbd" / (stem + "_color.png");
    entry.depth_path = folder / "rgbd" / (stem + "_aligned_depth.png");
    for (const auto& path : {entry.rgb_path, entry.depth_path}) {
      if (!std::filesystem::exists(path))
        throw Error(where + ": frame " + stem + " lists " + path.filename().string() +
                    ", which does not exist");
    }
    if (!sequence.entries.empty() && entry.timestamp <= sequence.entries.back().timestamp)
      throw Error(where + ": timestamps do not increase");
    sequence.entries.push_back(std::move(entry));
  }
  if (sequence.entries.empty()) throw Error(list.string() + ": no frames");

  const std::filesystem::path kalibr = Calibration(folder, "kalibr.yaml");
  const std::vector<KalibrCamera> cameras = ReadKalibrCameras(kalibr);
  const KalibrCamera* rgb = nullptr;
  std::string known;
  for (const KalibrCamera& c : cameras) {
    known += (known.empty() ? "" : ", ") + c.name + " (" + c.rostopic + ")";
    const bool chosen = options.rgb_camera.empty()
                            ? Lower(c.rostopic).find("color") != std::string::npos ||
                                  Lower(c.rostopic).find("rgb") != std::string::npos
                            : c.name == options.rgb_camera;
    if (!chosen) continue;
    if (rgb != nullptr)
      throw Error(kalibr.string() + ": more than one colour camera; choose one (" + known + ")");
    rgb = &c;
  }
  if (rgb == nullptr) {
    throw Error(kalibr.string() + ": no camera " +
                (options.rgb_camera.empty() ? "whose rostopic names a colour image"
                                            : "named '" + options.rgb_camera + "'") +
                " (cameras: " + known + ")");
  }
  sequence.camera = rgb->intrinsics;
  sequence.camera.depth_factor = options.depth_factor;

  const std::filesystem::path vicon = folder / "vicon.csv";
  if (!std::filesystem::exists(vicon)) return sequence;  // frames without ground truth
  const Eigen::Isometry3d T_apparatus_left =
      ReadViconCalibration(Calibration(folder, "vicon.yaml"));
  sequence.bodies = ReadViconBodies(vicon);
  const auto apparatus = sequence.bodies.find(options.apparatus_body);
  if (apparatus == sequence.bodies.end()) {
    std::string names;
    for (const auto& [name, unused] : sequence.bodies) names += (names.empty() ? "" : ", ") + name;
    throw Error(vicon.string() + ": no body '" + options.apparatus_body + "' (bodies: " + names +
                ")");
  }
  const Trajectory camera_at_vicon =
      ComposeCameraTrajectory(apparatus->second, T_apparatus_left, rgb->T_cam0_cam);
  sequence.bodies.erase(apparatus);
  for (const RgbdFrameEntry& entry : sequence.entries) {
    if (auto T = InterpolatePose(camera_at_vicon, entry.timestamp, options.max_ground_truth_gap))
      sequence.ground_truth.push_back({entry.timestamp, *T});
  }
  return sequence;
}

namespace {

void WriteTransform(YAML::Emitter& y, const Eigen::Isometry3d& T) {
  y << YAML::BeginSeq;
  const Eigen::Matrix4d m = T.matrix();
  for (int r = 0; r < 4; ++r) {
    y << YAML::Flow << YAML::BeginSeq;
    for (int c = 0; c < 4; ++c) y << m(r, c);
    y << YAML::EndSeq;
  }
  y << YAML::EndSeq;
}

// Body poses sampled at `times`, interpolated from `trajectory` where it covers them.
void AddViconRows(const std::string& body, const Trajectory& trajectory,
                  const std::vector<double>& times,
                  std::vector<std::pair<double, std::string>>* rows) {
  for (double t : times) {
    const auto T = InterpolatePose(trajectory, t, 1.0);
    if (!T) continue;
    const Eigen::Quaterniond q(T->linear());
    const Eigen::Vector3d p = T->translation();
    const long long sec = static_cast<long long>(std::floor(t));
    const long long nsec = std::llround((t - static_cast<double>(sec)) * 1e9);
    std::string row = fmt::format("{},{},{},{:.12f},{:.12f},{:.12f},{:.12f},{:.9f},{:.9f},{:.9f}",
                                  sec, nsec, body, q.x(), q.y(), q.z(), q.w(), p.x(), p.y(), p.z());
    const Eigen::Matrix4d m = T->matrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) row += fmt::format(",{:.12f}", m(r, c));
    rows->emplace_back(t, row + "\n");
  }
}

// rgbd/: the frames as OMD names them (depth in millimetres) and rgbd.csv.
void WriteOmdFrames(const TumDataset& dataset, const CameraOptions& camera,
                    const std::filesystem::path& staging) {
  std::string list = "frame_num,time_sec,time_nsec\n";
  for (size_t k = 0; k < dataset.size(); ++k) {
    const RgbdFrameEntry& e = dataset.entries()[k];
    const std::string stem = fmt::format("{:06d}", k + 1);
    std::filesystem::copy_file(e.rgb_path, staging / "rgbd" / (stem + "_color.png"));
    const std::filesystem::path depth = staging / "rgbd" / (stem + "_aligned_depth.png");
    if (camera.depth_factor == 1000.0) {
      std::filesystem::copy_file(e.depth_path, depth);
    } else {
      const cv::Mat raw = ReadImage(e.depth_path, cv::IMREAD_UNCHANGED);
      if (raw.type() != CV_16UC1) throw Error(e.depth_path.string() + ": not 16-bit depth");
      cv::Mat millimetres;
      raw.convertTo(millimetres, CV_16UC1, 1000.0 / camera.depth_factor);
      if (!cv::imwrite(depth.string(), millimetres)) throw Error(depth.string() + ": cannot write");
    }
    const long long sec = static_cast<long long>(std::floor(e.timestamp));
    list += fmt::format("{},{},{}\n", k + 1, sec,
                        std::llround((e.timestamp - static_cast<double>(sec)) * 1e9));
  }
  WriteFileAtomically(staging / "rgbd" / "rgbd.csv", [&](std::ostream& o) { o << list; });
}

// kalibr.yaml (the camera chain: left stereo cam0, right stereo cam1, colour cam2) and
// vicon.yaml.
void WriteOmdCalibration(const CameraOptions& camera, const OmdWriteOptions& options,
                         const std::filesystem::path& staging) {
  YAML::Emitter kalibr;
  kalibr << YAML::BeginMap;
  for (int n = 0; n < 3; ++n) {
    kalibr << YAML::Key << "cam" + std::to_string(n) << YAML::Value << YAML::BeginMap;
    if (n > 0) {
      kalibr << YAML::Key << "T_cn_cnm1" << YAML::Value;
      WriteTransform(kalibr, n == 1 ? options.T_cam1_cam0 : options.T_cam2_cam1);
    }
    kalibr << YAML::Key << "camera_model" << YAML::Value << "pinhole";
    kalibr << YAML::Key << "distortion_model" << YAML::Value << "radtan";
    kalibr << YAML::Key << "distortion_coeffs" << YAML::Value << YAML::Flow << YAML::BeginSeq
           << (n == 2 ? camera.k1 : 0.0) << (n == 2 ? camera.k2 : 0.0) << (n == 2 ? camera.p1 : 0.0)
           << (n == 2 ? camera.p2 : 0.0) << YAML::EndSeq;
    kalibr << YAML::Key << "intrinsics" << YAML::Value << YAML::Flow << YAML::BeginSeq
           << YAML::Precision(17) << camera.fx << camera.fy << camera.cx << camera.cy
           << YAML::EndSeq;
    kalibr << YAML::Key << "resolution" << YAML::Value << YAML::Flow << YAML::BeginSeq
           << camera.width << camera.height << YAML::EndSeq;
    kalibr << YAML::Key << "rostopic" << YAML::Value
           << (n == 0   ? "/stereo/left/image_raw"
               : n == 1 ? "/stereo/right/image_raw"
                        : "/camera/color/image_raw");
    kalibr << YAML::EndMap;
  }
  kalibr << YAML::EndMap;
  WriteFileAtomically(staging / "kalibr.yaml",
                      [&](std::ostream& o) { o << kalibr.c_str() << '\n'; });
  YAML::Emitter vicon_yaml;
  vicon_yaml << YAML::BeginMap << YAML::Key << "T_apparatus_left" << YAML::Value
             << YAML::Precision(17);
  WriteTransform(vicon_yaml, options.T_apparatus_left);
  vicon_yaml << YAML::EndMap;
  WriteFileAtomically(staging / "vicon.yaml",
                      [&](std::ostream& o) { o << vicon_yaml.c_str() << '\n'; });
}

// vicon.csv: the apparatus (from the camera's ground truth) and each object of
// object_poses.txt, at the Vicon rate.
void WriteOmdVicon(const std::filesystem::path& tum, const Trajectory& ground_truth,
                   const OmdWriteOptions& options, const std::filesystem::path& staging) {
  const Eigen::Isometry3d T_left_rgb = (options.T_cam2_cam1 * options.T_cam1_cam0).inverse();
  // Vicon samples from the first frame to the last at the Vicon rate, and the last frame.
  std::vector<double> times;
  const double first = ground_truth.front().timestamp, last = ground_truth.back().timestamp;
  for (double t = first; t < last;
       t = first + static_cast<double>(times.size()) / options.vicon_rate_hz)
    times.push_back(t);
  times.push_back(last);
  Trajectory apparatus;
  const Eigen::Isometry3d T_rgb_apparatus = (options.T_apparatus_left * T_left_rgb).inverse();
  for (const StampedPose& p : ground_truth)
    apparatus.push_back({p.timestamp, p.T_world_camera * T_rgb_apparatus});
  std::vector<std::pair<double, std::string>> rows;
  AddViconRows("sensor_payload", apparatus, times, &rows);
  const std::filesystem::path objects_file = tum / "object_poses.txt";
  if (std::filesystem::exists(objects_file)) {
    const std::map<int, Trajectory> objects = ReadObjectPoses(objects_file);
    for (const auto& [id, trajectory] : objects)
      AddViconRows("object_" + std::to_string(id), trajectory, times, &rows);
  }
  std::stable_sort(rows.begin(), rows.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  WriteFileAtomically(staging / "vicon.csv", [&](std::ostream& o) {
    o << "time_sec,time_nsec,object,rot_x,rot_y,rot_z,rot_w,trans_x,trans_y,trans_z,"
         "m11,m12,m13,m14,m21,m22,m23,m24,m31,m32,m33,m34,m41,m42,m43,m44\n";
    for (const auto& [t, row] : rows) o << row;
  });
}

}  // namespace

OmdWriteOptions OmdWriteOptions::ExampleApparatus() {
  OmdWriteOptions o;
  o.T_apparatus_left.linear() = (Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitZ()) *
                                 Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitX()))
                                    .toRotationMatrix();
  o.T_apparatus_left.translation() = Eigen::Vector3d(0.10, 0.0, -0.05);
  o.T_cam1_cam0.translation() = Eigen::Vector3d(-0.11, 0, 0);
  o.T_cam2_cam1.linear() = Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitY()).toRotationMatrix();
  o.T_cam2_cam1.translation() = Eigen::Vector3d(-0.06, 0.004, 0.002);
  return o;
}

void WriteOmdFromTum(const std::filesystem::path& tum, const std::filesystem::path& out,
                     const OmdWriteOptions& options, bool overwrite) {
  if (!(options.vicon_rate_hz > 0)) throw Error("vicon_rate_hz must be positive");
  const CameraOptions camera = LoadCameraConfig(tum / "camera.yaml");
  const TumDataset dataset(tum, camera);
  const Trajectory ground_truth = ReadTumTrajectory(tum / "groundtruth.txt");
  OutputFolderOptions folder_options;
  folder_options.kind = kOmdSegmentKind;
  folder_options.overwrite = overwrite;
  folder_options.inputs = {tum};
  OutputFolder folder(out, folder_options);
  const std::filesystem::path& staging = folder.staging();
  std::filesystem::create_directories(staging / "rgbd");

  WriteOmdFrames(dataset, camera, staging);
  WriteOmdCalibration(camera, options, staging);
  WriteOmdVicon(tum, ground_truth, options, staging);
  folder.Commit();
}

}  // namespace sdoslam
