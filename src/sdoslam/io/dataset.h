#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "sdoslam/core/camera.h"
#include "sdoslam/io/omd.h"
#include "sdoslam/io/trajectory.h"
#include "sdoslam/io/tum_dataset.h"

namespace sdoslam {

// The folder layouts `sdoslam run` reads as published.
enum class DatasetLayout {
  kAuto,  // recognised by its files
  kTum,   // TUM RGB-D, also Bonn RGB-D Dynamic and `sdoslam synth` output
  kOmd,   // Oxford Multi-motion Dataset segment
  // Bonn RGB-D Dynamic: the TUM layout, but its groundtruth.txt is the motion-capture markers'
  // pose, which BonnCameraTrajectory brings to the camera. Auto-detected by the dataset's folder
  // names (rgbd_bonn_*).
  kBonn,
};
const char* ToString(DatasetLayout layout);
DatasetLayout ParseDatasetLayout(const std::string& name);  // throws naming the known ones

// The camera's trajectory from a Bonn RGB-D Dynamic groundtruth.txt (the markers'), with the
// transforms the dataset's page gives: T_camera = T_ros · T_marker · T_ros · T_m, where T_ros is
// a fixed axis change and T_m the marker-to-camera calibration. The published T_m's 3×3 block
// is a rotation scaled by 1.06 (its rows are orthogonal, each of norm 1.059); we take its
// rotation (the nearest orthonormal matrix), so that poses stay rigid.
Trajectory BonnCameraTrajectory(const Trajectory& markers);

// The layout of `folder` by its files: rgb.txt + depth.txt (TUM; Bonn when the folder is named
// rgbd_bonn_*) or rgbd/rgbd.csv (OMD). Throws
// Error naming what is missing when it is neither, or what clashes when it is both.
DatasetLayout DetectLayout(const std::filesystem::path& folder);

struct DatasetOptions {
  DatasetLayout layout = DatasetLayout::kAuto;
  TumDatasetOptions tum;
  OmdOptions omd;
  void Check() const;
};

// An RGB-D sequence of any supported layout: its frames, its camera and, where the folder has
// it, the ground truth of that camera (TUM: groundtruth.txt; OMD: Vicon composed with the
// calibration chain). Opening reads and validates every list, calibration and ground-truth
// file, so a malformed one fails before the first frame is processed.
class RgbdDataset {
 public:
  // `camera`: the run's camera config. With camera.from_dataset the intrinsics come from the
  // folder (OMD: kalibr.yaml; TUM: camera.yaml), the depth settings still from `camera`.
  RgbdDataset(const std::filesystem::path& folder, const CameraOptions& camera,
              const DatasetOptions& options = {});

  size_t size() const { return entries_.size(); }
  const std::vector<RgbdFrameEntry>& entries() const { return entries_; }
  const std::filesystem::path& folder() const { return folder_; }
  DatasetLayout layout() const { return layout_; }
  const CameraOptions& camera() const { return camera_; }  // resolved: intrinsics included
  const std::optional<Trajectory>& ground_truth() const { return ground_truth_; }
  // Other tracked bodies with their ground truth (OMD: the moving objects, T_world_body).
  const std::map<std::string, Trajectory>& bodies() const { return bodies_; }

  // Decodes frame `index` (see LoadRgbdFrame).
  RgbdFrame Load(size_t index) const;

 private:
  std::filesystem::path folder_;
  DatasetLayout layout_ = DatasetLayout::kTum;
  CameraOptions camera_;
  std::vector<RgbdFrameEntry> entries_;
  std::optional<Trajectory> ground_truth_;
  std::map<std::string, Trajectory> bodies_;
};

// Writes `dataset` in the TUM layout at `out`: images copied
// as they are (rgb/, depth/ named by timestamp), rgb.txt, depth.txt, camera.yaml (the resolved
// camera, depth factor included), groundtruth.txt and bodies/<name>.txt where it has them. For
// evo, the TUM tools and anything else that reads TUM. Staged, then moved into place: an existing
// non-empty `out` is an error unless `overwrite`, and is replaced only by a complete copy.
void WriteTumCopy(const RgbdDataset& dataset, const std::filesystem::path& out,
                  bool overwrite = false);

// Decodes one frame's images. Throws Error naming the file when an image does not decode, has
// the wrong size for the camera, a colour PNG is 16-bit, or a depth image is not 16-bit
// single-channel.
RgbdFrame LoadRgbdFrame(const RgbdFrameEntry& entry, size_t index, const CameraOptions& camera);

}  // namespace sdoslam
