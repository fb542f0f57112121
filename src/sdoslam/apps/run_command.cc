#include "sdoslam/apps/run_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <iostream>
#include <memory>

#include "sdoslam/apps/pipeline.h"
#include "sdoslam/core/atomic_file.h"
#include "sdoslam/core/error.h"

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

void RunSlam(const RunArgs& args) {
  // Everything that can be wrong with the inputs is found before the first frame.
  ConfigMap root = ConfigMap::LoadFile(args.config);
  std::optional<ConfigMap> camera_section = root.Section("camera");
  if (!camera_section) throw Error(args.config + ": missing the 'camera:' section");
  const CameraOptions camera = ReadCameraOptions(*camera_section);
  SlamOptions options = ReadSlamOptions(root);
  root.RejectUnknownKeys();
  options.sequential = args.sequential;
  const RunSummary s = RunOnDataset(args.dataset, args.associations, camera, options,
                                    static_cast<size_t>(args.max_frames), args.out);
  std::cout << FormatRunSummary(s) << "wrote " << args.out
            << "/CameraTrajectory.txt, KeyFrameTrajectory.txt, config.yaml, frames.csv\n";
  if (s.evaluation) std::cout << '\n' << FormatTable({*s.evaluation}, EvaluationOptions{});
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
                "map inline after each keyframe: bit-identical runs (default: a mapping thread)");
  cmd->callback([args] { RunSlam(*args); });
}

}  // namespace sdoslam
