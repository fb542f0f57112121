#include "sdoslam/apps/run_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <iostream>
#include <memory>

#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"
#include "sdoslam/eval/report.h"
#include "sdoslam/io/tum_dataset.h"
#include "sdoslam/slam/system.h"

namespace sdoslam {
namespace {

struct RunArgs {
  std::string dataset;
  std::string config;
  std::string out;
  std::string associations;
  int max_frames = 0;
  bool sequential = false;
};

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

void RunSlam(const RunArgs& args) {
  // Everything that can be wrong with the inputs is found before the first frame.
  ConfigMap root = ConfigMap::LoadFile(args.config);
  std::optional<ConfigMap> camera_section = root.Section("camera");
  if (!camera_section) throw Error(args.config + ": missing the 'camera:' section");
  const CameraOptions camera = ReadCameraOptions(*camera_section);
  const SlamOptions options = ReadSlamOptions(root);
  root.RejectUnknownKeys();
  TumDatasetOptions dataset_options;
  dataset_options.associations = args.associations;
  const TumDataset dataset(args.dataset, camera, dataset_options);
  const size_t frames = args.max_frames > 0
                            ? std::min<size_t>(dataset.size(), static_cast<size_t>(args.max_frames))
                            : dataset.size();
  const std::filesystem::path out = args.out;

  YAML::Emitter resolved;
  resolved << YAML::BeginMap;
  WriteCameraOptions(camera, &resolved);
  WriteSlamOptions(options, &resolved);
  resolved << YAML::EndMap;

  System slam(camera, options);
  std::string log =
      "index,timestamp,state,features,features_with_depth,matches,inliers,keyframe,features_ms,"
      "tracking_ms,mapping_ms\n";
  std::vector<double> frame_ms, mapping_ms;
  size_t lost = 0, not_initialized = 0;
  for (size_t i = 0; i < frames; ++i) {
    const RgbdFrame frame = dataset.Load(i);
    FrameTiming timing;
    const TrackingResult r = slam.TrackRgbd(i, frame.timestamp, frame.bgr, frame.depth, &timing);
    if (r.state == TrackingState::kNotInitialized && ++not_initialized >= 30 &&
        slam.map().keyframes().empty()) {
      throw Error(
          fmt::format("{}: the first {} frames have too little depth to start (best frame: {} "
                      "features with depth, {} needed)",
                      args.dataset, not_initialized, r.features_with_depth,
                      options.tracking.min_initial_depth_features));
    }
    lost += r.state == TrackingState::kLost;
    frame_ms.push_back(timing.features_ms + timing.tracking_ms);
    if (r.keyframe && timing.mapping_ms > 0) mapping_ms.push_back(timing.mapping_ms);
    log +=
        fmt::format("{},{:.6f},{},{},{},{},{},{},{:.2f},{:.2f},{:.2f}\n", i, r.timestamp,
                    ToString(r.state), r.features, r.features_with_depth, r.matches, r.inliers,
                    r.keyframe ? 1 : 0, timing.features_ms, timing.tracking_ms, timing.mapping_ms);
    spdlog::debug("frame {} {} inliers {} kf {}", i, ToString(r.state), r.inliers, r.keyframe);
  }

  const Trajectory trajectory = slam.CameraTrajectory();
  WriteTumTrajectory(out / "CameraTrajectory.txt", trajectory);
  WriteTumTrajectory(out / "KeyFrameTrajectory.txt", slam.KeyFrameTrajectory());
  WriteFileAtomically(out / "config.yaml", [&](std::ostream& o) { o << resolved.c_str() << '\n'; });
  WriteFileAtomically(out / "frames.csv", [&](std::ostream& o) { o << log; });
  std::cout << fmt::format(
      "{} frames: {} tracked, {} lost, {} not initialised; {} keyframes, {} map points\n"
      "median per frame: {:.1f} ms (features + tracking); median local mapping per keyframe: "
      "{:.1f} ms\n"
      "wrote {}/CameraTrajectory.txt, KeyFrameTrajectory.txt, config.yaml, frames.csv\n",
      frames, trajectory.size(), lost, not_initialized, slam.map().GoodKeyFrames(),
      slam.map().GoodPoints(), Median(frame_ms), Median(mapping_ms), out.string());

  const auto gt_path = std::filesystem::path(args.dataset) / "groundtruth.txt";
  if (std::filesystem::exists(gt_path) && trajectory.size() >= 3) {
    EvaluationOptions eval;
    const auto result = EvaluateEstimate(ReadTumTrajectory(gt_path), trajectory, "sdoslam", eval);
    std::cout << '\n' << FormatTable({result}, eval);
  }
}

}  // namespace

void AddRunCommand(CLI::App& app) {
  auto args = std::make_shared<RunArgs>();
  CLI::App* cmd = app.add_subcommand("run", "RGB-D SLAM on a sequence in the TUM layout");
  cmd->add_option("--dataset", args->dataset, "sequence folder (rgb.txt, depth.txt, rgb/, depth/)")
      ->required();
  cmd->add_option("--config", args->config,
                  "config YAML: camera: and optional orb:, rgbd:, tracking:, mapping:")
      ->required();
  cmd->add_option("--out", args->out, "output folder")->required();
  cmd->add_option("--associations", args->associations, "explicit rgb/depth association file");
  cmd->add_option("--max-frames", args->max_frames, "stop after this many frames (0: all)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--sequential", args->sequential,
                "map inline after each keyframe (bit-identical runs); currently the only mode");
  cmd->callback([args] { RunSlam(*args); });
}

}  // namespace sdoslam
