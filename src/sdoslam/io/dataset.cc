#include "sdoslam/io/dataset.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <opencv2/imgcodecs.hpp>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/image_header.h"
#include "sdoslam/io/output_folder.h"
#include "sdoslam/io/png_reader.h"

namespace sdoslam {

namespace {

// The dataset's intrinsics with the run config's depth, rate and shutter settings.
CameraOptions WithDepthSettings(CameraOptions intrinsics, const CameraOptions& config) {
  intrinsics.readout_s = config.readout_s;
  intrinsics.depth_factor = config.depth_factor;
  intrinsics.depth_min = config.depth_min;
  intrinsics.depth_max = config.depth_max;
  intrinsics.fps = config.fps;
  intrinsics.from_dataset = false;
  return intrinsics;
}

}  // namespace

const char* ToString(DatasetLayout layout) {
  switch (layout) {
    case DatasetLayout::kAuto:
      return "auto";
    case DatasetLayout::kTum:
      return "tum";
    case DatasetLayout::kOmd:
      return "omd";
    case DatasetLayout::kBonn:
      return "bonn";
  }
  return "?";
}

DatasetLayout ParseDatasetLayout(const std::string& name) {
  for (DatasetLayout l :
       {DatasetLayout::kAuto, DatasetLayout::kTum, DatasetLayout::kOmd, DatasetLayout::kBonn}) {
    if (name == ToString(l)) return l;
  }
  throw Error("unknown layout '" + name + "' (known: auto, tum, omd, bonn)");
}

Trajectory BonnCameraTrajectory(const Trajectory& markers) {
  Eigen::Matrix4d ros;
  ros << -1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 1;
  Eigen::Matrix4d m;
  m << 1.0157, 0.1828, -0.2389, 0.0113, 0.0009, -0.8431, -0.6413, -0.0098, -0.3009, 0.6147, -0.8085,
      0.0111, 0, 0, 0, 1;
  // The nearest rotation to the scaled block: U·Vᵀ of its SVD.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(m.topLeftCorner<3, 3>(),
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Isometry3d T_ros(ros), T_m = Eigen::Isometry3d::Identity();
  T_m.linear() = svd.matrixU() * svd.matrixV().transpose();
  T_m.translation() = m.topRightCorner<3, 1>();
  Trajectory out;
  out.reserve(markers.size());
  for (const StampedPose& p : markers)
    out.push_back({p.timestamp, T_ros * p.T_world_camera * T_ros * T_m});
  return out;
}

DatasetLayout DetectLayout(const std::filesystem::path& folder) {
  if (!std::filesystem::is_directory(folder)) throw Error(folder.string() + ": no such folder");
  const bool rgb = std::filesystem::exists(folder / "rgb.txt");
  const bool depth = std::filesystem::exists(folder / "depth.txt");
  const bool omd = IsOmdFolder(folder);
  if ((rgb || depth) && omd) {
    throw Error(folder.string() +
                ": has both TUM lists (rgb.txt, depth.txt) and an OMD rgbd/rgbd.csv; choose one "
                "with --layout tum|omd");
  }
  if (omd) return DatasetLayout::kOmd;
  if (rgb && depth) {
    const std::filesystem::path normal = std::filesystem::absolute(folder).lexically_normal();
    const std::string name = normal.filename().string();
    const std::string parent_name = normal.parent_path().filename().string();
    const bool bonn = name.rfind("rgbd_bonn_", 0) == 0 ||
                      (name.empty() && parent_name.rfind("rgbd_bonn_", 0) == 0);
    return bonn ? DatasetLayout::kBonn : DatasetLayout::kTum;
  }
  if (rgb || depth) {
    throw Error(folder.string() + ": a TUM sequence needs both rgb.txt and depth.txt; " +
                (rgb ? "depth.txt" : "rgb.txt") + " is missing");
  }
  throw Error(folder.string() +
              ": not a sequence folder: expected rgb.txt and depth.txt (TUM, Bonn, sdoslam "
              "synth) or rgbd/rgbd.csv (Oxford Multi-motion)");
}

void DatasetOptions::Check() const {
  tum.Check();
  omd.Check();
}

RgbdDataset::RgbdDataset(const std::filesystem::path& folder, const CameraOptions& camera,
                         const DatasetOptions& options)
    : folder_(folder), camera_(camera) {
  options.Check();
  layout_ = options.layout == DatasetLayout::kAuto ? DetectLayout(folder) : options.layout;
  if (layout_ == DatasetLayout::kOmd) {
    const OmdSequence omd = ReadOmdSequence(folder, options.omd);
    if (camera.from_dataset) camera_ = WithDepthSettings(omd.camera, camera);
    entries_ = omd.entries;
    if (!omd.ground_truth.empty()) ground_truth_ = omd.ground_truth;
    bodies_ = omd.bodies;
  } else {
    if (camera.from_dataset) {
      const std::filesystem::path own = folder / "camera.yaml";
      if (!std::filesystem::exists(own)) {
        throw Error(folder.string() +
                    ": camera.from_dataset needs the dataset's calibration, and this TUM folder "
                    "has no camera.yaml; give the camera's intrinsics in the config");
      }
      camera_ = WithDepthSettings(LoadCameraConfig(own), camera);
    }
    const TumDataset tum(folder, camera_, options.tum);
    entries_ = tum.entries();
    if (std::filesystem::exists(folder / "groundtruth.txt")) {
      ground_truth_ = ReadTumTrajectory(folder / "groundtruth.txt");
      if (layout_ == DatasetLayout::kBonn) ground_truth_ = BonnCameraTrajectory(*ground_truth_);
    }
  }
  camera_.from_dataset = false;
  camera_.Check();
}

RgbdFrame RgbdDataset::Load(size_t index) const {
  if (index >= entries_.size()) {
    throw Error("frame " + std::to_string(index) + " out of range (" +
                std::to_string(entries_.size()) + " frames)");
  }
  return LoadRgbdFrame(entries_[index], index, camera_);
}

RgbdFrame LoadRgbdFrame(const RgbdFrameEntry& entry, size_t index, const CameraOptions& camera) {
  RgbdFrame frame;
  frame.index = index;
  frame.timestamp = entry.timestamp;
  frame.depth_timestamp = entry.depth_timestamp;
  frame.rgb_path = entry.rgb_path;

  auto check_size = [&](cv::Size size, const std::filesystem::path& path) {
    if (size.width != camera.width || size.height != camera.height) {
      throw Error(path.string() + ": image is " + std::to_string(size.width) + "x" +
                  std::to_string(size.height) + ", the camera config says " +
                  std::to_string(camera.width) + "x" + std::to_string(camera.height));
    }
  };

  // A PNG of the wrong size is refused from its header, before it is decoded.
  for (const auto& path : {entry.rgb_path, entry.depth_path}) {
    if (const std::optional<PngHeader> header = TryReadPngHeader(path)) {
      check_size(cv::Size(header->width, header->height), path);
      // Decoding as colour would quietly scale a 16-bit image (a depth image listed in rgb.txt)
      // to 8 bits and track on it.
      if (path == entry.rgb_path && header->bit_depth == 16) {
        throw Error(path.string() +
                    ": a 16-bit PNG; a colour frame must be an 8-bit colour image (is it a depth "
                    "image?)");
      }
    }
  }
  frame.bgr = ReadImage(entry.rgb_path, cv::IMREAD_COLOR);
  if (frame.bgr.empty()) throw Error(entry.rgb_path.string() + ": cannot decode image");
  check_size(frame.bgr.size(), entry.rgb_path);

  const cv::Mat raw = ReadImage(entry.depth_path, cv::IMREAD_UNCHANGED);
  if (raw.empty()) throw Error(entry.depth_path.string() + ": cannot decode image");
  if (raw.type() != CV_16UC1) {
    throw Error(entry.depth_path.string() + ": depth must be a 16-bit single-channel PNG, found " +
                std::to_string(raw.elemSize1() * 8) + "-bit with " +
                std::to_string(raw.channels()) + " channel(s)");
  }
  check_size(raw.size(), entry.depth_path);
  raw.convertTo(frame.depth, CV_32F, 1.0 / camera.depth_factor);
  // Outside the sensor's range a reading is noise; zero means "no depth" everywhere downstream.
  cv::Mat out_of_range = (frame.depth < camera.depth_min) | (frame.depth > camera.depth_max);
  frame.depth.setTo(0.0f, out_of_range);
  return frame;
}

void WriteTumCopy(const RgbdDataset& dataset, const std::filesystem::path& out, bool overwrite) {
  OutputFolderOptions folder_options;
  folder_options.kind = "TUM copy";
  folder_options.overwrite = overwrite;
  folder_options.inputs = {dataset.folder()};
  // Frames may be listed from outside the folder: writing over any of them is refused too.
  for (const RgbdFrameEntry& e : dataset.entries()) {
    for (const auto& image : {e.rgb_path.parent_path(), e.depth_path.parent_path()}) {
      if (std::find(folder_options.inputs.begin(), folder_options.inputs.end(), image) ==
          folder_options.inputs.end())
        folder_options.inputs.push_back(image);
    }
  }
  OutputFolder folder(out, folder_options);
  const std::filesystem::path& staging = folder.staging();
  std::filesystem::create_directories(staging / "rgb");
  std::filesystem::create_directories(staging / "depth");
  std::string rgb = "# color images\n# timestamp filename\n";
  std::string depth = "# depth maps\n# timestamp filename\n";
  for (const RgbdFrameEntry& e : dataset.entries()) {
    const std::string rgb_name = fmt::format("rgb/{:.6f}.png", e.timestamp);
    const std::string depth_name = fmt::format("depth/{:.6f}.png", e.depth_timestamp);
    std::filesystem::copy_file(e.rgb_path, staging / rgb_name);
    std::filesystem::copy_file(e.depth_path, staging / depth_name);
    rgb += fmt::format("{:.6f} {}\n", e.timestamp, rgb_name);
    depth += fmt::format("{:.6f} {}\n", e.depth_timestamp, depth_name);
  }
  WriteFileAtomically(staging / "rgb.txt", [&](std::ostream& o) { o << rgb; });
  WriteFileAtomically(staging / "depth.txt", [&](std::ostream& o) { o << depth; });
  YAML::Emitter camera;
  camera << YAML::BeginMap;
  WriteCameraOptions(dataset.camera(), &camera);
  camera << YAML::EndMap;
  WriteFileAtomically(staging / "camera.yaml",
                      [&](std::ostream& o) { o << camera.c_str() << '\n'; });
  if (dataset.ground_truth())
    WriteTumTrajectory(staging / "groundtruth.txt", *dataset.ground_truth());
  if (!dataset.bodies().empty()) {
    std::filesystem::create_directories(staging / "bodies");
    for (const auto& [name, trajectory] : dataset.bodies())
      WriteTumTrajectory(staging / "bodies" / (name + ".txt"), trajectory);
  }
  folder.Commit();
}

}  // namespace sdoslam
