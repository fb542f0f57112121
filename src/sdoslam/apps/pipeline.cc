#include "sdoslam/apps/pipeline.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/io/tum_dataset.h"

namespace sdoslam {
namespace {}  // namespace

RunSummary RunOnDataset(const std::filesystem::path& dataset_folder,
                        const std::filesystem::path& associations, const CameraOptions& camera,
                        const SlamOptions& options, size_t max_frames,
                        const std::filesystem::path& out) {
  TumDatasetOptions dataset_options;
  dataset_options.associations = associations;
  const TumDataset dataset(dataset_folder, camera, dataset_options);
  RunSummary summary;
  summary.frames = max_frames > 0 ? std::min(dataset.size(), max_frames) : dataset.size();

  YAML::Emitter resolved;
  resolved << YAML::BeginMap;
  WriteCameraOptions(camera, &resolved);
  WriteSlamOptions(options, &resolved);
  resolved << YAML::EndMap;

  System slam(camera, options);
  std::string log =
      "index,timestamp,state,features,features_with_depth,matches,inliers,keyframe,features_ms,"
      "tracking_ms,"
      "mapping_ms\n";
  std::vector<double> frame_ms, mapping_ms;
  int best_depth_features = 0;
  for (size_t i = 0; i < summary.frames; ++i) {
    const RgbdFrame frame = dataset.Load(i);
    FrameTiming timing;
    const TrackingResult r = slam.TrackRgbd(i, frame.timestamp, frame.bgr, frame.depth, &timing);
    if (r.state == TrackingState::kNotInitialized) {
      best_depth_features = std::max(best_depth_features, r.features_with_depth);
      if (++summary.not_initialized >= 30 && slam.map().keyframes().empty()) {
        throw Error(
            fmt::format("{}: the first {} frames have too little depth to start the map (best: {} "
                        "features with depth, "
                        "{} needed)",
                        dataset_folder.string(), summary.not_initialized, best_depth_features,
                        options.tracking.min_initial_depth_features));
      }
    }
    summary.lost += r.state == TrackingState::kLost;
    frame_ms.push_back(timing.features_ms + timing.tracking_ms);
    log +=
        fmt::format("{},{:.6f},{},{},{},{},{},{},{:.2f},{:.2f},{:.2f}\n", i, r.timestamp,
                    ToString(r.state), r.features, r.features_with_depth, r.matches, r.inliers,
                    r.keyframe ? 1 : 0, timing.features_ms, timing.tracking_ms, timing.mapping_ms);
    spdlog::debug("frame {} {} inliers {} keyframe {}", i, ToString(r.state), r.inliers,
                  r.keyframe);
  }
  slam.Shutdown();  // the mapping thread finishes the queued keyframes
  summary.trajectory = slam.CameraTrajectory();
  mapping_ms = slam.MappingTimes();
  summary.tracked = summary.trajectory.size();
  summary.keyframes = slam.map().GoodKeyFrames();
  summary.map_points = slam.map().GoodPoints();
  summary.median_frame_ms = ComputeErrorStats(frame_ms).median;
  summary.median_mapping_ms = ComputeErrorStats(mapping_ms).median;

  WriteTumTrajectory(out / "CameraTrajectory.txt", summary.trajectory);
  WriteTumTrajectory(out / "KeyFrameTrajectory.txt", slam.KeyFrameTrajectory());
  WriteFileAtomically(out / "config.yaml", [&](std::ostream& o) { o << resolved.c_str() << '\n'; });
  WriteFileAtomically(out / "frames.csv", [&](std::ostream& o) { o << log; });

  const auto gt_path = dataset_folder / "groundtruth.txt";
  if (std::filesystem::exists(gt_path) && summary.trajectory.size() >= 3) {
    summary.evaluation =
        EvaluateEstimate(ReadTumTrajectory(gt_path), summary.trajectory, "sdoslam", {});
  }
  return summary;
}

std::string FormatRunSummary(const RunSummary& s) {
  return fmt::format(
      "{} frames: {} tracked, {} lost, {} before initialisation; {} keyframes, {} map points\n"
      "median per frame: {:.1f} ms (features + tracking); median local mapping per keyframe: "
      "{:.1f} ms\n",
      s.frames, s.tracked, s.lost, s.not_initialized, s.keyframes, s.map_points, s.median_frame_ms,
      s.median_mapping_ms);
}

}  // namespace sdoslam
